"""Zero/non-zero and rank decisions that do not depend on rounding.

Every yes/no the toolkit takes on computed numbers -- does this sensor see that force
statically, does a layout see every force combination (PBH at s = 0), is a strain output
identically zero (an inadmissible placement candidate), is the structure supported -- is taken
here, against a bound on the rounding error of the number itself.  A number that differs
between two BLAS kernels only by rounding therefore always falls on the same side.

The bounds are first-order perturbation bounds (Higham, *Accuracy and Stability of Numerical
Algorithms*, 2002).  The model's matrices are known to a relative accuracy ``delta`` per entry
(:data:`MODEL_RTOL`: assembly rounding, values exchanged as text, and the rounding of a
backward-stable solve, which returns the exact solution for ``K + dK`` with ``|dK| <~ eps |K|``),
so the static response ``g = s^T K^-1 b`` of a sensor row ``s`` is uncertain by::

    |dg| <= delta (|w|^T |K| |x| + |s|^T |x|),      w = K^-1 s,  x = K^-1 b,

the first term from ``K`` and the second from the final dot product.  The bound scales with the
problem (units, stiffness factor, mesh size) exactly as ``g`` does, so the ratio ``|g| / bound``
is free of units.  A response counts as zero below :data:`SAFETY` bounds.  Measured on the
built-in models (S17 truss, both thesis plates, the IMP plate): rounding noise and a random
1e-13 perturbation of every entry of K and M stay below 1 bound under the default, Haswell, Zen,
Sandybridge and Prescott kernels, while every strain response to the papers' load positions lies
above 1e4 bounds (truss, stiff plates) or 36 bounds (the flexible thesis plate, condition 4e10).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

#: unit roundoff of float64
EPS = float(np.finfo(float).eps)

#: relative accuracy of the model's matrix entries assumed by every zero/non-zero decision:
#: above unit roundoff (assembly, solves) and the 1e-13 differences of matrices written with 13
#: or more significant digits
MODEL_RTOL = 1e-13

#: a computed quantity counts as non-zero only above this many times its perturbation bound
#: (rounding and a 1e-13 perturbation of the model have been measured below 1 bound)
SAFETY = 10.0

#: a force combination that a layout sees 1e9 times more weakly than its best-seen one is
#: treated as unseen even if it clears its rounding bound: its estimate would carry 1e9 times
#: the noise of the best one, which no filter can use
RANK_FLOOR = 1e-9

#: an eigenvalue of ``A_c`` whose real part is above ``-CRITICAL_RTOL |s|`` counts as on the
#: imaginary axis (an undamped mode): real damping ratios are >= 1e-4, while the damping computed
#: for an undamped model is at rounding level (<= 1e-12 of the frequency)
CRITICAL_RTOL = 1e-9


def stiffness_factorisation(structure):
    """Cholesky factor of ``K`` (SPD for a supported structure), computed once per structure.

    Parameters
    ----------
    structure : Structure

    Returns
    -------
    tuple
        The factor of :func:`scipy.linalg.cho_factor`.
    """
    return structure.memo("stiffness_cholesky", lambda: scipy.linalg.cho_factor(structure.K))


def is_supported(structure):
    """Whether ``K`` is positive definite (no rigid-body mode).

    Decided on the Jacobi-scaled stiffness ``K_s = D^-1/2 K D^-1/2`` (unit diagonal): its
    smallest eigenvalue is independent of units and of the spread of the frequencies (a thin
    cantilever plate with f1 / f_max ~ 1e-8 has about 1e-10), and a rigid-body mode leaves it at
    rounding level, ``eps ||K_s||``.  The structure is supported if ``K_s - tol I`` has a
    Cholesky factor with ``tol = SAFETY MODEL_RTOL ||K_s||`` (``||K_s||`` bounded by its largest
    absolute row sum), the most a perturbation of the entries within the model's accuracy can
    move an eigenvalue (Weyl).

    Parameters
    ----------
    structure : Structure

    Returns
    -------
    bool
    """
    def decide():
        K = np.asarray(structure.K, float)
        d = np.sqrt(np.abs(np.diag(K)))
        if np.any(d == 0):
            return False
        Ks = K / np.outer(d, d)
        tol = SAFETY * MODEL_RTOL * np.max(np.sum(np.abs(Ks), axis=1))
        try:
            np.linalg.cholesky(Ks - tol * np.eye(K.shape[0]))
        except np.linalg.LinAlgError:
            return False
        return True
    return structure.memo("supported", decide)


def zero_rows(mat):
    """The rows of a matrix that are zero up to rounding.

    Every entry below ``SAFETY MODEL_RTOL`` times the largest entry of the matrix.  Used for
    outputs that are identically zero by construction (strain ``e_x`` along a clamped edge),
    whose computed rows hold at most a few rounding errors of the assembly.

    Parameters
    ----------
    mat : ndarray (rows, cols)

    Returns
    -------
    ndarray (rows,) of bool
    """
    mat = np.abs(np.asarray(mat, float))
    scale = np.max(mat, initial=0.0)
    return np.max(mat, axis=1, initial=0.0) <= SAFETY * MODEL_RTOL * scale


def _unit_scale(mat):
    """``mat`` with its rows, then its columns scaled to unit 2-norm (zero ones left alone), and
    the row and column scales: strain rows are O(1e-9) per N, acceleration rows O(omega^2), so an
    unscaled rank test would be meaningless."""
    r = np.linalg.norm(mat, axis=1)
    r[r == 0] = 1.0
    c = np.linalg.norm(mat / r[:, None], axis=0)
    c[c == 0] = 1.0
    return mat / r[:, None] / c[None, :], r, c


@dataclass
class StaticGain:
    """Static gain from unit forces to sensors with its rounding bound.

    Attributes
    ----------
    gain : ndarray (m, n_p)
        ``(S_s + S_d) K^-1 S_p`` (sensor units per N), with every entry below ``SAFETY``
        times its bound set to exactly zero.  Velocity and acceleration rows are exactly zero:
        a static state has neither.
    bound : ndarray (m, n_p)
        First-order perturbation bound of each entry for a model known to :data:`MODEL_RTOL`
        (module docstring), in the same units.
    """

    gain: np.ndarray
    bound: np.ndarray

    def rows(self, idx):
        """The gain of a subset of the sensors.

        Parameters
        ----------
        idx : sequence of int
            Row indices (0-based).

        Returns
        -------
        StaticGain
        """
        idx = list(idx)
        return StaticGain(self.gain[idx], self.bound[idx])

    def visibility(self):
        """How well the sensors see every force combination.

        A combination is seen if the smallest singular value exceeds both ``SAFETY`` times the
        (equally scaled) perturbation bound -- by Weyl's inequality rounding or model error cannot
        then have created it -- and ``RANK_FLOOR`` times the largest one.

        Returns
        -------
        rel : float
            The smallest singular value of the gain relative to the largest, after unit row and
            column scaling.
        combo : ndarray (n_p,)
            The least visible force combination (a unit vector over the force locations).
        seen : bool
            Whether every combination is seen.
        """
        H = self.gain
        m, n_p = H.shape
        if m < n_p or not np.any(H):
            combo = np.eye(n_p)[0]
            if np.any(H):
                combo = np.linalg.svd(H)[2][-1]
            return 0.0, combo, False
        scaled, r, c = _unit_scale(H)
        _, sv, vh = np.linalg.svd(scaled)
        err = SAFETY * np.linalg.norm(self.bound / r[:, None] / c[None, :])   # Frobenius >= 2-norm
        combo = vh[-1] / c
        combo /= np.linalg.norm(combo)
        rel = float(sv[-1] / sv[0])
        return rel, combo, bool(sv[-1] > max(err, RANK_FLOOR * sv[0]))

    @property
    def sees_every_force(self):
        """True if the sensors see every force combination statically (PBH at s = 0)."""
        return self.visibility()[2]


def static_gain(structure, S_static, S_p, extra=None):
    """The static gain from unit forces to sensors, with its rounding bound.

    Needs a supported structure (``K`` positive definite); see :func:`is_supported`.

    Parameters
    ----------
    structure : Structure
    S_static : ndarray (m, n)
        Strain plus displacement selection rows in generalised coordinates.
    S_p : ndarray (n, n_p)
        Force selection.
    extra : ndarray (m, n_p), optional
        A static feed-through added to the gain (the static correction of a reduced model).

    Returns
    -------
    StaticGain
    """
    S = np.asarray(S_static, float)
    cf = stiffness_factorisation(structure)
    X = scipy.linalg.cho_solve(cf, np.asarray(S_p, float))           # (n, n_p) static displacements
    W = scipy.linalg.cho_solve(cf, S.T)                                # (n, m) sensor influence lines
    H = S @ X
    absK = np.abs(structure.K)
    bound = MODEL_RTOL * (np.abs(W).T @ (absK @ np.abs(X)) + np.abs(S) @ np.abs(X))
    if extra is not None:
        H = H + extra
        bound = bound + MODEL_RTOL * np.abs(extra)
    H[np.abs(H) <= SAFETY * bound] = 0.0
    return StaticGain(H, bound)


def column_rank_test(mat):
    """Column-rank decision for a PBH matrix whose rows mix units.

    Rows (strain, acceleration, rows of ``sI - A``), then columns, are scaled to unit 2-norm.
    A perturbation of every entry of the scaled matrix within the model's accuracy has a
    Frobenius norm of at most ``MODEL_RTOL sqrt(rows cols)``; the matrix counts as deficient below
    ``SAFETY`` times that, or below ``RANK_FLOOR`` (see there).

    Parameters
    ----------
    mat : ndarray (rows, cols)
        The PBH matrix (real or complex).

    Returns
    -------
    rel : float
        The smallest singular value relative to the largest.
    null : ndarray (cols,)
        The right singular vector of the smallest one (in the scaled coordinates, so its blocks
        compare).
    deficient : bool
        Whether the matrix is rank deficient.
    """
    mat = np.asarray(mat)
    _, sv, vh = np.linalg.svd(_unit_scale(mat)[0])
    rows, cols = mat.shape
    rel = float(sv[-1] / sv[0]) if sv.size == cols and sv[0] > 0 else 0.0
    tol = max(RANK_FLOOR, SAFETY * MODEL_RTOL * np.sqrt(rows * cols))
    return rel, vh[-1], bool(rel <= tol)
