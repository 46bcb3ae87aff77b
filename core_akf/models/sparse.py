"""Large models: the lowest modes of sparse ``K`` and ``M`` by shift-invert Lanczos
(:func:`scipy.sparse.linalg.eigsh`) on one sparse factorisation of ``K``, which also gives the
static correction of the modes left out (:class:`~core_akf.models.sparse.StaticCorrection`).

No dense ``n x n`` matrix is formed: the model kept is ``M = I``, ``K = diag(omega^2)`` with the
mode shapes as basis (n_phys x n_modes), the projection ``Phi^T M`` (n_modes x n_phys) and the
strain operator as given (sparse or dense rows).

Static correction of a modally reduced model: the residual flexibility of the modes it leaves
out (mode-acceleration method).

A model reduced to its lowest modes ``Phi`` (mass-normalised, physical coordinates) misses the
quasi-static response of the higher modes to the forces::

    u_res = (K^-1 - Phi Omega^-2 Phi^T) S_p f

It enters every strain and displacement output as a feed-through on the force states, so the
reduced filter sees the static deflection of the full model exactly.  :class:`StaticCorrection`
holds what that needs -- a solver for ``K^-1`` (a sparse factorisation for a large model) and the
kept modes -- and is carried by a reduced :class:`~core_akf.structure.Structure`
(``structure.static``).
"""
from __future__ import annotations

import numpy as np

from ..checks import AKFInputError

#: dense matrices are formed up to this many DOFs; larger models are reduced here
DENSE_LIMIT = 6000
#: a lowest eigenvalue below this fraction of the largest diagonal ratio K_ii / M_ii is a rigid-body
#: mode (rounding leaves one at about 1e-16 of it; the thinnest real structures reach 1e-10)
RIGID_BODY_RTOL = 1e-12
#: the number of modes kept from a large model unless the user says otherwise
DEFAULT_MODES = 100


def refuse_complex(A, name):
    """Refuse a complex matrix.

    Hysteretic or structural damping as ``K (1 + i eta)`` is not modelled: the models here are
    real, their damping a ratio, Rayleigh coefficients or ``C``.

    Parameters
    ----------
    A : array_like or scipy.sparse matrix
    name : str
        Its name in the message.

    Raises
    ------
    ModelError
        For complex entries.
    """
    if np.iscomplexobj(A.data if hasattr(A, "tocsr") and hasattr(A, "data") else A):
        raise AKFInputError(f"{name} is complex; the state-space models here are real: give the real part as {name} "
                            "and the damping as a modal ratio (damping = 0.02), Rayleigh coefficients or a damping "
                            "matrix C (a loss factor eta is about twice the damping ratio)")


def as_sparse(A, name):
    """A matrix as CSR of floats, checked square and finite.

    Parameters
    ----------
    A : array_like (n, n) or scipy.sparse matrix
    name : str
        Its name in a message.

    Returns
    -------
    scipy.sparse.csr_matrix
    """
    import scipy.sparse

    refuse_complex(A, name)
    if len(np.shape(A)) != 2 or np.shape(A)[0] != np.shape(A)[1]:
        raise AKFInputError(f"{name} must be a square matrix, got shape {np.shape(A)}")
    A = scipy.sparse.csr_matrix(A, dtype=float)
    if not np.all(np.isfinite(A.data)):
        raise AKFInputError(f"{name} has NaN or infinite entries")
    A.sum_duplicates()
    return A


def check_symmetric(A, name, rtol):
    """The symmetric part of a sparse matrix, checked nearly symmetric.

    Parameters
    ----------
    A : scipy.sparse matrix (n, n)
    name : str
        Its name in a message.
    rtol : float
        Largest asymmetry accepted, relative to the largest entry.

    Returns
    -------
    scipy.sparse.csr_matrix
        ``(A + A^T) / 2``; an error names the worst asymmetric pair.
    """
    if A.nnz == 0:
        raise AKFInputError(f"{name} is all zeros")
    scale = float(np.max(np.abs(A.data)))
    diff = (A - A.T).tocoo()
    if diff.nnz and np.max(np.abs(diff.data)) > rtol * scale:
        k = int(np.argmax(np.abs(diff.data)))
        i, j, v = int(diff.row[k]), int(diff.col[k]), abs(float(diff.data[k]))
        raise AKFInputError(f"{name} is not symmetric: entries ({i + 1}, {j + 1}) and ({j + 1}, {i + 1}) differ by "
                            f"{v:.3g} ({v / scale:.2g} of its largest entry); a linear structural model has symmetric "
                            "matrices (was the file written as a triangle or with another DOF order?)")
    return ((A + A.T) * 0.5).tocsr()


def factorise(K, name="model"):
    """Sparse factorisation of a stiffness matrix, for ``K^-1 B``.

    A sparse Cholesky factorisation with a nested-dissection ordering (CHOLMOD with METIS, from
    the ``cholespy`` wheel, which carries SuiteSparse: no system library) when it is installed
    (the ``large`` extra) and ``K`` is positive definite; else SuperLU's LU with
    COLAMD.  Measured on a plate of 101 016 DOFs (2 cores): Cholesky 2.5 s to factorise and 0.04 s
    per solve, LU 10.8 s and 0.11-0.14 s, with the same residual (8e-10 relative).

    Parameters
    ----------
    K : scipy.sparse matrix (n, n)
        Stiffness of the free DOFs.
    name : str
        The model's name in a message.

    Returns
    -------
    CholeskyFactor or LUFactor
        With ``solve(B)`` for B of shape (n,) or (n, k), and ``method`` (``"cholmod"`` or
        ``"superlu"``).

    Raises
    ------
    AKFInputError
        For a singular ``K`` (a model free to move as a rigid body).
    """
    try:
        return CholeskyFactor(K)
    except (ImportError, ValueError):        # not installed, or K not positive definite: LU decides
        pass
    try:
        return LUFactor(K)
    except RuntimeError as exc:
        raise AKFInputError(f"{name}: K is singular ({exc}): the model has a rigid-body mode; constrain it "
                            "(fixed = [...]) so that it cannot move freely") from None


class LUFactor:
    """``K = L U`` by SuperLU with the COLAMD ordering (on a plate of 1e5 DOFs 7e7 non-zeros in
    L + U, 11 s; MMD on ``A^T + A``: 10x the fill).

    Parameters
    ----------
    K : scipy.sparse matrix (n, n)

    Raises
    ------
    RuntimeError
        For a singular ``K``.
    """

    method = "superlu"

    def __init__(self, K):
        import scipy.sparse.linalg

        self._lu = scipy.sparse.linalg.splu(K.tocsc(), permc_spec="COLAMD")

    def solve(self, B):
        """``K^-1 B``.

        Parameters
        ----------
        B : array_like (n,) or (n, k)

        Returns
        -------
        ndarray, the shape of ``B``
        """
        return self._lu.solve(np.asarray(B, dtype=np.float64))


class CholeskyFactor:
    """``K = L L^T`` by CHOLMOD (``cholespy``; its own METIS nested-dissection ordering).

    Parameters
    ----------
    K : scipy.sparse matrix (n, n)
        Symmetric positive definite.

    Raises
    ------
    ImportError
        Without ``cholespy``.
    ValueError
        For a ``K`` that is not positive definite.
    """

    method = "cholmod"

    def __init__(self, K):
        import cholespy

        K = K.tocsc()
        self.n = K.shape[0]
        self._solver = cholespy.CholeskySolverD(self.n, K.indptr.astype(np.int32), K.indices.astype(np.int32),
                                                np.ascontiguousarray(K.data, dtype=np.float64),
                                                cholespy.MatrixType.CSC)

    def solve(self, B):
        """``K^-1 B``.

        Parameters
        ----------
        B : array_like (n,) or (n, k)

        Returns
        -------
        ndarray, the shape of ``B``
        """
        B = np.ascontiguousarray(B, dtype=np.float64)
        X = np.empty_like(B)
        self._solver.solve(B, X)
        return X


def lowest_modes(K, M, n_modes, name="model"):
    """The lowest modes of a sparse model (shift-invert Lanczos).

    Parameters
    ----------
    K, M : scipy.sparse matrix (n, n)
        Stiffness (N/m) and mass (kg) of the free DOFs.
    n_modes : int
    name : str
        The model's name in a message.

    Returns
    -------
    omega : ndarray (n_modes,)
        Circular frequencies (rad/s), ascending.
    phi : ndarray (n, n_modes)
        Mass-normalised modes.
    solve : callable
        ``K^-1`` applied to an (n, k) array, from one sparse factorisation.
    """
    import scipy.sparse.linalg

    n = K.shape[0]
    n_modes = int(n_modes)
    if not 1 <= n_modes < n - 1:
        raise AKFInputError(f"{name}: n_modes must be between 1 and {n - 2} for a sparse model of {n} DOFs, got {n_modes}")
    diag_m = M.diagonal()
    if np.any(diag_m <= 0):
        r = int(np.flatnonzero(diag_m <= 0)[0])
        raise AKFInputError(f"{name}: M has a diagonal entry {diag_m[r]:.3g} <= 0 in free row {r + 1}: every free DOF "
                            "needs mass (a DOF without mass: remove or condense it in the FE program)")
    lu = factorise(K, name)

    def solve(B):
        return lu.solve(np.asarray(B, float))

    op = scipy.sparse.linalg.LinearOperator((n, n), matvec=solve, dtype=float)
    v0 = np.random.default_rng(0).standard_normal(n)          # a fixed start: the same modes on every run
    try:
        w2, phi = scipy.sparse.linalg.eigsh(K, k=n_modes, M=M, sigma=0.0, which="LM", OPinv=op, v0=v0)
    except scipy.sparse.linalg.ArpackError as exc:
        raise AKFInputError(f"{name}: the eigenvalue solver failed ({exc})") from None
    order = np.argsort(w2)
    w2, phi = w2[order], phi[:, order]
    top = float(np.max(K.diagonal() / diag_m))
    if w2[0] <= RIGID_BODY_RTOL * top:
        raise AKFInputError(f"{name}: the model has a rigid-body mode (lowest eigenvalue {w2[0]:.3g} against {top:.3g}): "
                            "constrain it (fixed = [...]) so that it cannot move freely")
    norms = np.sqrt(np.einsum("ij,ij->j", phi, M @ phi))
    phi = phi / norms
    phi *= np.where(phi[np.argmax(np.abs(phi), axis=0), np.arange(n_modes)] < 0, -1.0, 1.0)   # a fixed sign
    return np.sqrt(w2), phi, solve


def modal_parts(K, M, n_modes, C=None, name="model"):
    """What a reduced :class:`~core_akf.structure.Structure` of a sparse model holds.

    Parameters
    ----------
    K, M : scipy.sparse matrix (n, n)
        Stiffness (N/m) and mass (kg) of the free DOFs.
    n_modes : int
    C : scipy.sparse matrix (n, n), optional
        Damping (N s/m).
    name : str
        The model's name in a message.

    Returns
    -------
    K_r : ndarray (n_modes, n_modes)
        ``diag(omega^2)``.
    basis : ndarray (n, n_modes)
        The mass-normalised modes.
    projection : ndarray (n_modes, n)
        ``Phi^T M``.
    C_r : ndarray (n_modes, n_modes) or None
        ``Phi^T C Phi`` (None without ``C``).
    static : StaticCorrection
    """
    omega, phi, solve = lowest_modes(K, M, n_modes, name)
    P = np.asarray((M @ phi).T)
    Cr = None if C is None else np.asarray(phi.T @ (C @ phi))
    return np.diag(omega ** 2), phi, P, Cr, StaticCorrection(solve, phi, omega)


class StaticCorrection:
    """Residual flexibility ``K^-1 - Phi Omega^-2 Phi^T`` of the modes a reduced model leaves out.

    Parameters
    ----------
    solve : callable -- ``solve(B)`` returns ``K^-1 B`` for a (n_phys, k) array (m/N)
    phi : ndarray (n_phys, n_kept) -- the kept mass-normalised modes in physical free DOFs
    omega : ndarray (n_kept,) -- their circular frequencies (rad/s)
    flexibility_scale : float -- multiplies ``solve`` (a model ``factor`` times stiffer: ``1 / factor``)
    """

    def __init__(self, solve, phi, omega, flexibility_scale=1.0):
        self.solve = solve
        self.phi = np.asarray(phi, float)
        self.omega = np.asarray(omega, float)
        self.flexibility_scale = float(flexibility_scale)
        self._cache = {}

    @property
    def n_phys(self):
        return self.phi.shape[0]

    def residual(self, dofs):
        """Residual displacement for unit forces at physical free DOFs.

        Parameters
        ----------
        dofs : sequence of int
            Physical free DOF indices (0-based).

        Returns
        -------
        ndarray (n_phys, len(dofs))
            m/N (cached per set of DOFs).
        """
        key = tuple(int(d) for d in dofs)
        if key not in self._cache:
            unit = np.zeros((self.n_phys, len(key)))
            unit[list(key), np.arange(len(key))] = 1.0
            full = np.asarray(self.solve(unit), float).reshape(self.n_phys, len(key))
            kept = self.phi @ (self.phi[list(key)].T / self.omega[:, None] ** 2)
            self._cache[key] = self.flexibility_scale * full - kept
        return self._cache[key]

    def scaled(self, stiffness_factor=1.0, mass_factor=1.0):
        """The correction of the model with ``K`` times ``stiffness_factor`` and ``M`` times ``mass_factor``.

        Modes ``phi / sqrt(mass_factor)``, frequencies times ``sqrt(stiffness_factor / mass_factor)``,
        ``K^-1`` over ``stiffness_factor``.

        Parameters
        ----------
        stiffness_factor, mass_factor : float

        Returns
        -------
        StaticCorrection
        """
        return StaticCorrection(self.solve, self.phi / np.sqrt(mass_factor),
                                self.omega * np.sqrt(stiffness_factor / mass_factor),
                                self.flexibility_scale / stiffness_factor)

    def keeping(self, phi, omega):
        """The correction of the same model reduced to fewer modes; the others join the residual.

        Parameters
        ----------
        phi : ndarray (n_phys, k)
            The modes it keeps now (mass-normalised).
        omega : ndarray (k,)
            Their circular frequencies (rad/s).

        Returns
        -------
        StaticCorrection
        """
        return StaticCorrection(self.solve, phi, omega, self.flexibility_scale)
