"""Augmented Kalman filter (AKF) with a random-walk force model (Lourens et al. 2012; S17 eq. 14-26, IMP eq. 12-25),
or a Matérn Gaussian-process force model and dummy measurements (:mod:`core_akf.forcemodels`).

Low level: :func:`run` / :func:`filter_states` work on the augmented matrices and a
stack (batch) of filters at once.  High level: :func:`estimate` takes a
:class:`~core_akf.structure.Structure`, a sensor layout, force locations, covariance
levels and measurements and returns an :class:`Estimate` (forces, states, strains at
every member/node, innovations); :func:`estimate_batch` does the same for many sensor
layouts / measurement sets sharing one structure and force set.

Conventions: ``X_k = [x_k; f_k]`` (``n_a = 2n + n_p``; ``[x_k; xi_k]`` with the force states of a
Matérn model, ``f_k = H xi_k``), the prior at step 0 is
``x0`` with covariance ``P0``; each step first updates with ``y_k`` and then predicts.
The returned states are the filtered (posterior) ones.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg

from .types import ArrayLike, BatchMeasurements, Covariance, FloatArray, Forces, Layout, Matrix, Measurements, NoiseCovariance

if TYPE_CHECKING:
    import pandas as pd

    from .structure import Structure
from .checks import as_finite_array, check_covariance
from .covariances import augmented_covariance, diag_levels, noise_covariance, state_covariance  # noqa: F401
from .exceptions import AKFInputError
from .forcemodels import DummyMeasurements, ForceModel, as_force_model
from .likelihood import loglik_terms
from .recursion import lti_response
from .riccati import RiccatiError
from .sensors import as_layout, parse_force_locations
from .statespace import (
    check_detectable,
    observation,
    strain_feedthrough,
)
from .steady import steady_filter, steady_outputs, steady_states  # noqa: F401  (public here as before)


def _batchify(A_a, G_a, Q_a, R, Y, check=True):
    """Validate shapes (and with ``check`` the covariances); return arrays with a leading batch
    axis and the batch shape."""
    A_a = as_finite_array(A_a, "A_a", ndim=(2, 3))
    G_a = as_finite_array(G_a, "G_a", ndim=(2, 3))
    Q_a = as_finite_array(Q_a, "Q_a", ndim=(2, 3))
    R = as_finite_array(R, "R", ndim=(2, 3))
    Y = as_finite_array(Y, "measurements Y", ndim=(2, 3))
    if Y.shape[-2] < 1:
        raise AKFInputError("measurements Y have no time steps")
    n = A_a.shape[-1]
    m = G_a.shape[-2]
    if A_a.shape[-2] != n:
        raise AKFInputError(f"A_a must be square, got {A_a.shape}")
    if G_a.shape[-1] != n:
        raise AKFInputError(f"G_a has {G_a.shape[-1]} columns; A_a has {n} states")
    if Q_a.shape[-2:] != (n, n):
        raise AKFInputError(f"Q_a must be {n}x{n}, got {Q_a.shape}")
    if R.shape[-2:] != (m, m):
        raise AKFInputError(f"R must be {m}x{m} for {m} channels, got {R.shape}")
    if Y.shape[-1] != m:
        raise AKFInputError(f"measurements have {Y.shape[-1]} channels but G_a has {m} rows")
    if check:
        check_covariance(Q_a, "process covariance Q_a")
        check_covariance(R, "measurement-noise covariance R", definite=True)
    batched = any(x.ndim == 3 for x in (A_a, G_a, Q_a, R, Y))
    if not batched:
        return A_a[None], G_a[None], Q_a[None], R[None], Y[None], False
    sizes = {x.shape[0] for x in (A_a, G_a, Q_a, R, Y) if x.ndim == 3}
    if len(sizes) > 1:
        raise AKFInputError(f"batched inputs disagree on the batch size: {sorted(sizes)}")
    B = sizes.pop()
    expand = [x if x.ndim == 3 else np.broadcast_to(x, (B,) + x.shape) for x in (A_a, G_a, Q_a, R, Y)]
    return (*expand, True)


@dataclass
class FilterResult:
    """Raw output of :func:`filter_states` (leading batch axis kept if the input had one).

    Attributes
    ----------
    states : ndarray (N, n_a)
        Filtered (posterior) augmented states.
    innovations : ndarray (N, m)
        ``y_k - G_a X_k^-``, in the sensors' units.
    gain : ndarray (n_a, m)
        The steady-state gain, or the last one of the time-varying filter.
    P_prior : ndarray (n_a, n_a)
        The steady-state prior covariance, or the last one.
    loglik_terms : ndarray (N, m)
        The log-likelihood of the innovations per step and channel
        (:func:`core_akf.likelihood.loglik_terms`); their sum is the record's log-likelihood.
    """

    states: np.ndarray
    innovations: np.ndarray
    gain: np.ndarray
    P_prior: np.ndarray
    loglik_terms: np.ndarray = None


class ModalBlockTransition:
    """The augmented transition of a classically damped structure in modal coordinates.

    ``A_a = [[A_z, B_z], [0, I]]`` whose structural part ``A_z`` consists of four diagonal
    blocks -- the ZOH transition in modal coordinates ``z = [omega q; q']`` (see
    :func:`core_akf.statespace.modal_state_transform`).  :meth:`left` applies ``A_a`` from the
    left in ``O(n_a (1 + n_p))`` operations per column instead of ``O(n_a^2)``, which makes the
    time-varying covariance update ``A_a P A_a^T`` ``O(n_a^2)`` instead of ``O(n_a^3)`` per step.

    Parameters
    ----------
    A_a : ndarray (n_a, n_a)
        The augmented transition, ``n_a = 2 n_modes + n_p``.
    n_modes : int
        Modes of the structural part.
    rtol : float
        Tolerance of the structure test (:meth:`detect`).
    """

    def __init__(self, A_a, n_modes, rtol=1e-12):
        n = int(n_modes)
        nx = 2 * n
        blocks = [np.diag(A_a[i * n:(i + 1) * n, j * n:(j + 1) * n]).copy() for i in (0, 1) for j in (0, 1)]
        rebuilt = np.zeros((nx, nx))
        for (i, j), d in zip(((0, 0), (0, 1), (1, 0), (1, 1)), blocks):
            rebuilt[i * n:(i + 1) * n, j * n:(j + 1) * n] = np.diag(d)
        self.error = float(np.max(np.abs(A_a[:nx, :nx] - rebuilt)) / max(np.max(np.abs(A_a[:nx, :nx])), 1e-300))
        lower = A_a[nx:]
        if self.error > rtol or not np.array_equal(lower, np.eye(A_a.shape[0])[nx:]):
            raise ValueError(f"A_a has no modal block structure (relative off-block size {self.error:.1e})")
        self.n, self.nx = n, nx
        self.d11, self.d12, self.d21, self.d22 = (d[:, None] for d in blocks)
        self.B = A_a[:nx, nx:].copy()

    @classmethod
    def detect(cls, A_a, n_modes, rtol=1e-12):
        """The structured form of ``A_a`` if it has it.

        Parameters
        ----------
        A_a : ndarray (n_a, n_a)
            An augmented transition.
        n_modes : int
            Modes of its structural part.
        rtol : float
            Largest entry outside the four diagonal blocks, relative to the largest entry.

        Returns
        -------
        ModalBlockTransition or None
        """
        try:
            return cls(A_a, n_modes, rtol)
        except ValueError:
            return None

    def left(self, X):
        """``A_a @ X``.

        Parameters
        ----------
        X : ndarray (..., n_a, k)

        Returns
        -------
        ndarray (..., n_a, k)
        """
        n, nx = self.n, self.nx
        q, v, f = X[..., :n, :], X[..., n:nx, :], X[..., nx:, :]
        out = np.empty(X.shape)
        np.matmul(self.B, f, out=out[..., :nx, :])
        out[..., :n, :] += self.d11 * q
        out[..., :n, :] += self.d12 * v
        out[..., n:nx, :] += self.d21 * q
        out[..., n:nx, :] += self.d22 * v
        out[..., nx:, :] = f
        return out

    def propagate(self, P, Q):
        """``A_a P A_a^T + Q``, symmetrised.

        Two left products on contiguous data (``A (A P)^T`` is the transpose of the wanted
        symmetric matrix).

        Parameters
        ----------
        P : ndarray (B, n_a, n_a)
            Posterior covariances.
        Q : ndarray (B, n_a, n_a)
            Process covariances.

        Returns
        -------
        ndarray (B, n_a, n_a)
            The prior covariances of the next step.
        """
        out = self.left(np.ascontiguousarray(np.swapaxes(self.left(P), -1, -2)))
        out += np.swapaxes(out, -1, -2)
        out *= 0.5
        out += Q
        return out


def time_varying_filter(A, G, Q, R, Y, x, P, switch_tol, transition=None):
    """Time-varying AKF on a batch of B filters.

    Once the prior covariance has stopped changing (relative change over ``_CHECK_EVERY`` steps
    below ``switch_tol``, every filter of the batch), the gain is constant to that precision and
    the rest of the record runs as the fixed-gain recursion.

    Parameters
    ----------
    A : ndarray (B, n, n)
        Transition matrices.
    G : ndarray (B, m, n)
        Observation matrices.
    Q : ndarray (B, n, n)
        Process covariances.
    R : ndarray (B, m, m)
        Measurement-noise covariances.
    Y : ndarray (B, N, m)
        Measurements.
    x : ndarray (B, n)
        Prior mean of the first step.
    P : ndarray (B, n, n)
        Prior covariance of the first step.
    switch_tol : float
        Relative change of the covariance below which the gain is held (0: never).
    transition : ModalBlockTransition, optional
        Applies ``A`` cheaply in the covariance update.

    Returns
    -------
    X : ndarray (B, N, n)
        Filtered states.
    E : ndarray (B, N, m)
        Innovations.
    L : ndarray (B, n, m)
        The last gain.
    P : ndarray (B, n, n)
        The prior covariance of the next step (or, ``switched``, the converged one).
    switched : bool
        Whether the filter went over to the fixed gain.
    terms : ndarray (B, N, m)
        The log-likelihood of the innovations per step and channel
        (:func:`core_akf.likelihood.loglik_terms`).
    """
    B, N, m = Y.shape
    n = A.shape[-1]
    out = np.empty((B, N, n))
    innov = np.empty((B, N, m))
    At = np.swapaxes(A, -1, -2)
    Gt = np.swapaxes(G, -1, -2)
    terms = np.empty((B, N, m))
    P_check = P.copy()
    for k in range(N):
        e = Y[:, k] - np.einsum("bij,bj->bi", G, x)
        PGt = P @ Gt
        S = G @ PGt + R
        L = np.swapaxes(np.linalg.solve(S, np.swapaxes(PGt, -1, -2)), -1, -2)  # P G^T S^-1
        if switch_tol > 0 and k > 0 and k % _CHECK_EVERY == 0:
            change = np.linalg.norm(P - P_check, axis=(-2, -1)) / np.linalg.norm(P, axis=(-2, -1))
            if np.all(change < switch_tol):
                I_LG = np.eye(n) - L @ G
                first = np.einsum("bij,bj->bi", I_LG, x) + np.einsum("bij,bj->bi", L, Y[:, k])
                out[:, k:] = lti_response(I_LG @ A, L, Y[:, k:], first)
                innov[:, k] = e
                innov[:, k + 1:] = Y[:, k + 1:] - out[:, k:-1] @ np.swapaxes(G @ A, -1, -2)
                terms[:, k:] = loglik_terms(innov[:, k:], S)       # the covariance has converged: S from here on
                return out, innov, L, P, True, terms
            P_check = P.copy()
        terms[:, k] = loglik_terms(e[:, None], S)[:, 0]
        x = x + np.einsum("bij,bj->bi", L, e)
        P = P - L @ np.swapaxes(PGt, -1, -2)  # a new array: P0 given by the caller stays untouched
        out[:, k] = x
        innov[:, k] = e
        x = np.einsum("bij,bj->bi", A, x)
        if transition is None:
            P = A @ P @ At + Q
            P = 0.5 * (P + np.swapaxes(P, -1, -2))
        else:
            P = transition.propagate(P, Q)
    return out, innov, L, P, False, terms


#: the time-varying filter tests every this many steps whether its covariance has converged
_CHECK_EVERY = 32


def _steady(A, G, Q, R, Y, x):
    out, L, P = steady_states(A, G, Q, R, Y, x)
    innov = np.empty_like(Y)                          # y_k - G A X_{k-1}: (G A) is only m x n
    innov[:, 0] = Y[:, 0] - np.einsum("bij,bj->bi", G, x)
    innov[:, 1:] = Y[:, 1:] - out[:, :-1] @ np.swapaxes(G @ A, -1, -2)
    return out, innov, L, P, loglik_terms(innov, innovation_covariance(G, P, R))


def innovation_covariance(G, P, R):
    """The predicted innovation covariance ``S = G P G^T + R``, symmetrised.

    Parameters
    ----------
    G : ndarray (..., m, n)
    P : ndarray (..., n, n)
        A prior covariance.
    R : ndarray (..., m, m)

    Returns
    -------
    ndarray (..., m, m)
    """
    S = G @ P @ np.swapaxes(G, -1, -2) + R
    return 0.5 * (S + np.swapaxes(S, -1, -2))


def filter_states(A_a, G_a, Q_a, R, Y, x0=None, P0=None, steady=False, switch_tol=1e-14, transition=None,
                  check=True):
    """Run one AKF or a batch of them (see :func:`run`).

    Parameters
    ----------
    A_a, G_a, Q_a, R, Y
        As in :func:`run`.
    x0 : ndarray (n_a,) or (B, n_a), optional
        Prior mean at step 0 (default zero).
    P0 : ndarray (n_a, n_a) or (B, n_a, n_a), optional
        Prior covariance at step 0 (default ``Q_a``); not used by the steady-state filter.
    steady : bool
        The steady-state gain instead of the time-varying filter.
    switch_tol : float
        The time-varying filter continues with its (then constant) gain once its covariance
        changes by less than this, relatively; 0 keeps it time-varying to the end.
    transition : ModalBlockTransition, optional
        A structured form of a shared ``A_a`` for a cheaper time-varying covariance update.
    check : bool
        Check that Q_a, R and P0 are symmetric PSD (R PD); False for matrices the caller has
        already checked (as :func:`estimate_batch` does).

    Returns
    -------
    FilterResult
    """
    A, G, Q, Rb, Yb, batched = _batchify(A_a, G_a, Q_a, R, Y, check)
    B, n = Yb.shape[0], A.shape[-1]
    if x0 is not None:
        x0 = as_finite_array(x0, "x0")
        if x0.shape[-1:] != (n,):
            raise AKFInputError(f"x0 must have {n} entries (the augmented state), got shape {x0.shape}")
    x = np.zeros((B, n)) if x0 is None else np.broadcast_to(x0, (B, n)).copy()
    if steady:
        out, innov, L, P, terms = _steady(A, G, Q, Rb, Yb, x)
    else:
        if P0 is not None:
            P0 = check_covariance(P0, "initial covariance P0") if check else np.asarray(P0, float)
            if P0.shape[-2:] != (n, n):
                raise AKFInputError(f"P0 must be {n}x{n}, got {P0.shape}")
        P = Q.copy() if P0 is None else np.broadcast_to(P0, (B, n, n)).copy()
        out, innov, L, P, _, terms = time_varying_filter(A, G, Q, Rb, Yb, x, P, switch_tol, transition)
    if not batched:
        out, innov, L, P, terms = out[0], innov[0], L[0], P[0], terms[0]
    return FilterResult(states=out, innovations=innov, gain=L, P_prior=P, loglik_terms=terms)


def run(A_a: Matrix, G_a: ArrayLike, Q_a: Matrix, R: Matrix, Y: Measurements | BatchMeasurements, x0: ArrayLike | None = None,
        P0: ArrayLike | None = None, steady: bool = False) -> np.ndarray:
    """Filtered (posterior) augmented states of the AKF.

    Parameters
    ----------
    A_a : ndarray (n_a, n_a) or (B, n_a, n_a)
        Augmented transition matrix ``[[A, B], [0, I]]``.
    G_a : ndarray (m, n_a) or (B, m, n_a)
        Augmented observation ``[G, D]``.
    Q_a : ndarray (n_a, n_a) or (B, n_a, n_a)
        Process covariance ``blockdiag(Q, S)`` (model error, force increments).
    R : ndarray (m, m) or (B, m, m)
        Measurement-noise covariance.
    Y : ndarray (N, m) or (B, N, m)
        Measurements, one row per time step.
    x0, P0 : optional
        Prior mean (default 0) and covariance (default ``Q_a``) at step 0; ``P0`` is
        ignored by the steady-state filter.
    steady : bool
        Use the steady-state gain (one Riccati solution) instead of the time-varying filter.

    Returns
    -------
    ndarray (N, n_a), or (B, N, n_a) when any input carries a batch axis.

    Notes
    -----
    The filter works in whatever coordinates the matrices are given in.  For stiff FE models
    in raw ``[u; u']`` the Riccati iteration is ill-conditioned; :func:`estimate` therefore
    transforms to energy-normalised modal coordinates first
    (:func:`core_akf.statespace.modal_state_transform`) and back afterwards.

    Examples
    --------
    The AKF on matrices of one's own (here the S17 truss' augmented model):

    >>> import numpy as np
    >>> from core_akf import simulate, state_space
    >>> from core_akf.models import s17_truss
    >>> sensors, forces = ["strain:13", "acc:8:y"], ["8:y"]
    >>> sim = simulate(s17_truss(), sensors, forces, np.full((200, 1), 100.0), 1e-3, relative_noise=0.02, seed=0)
    >>> ss = state_space(s17_truss(), sensors, forces, 1e-3)
    >>> Q = np.diag(np.r_[np.full(66, 1e-16), 1e4])
    >>> X = run(ss.A_a, ss.G_a, Q, np.diag(sim.noise_std ** 2), sim.measurements, steady=True)
    >>> X.shape, round(float(X[-1, -1]))          # the last state is the force (N)
    ((200, 67), 100)
    """
    return filter_states(A_a, G_a, Q_a, R, Y, x0=x0, P0=P0, steady=steady).states


# ------------------------------------------------------------------------------- high level
@dataclass
class Estimate:
    """AKF estimate of forces, states and strains.

    Attributes
    ----------
    structure : Structure
        The filter's model.
    sensors : tuple of Sensor
        The layout, m channels.
    force_locations : list of tuple
        The unknown force locations, 1-based ``(node, direction)``.
    dt : float
        Time step (s).
    time : ndarray (N,)
        Time of each step (s).
    forces : ndarray (N, n_p)
        Estimated forces (N) at ``force_locations``.
    states : ndarray (N, 2n)
        ``[u; u']`` in generalised coordinates (m, m/s for a full model).
    innovations : ndarray (N, m)
        ``y_k - G_a X_k^-``, in the sensors' units.
    gain : ndarray (n_a, m)
        Steady-state (or last) Kalman gain for ``[u; u'; f]``.
    detectability : DetectabilityReport
        The PBH test of the sensor layout.
    measurements : ndarray (N, m)
        The data the filter ran on (SI).
    innovation_cov : ndarray (m, m)
        Predicted innovation covariance ``G_a P G_a^T + R`` of the steady-state (or last) prior
        covariance ``P``, in squared sensor units.
    filter_matrices : tuple
        ``(A_a, G_a, L)`` in the filter's internal coordinates, with the steady-state (or last)
        gain ``L``; the closed loop ``(I - L G_a) A_a`` sets the transient.
    t0 : float
        Time of the first step (s); 0 except for chunks of a streamed record
        (:class:`core_akf.streaming.Estimator`).
    loglik_terms : ndarray (N, m)
        The log-likelihood of the innovations per step and channel
        (:func:`core_akf.likelihood.loglik_terms`); see :attr:`loglik`.
    force_std : ndarray (N, n_p) or None
        The standard deviation of every smoothed force (N); None for a filtered estimate.
    strain_std : ndarray (N, n_strain) or None
        The standard deviation of every smoothed strain output (m/m); None for a filtered estimate.
    """

    structure: object
    sensors: tuple
    force_locations: list
    dt: float
    states: np.ndarray
    forces: np.ndarray
    innovations: np.ndarray
    gain: np.ndarray = field(repr=False, default=None)
    detectability: object = field(repr=False, default=None)
    measurements: np.ndarray = field(repr=False, default=None)
    innovation_cov: np.ndarray = field(repr=False, default=None)
    filter_matrices: tuple = field(repr=False, default=None)
    t0: float = 0.0
    loglik_terms: np.ndarray = field(repr=False, default=None)
    force_std: np.ndarray = field(repr=False, default=None)
    strain_std: np.ndarray = field(repr=False, default=None)

    @property
    def smoothed(self):
        """Whether the states are smoothed (:func:`estimate` with ``smooth=True``): then
        :attr:`force_std` and :attr:`strain_std` hold their standard deviations."""
        return self.force_std is not None

    @property
    def loglik(self):
        """The Gaussian log-likelihood of the innovations (a float, dimensionless): how probable
        the record is under the filter's model and covariances (:mod:`core_akf.likelihood`)."""
        return float(np.sum(self.loglik_terms))

    @property
    def loglik_channels(self):
        """The log-likelihood per channel, shape (m,): each channel's innovations given those of
        the channels before it in the layout; they sum to :attr:`loglik`."""
        return np.sum(self.loglik_terms, axis=0)

    @property
    def predicted(self):
        """One-step predictions of the measurements, ``y_k - innovation_k``, shape (N, m)."""
        return self.measurements - self.innovations

    @cached_property
    def transient_time(self):
        """Time constant (s) of the filter's slowest error mode, ``-dt / ln(rho)`` with ``rho`` the
        spectral radius of the closed loop ``(I - L G_a) A_a``; ``inf`` if it does not decay."""
        A, G, L = self.filter_matrices
        rho = float(np.max(np.abs(np.linalg.eigvals(A - L @ (G @ A)))))
        return self.dt / -np.log(rho) if rho < 1 else np.inf

    @property
    def time(self):
        """Time of each step (s): ``t0 + k dt`` (``t0`` > 0 for a chunk of a streamed record)."""
        return self.t0 + np.arange(self.forces.shape[0]) * self.dt

    @cached_property
    def strains(self):
        """Strains at every member (truss) or node component (plate), shape (N, n_strain)."""
        n = self.structure.n
        out = self.states[:, :n] @ self.structure.strain_operator.T
        extra = strain_feedthrough(self.structure, self.force_locations)
        return out if extra is None else out + self.forces @ extra.T

    def response(self, sensors: Layout) -> FloatArray:
        """Estimated response at any sensors (e.g. held-back validation sensors).

        Parameters
        ----------
        sensors : sequence of sensor specs
            k sensors on the filter's model.

        Returns
        -------
        ndarray (N, k)
            In the sensors' SI units.
        """
        G, D = observation(self.structure, sensors, self.force_locations)
        return self.states @ G.T + self.forces @ D.T

    def to_frame(self, wide: bool = False) -> pd.DataFrame:
        """The estimated forces and strains as a :class:`pandas.DataFrame`.

        Parameters
        ----------
        wide : bool
            False (default), tidy: one row per time step and channel, columns ``time`` (s),
            ``quantity`` ("force" or "strain"), ``channel`` (``"8:y"``, ``"strain:13"``,
            ``"strain:70:ex"``: the names of force locations and sensors), ``unit`` ("N", "m/m") and
            ``value``.  True: one row per time step and one column per channel (``force:8:y``,
            ``strain:13``), for spreadsheets.

        Returns
        -------
        pandas.DataFrame
        """
        import pandas as pd

        forces = [f"{node}:{d}" for node, d in self.force_locations]
        strains = self.structure.strain_labels
        if wide:
            cols = {"time": self.time}
            cols.update({f"force:{c}": self.forces[:, j] for j, c in enumerate(forces)})
            cols.update(dict(zip(strains, self.strains.T)))
            return pd.DataFrame(cols)
        N = self.time.size
        values = np.hstack([self.forces, self.strains])
        channels = forces + strains
        return pd.DataFrame({
            "time": np.tile(self.time, len(channels)),
            "quantity": np.repeat(["force"] * len(forces) + ["strain"] * len(strains), N),
            "channel": np.repeat(channels, N),
            "unit": np.repeat(["N"] * len(forces) + ["m/m"] * len(strains), N),
            "value": values.T.reshape(-1)})


def estimate_batch(structure: Structure, layouts: Sequence[Layout], forces: Forces, measurements: BatchMeasurements,
                   dt: float, *, model_error_cov: Covariance, force_increment_cov: Covariance | None = None,
                   noise_cov: NoiseCovariance, steady: bool | None = None, allow_undetectable: bool = False,
                   x0: ArrayLike | None = None, P0: ArrayLike | None = None, smooth: bool = False,
                   force_model: ForceModel | None = None, dummy: DummyMeasurements | None = None) -> list[Estimate]:
    """AKF estimates for many sensor layouts of one structure in one batched filter call.

    Parameters
    ----------
    structure : Structure
        The filter's model.
    layouts : sequence of sensor layouts
        B layouts, all with the same number m of sensors.
    forces : sequence of force specs
        The unknown force locations (shared).
    measurements : ndarray (B, N, m) or sequence of (N, m)
        One measurement set per layout, columns in layout order (SI).
    dt : float
        Time step (s).
    model_error_cov, force_increment_cov
        Q and S, as in :func:`estimate`.
    noise_cov : float, ndarray, dict, or one per layout
        R as in :func:`estimate`, applied to every layout; or one entry per layout (a (B, m, m)
        array or a list of B dicts of variances per sensor kind).
    steady : bool or None
        As in :func:`estimate` (None: steady where every layout is detectable).
    allow_undetectable : bool
        Run layouts that fail the PBH test.
    x0, P0 : optional
        Prior mean (n_a,) and covariance of the physical augmented state ``[u; u'; f]``.
    smooth : bool
        As in :func:`estimate`.
    force_model, dummy : optional
        As in :func:`estimate`.

    Returns
    -------
    list of Estimate
        One per layout.

    Examples
    --------
    Two layouts, each with its own record, in one call:

    >>> import numpy as np
    >>> from core_akf import simulate
    >>> from core_akf.models import s17_truss
    >>> truss, layouts = s17_truss(), [["strain:13", "acc:8:y"], ["strain:12", "acc:8:y"]]
    >>> Y = np.stack([simulate(truss, l, ["8:y"], np.full((200, 1), 100.0), 1e-3, relative_noise=0.02,
    ...                        seed=0).measurements for l in layouts])
    >>> ests = estimate_batch(truss, layouts, ["8:y"], Y, 1e-3, model_error_cov=1e-16, force_increment_cov=1e4,
    ...                       noise_cov={"strain": 1e-14, "acc": 1e-4})
    >>> [round(float(e.forces[-50:].mean())) for e in ests]      # the 100 N step
    [100, 100]
    """
    layouts = [as_layout(l) for l in layouts]
    if not layouts:
        raise AKFInputError("no sensor layouts given")
    m = len(layouts[0])
    if any(len(l) != m for l in layouts):
        raise AKFInputError("all layouts of a batch must have the same number of sensors")
    Y = as_finite_array(measurements, "measurements", ndim=3)
    if Y.shape[0] != len(layouts) or Y.shape[2] != m:
        raise AKFInputError(f"measurements must have shape ({len(layouts)}, N, {m}); got {Y.shape}")
    locs = parse_force_locations(structure, forces)
    force_model = as_force_model(force_model, force_increment_cov)
    dummies = [] if dummy is None else dummy.layout(structure, layouts[0])
    reports = [check_detectable(structure, list(l) + dummies, locs, allow_undetectable, force_model) for l in layouts]
    if steady is None:     # the default: the steady-state filter where it exists
        steady = all(r.detectable for r in reports)
    for l, report in zip(layouts, reports):
        if steady and not report.detectable:
            raise AKFInputError("the steady-state AKF does not exist for an undetectable sensor set "
                                f"({', '.join(s.label for s in l)}); use steady=False to run the "
                                "time-varying filter and watch it drift")
    setup = FilterSetup(structure, layouts, locs, dt, model_error_cov, None, noise_cov, x0, P0, force_model, dummy)
    Y_f = setup.extend(Y)
    # classically damped structures are block-diagonal in these coordinates: cheap A P A^T
    transition = None if steady else ModalBlockTransition.detect(setup.A_a, structure.n)
    try:
        # Q, S, R and P0 were checked as the user gave them; their modal transforms need no second check
        res = filter_states(setup.A_a, setup.G_a, setup.Q_a, setup.R, Y_f, x0=setup.z0, P0=setup.Pz0, steady=steady,
                            transition=transition, check=False)
    except RiccatiError as exc:
        raise setup.riccati_error(exc) from None
    estimates = setup.estimates(res.states, res.innovations, res.gain, res.P_prior, Y, reports, terms=res.loglik_terms)
    if smooth:
        estimates = [setup.smooth(est, b, Y[b], steady) for b, est in enumerate(estimates)]
    return estimates


class FilterSetup:
    """The filter's matrices for sensor layouts of one structure and force set.

    They are built in energy-normalised modal coordinates ``x = T z`` (see
    :func:`~core_akf.statespace.modal_state_transform`), discretised there mode by mode when the
    damping is classical: the one builder behind :func:`estimate_batch` and
    :class:`core_akf.streaming.Estimator`.

    Parameters
    ----------
    structure : Structure
        The filter's model.
    layouts : list of list of Sensor
        B layouts of m sensors each.
    locs : list of tuple
        Force locations, 1-based ``(node, direction)``.
    dt : float
        Time step (s).
    model_error_cov, force_increment_cov, noise_cov
        Q, S and R as in :func:`estimate` (``noise_cov`` may give one entry per layout).
    x0, P0 : optional
        Prior mean and covariance of the physical augmented state.
    force_model : ForceModel, optional
        The forces' prior (default the random walk of ``force_increment_cov``).
    dummy : DummyMeasurements, optional
        Zero pseudo-measurements appended to every layout's channels (:meth:`extend`).

    Attributes
    ----------
    A_a : ndarray (n_a, n_a)
    G_a : ndarray (B, m, n_a)
    R : ndarray (B, m, m)
    Q_a : ndarray (n_a, n_a)
    z0, Pz0 : ndarray or None
        The prior in modal coordinates (None: zero / ``Q_a``).
    Ta, Ta_inv : ndarray (n_a, n_a)
        The transforms of the augmented state, ``x_a = Ta z_a``.
    H : ndarray (n_p, n_g)
        The forces from the force states.
    m : int
        The real channels per layout (the dummies follow them in ``G_a`` and ``R``).
    """

    def __init__(self, structure, layouts, locs, dt, model_error_cov, force_increment_cov, noise_cov, x0=None, P0=None,
                 force_model=None, dummy=None):
        from .reduced import ModalFilterModel

        self.structure, self.layouts, self.locs, self.dt = structure, layouts, locs, float(dt)
        self.m = len(layouts[0])
        self.dummy_layout = [] if dummy is None else dummy.layout(structure, layouts[0])
        self.force_model = force_model = as_force_model(force_model, force_increment_cov)
        self.filter_model = fm = ModalFilterModel(structure, locs, dt, force_model=force_model)
        T, T_inv, self.A_a = fm.T, fm.T_inv, fm.A_a
        self.nx, ng = fm.n_states, fm.H.shape[1]
        self.H = fm.H
        self.Ta = scipy.linalg.block_diag(T, np.eye(ng))
        self.Ta_inv = Ta_inv = scipy.linalg.block_diag(T_inv, np.eye(ng))
        self.G_a = np.stack([fm.observation(list(l) + self.dummy_layout) for l in layouts])
        per_layout = (isinstance(noise_cov, (list, tuple)) and len(noise_cov) > 0
                      and all(isinstance(c, dict) for c in noise_cov)) or (
            not isinstance(noise_cov, dict) and np.ndim(noise_cov) == 3)
        if per_layout and len(noise_cov) != len(layouts):
            raise AKFInputError(f"noise_cov has {len(noise_cov)} entries for {len(layouts)} layouts")
        self.R = np.stack([noise_covariance(l, noise_cov[b] if per_layout else noise_cov)
                           for b, l in enumerate(layouts)])
        if self.dummy_layout:
            self.R = np.stack([scipy.linalg.block_diag(R, dummy.variance * np.eye(len(self.dummy_layout))) for R in self.R])
        Q_a = scipy.linalg.block_diag(state_covariance(structure, model_error_cov), fm.Q_f)
        Q_a = Ta_inv @ Q_a @ Ta_inv.T
        self.Q_a = 0.5 * (Q_a + Q_a.T)
        self.z0 = None if x0 is None else Ta_inv @ as_finite_array(x0, "x0", ndim=1, shape=(self.nx + ng,))
        self.Pz0 = None if P0 is None else Ta_inv @ diag_levels(P0, self.nx + ng, "P0") @ Ta_inv.T
        if P0 is None and force_model.stationary:      # a stationary force starts from its own prior
            self.Pz0 = self.Q_a.copy()
            self.Pz0[self.nx:, self.nx:] = force_model.stationary_covariance(len(locs))

    def extend(self, Y):
        """The measurements with the dummy channels' zeros appended (the filter's channels).

        Parameters
        ----------
        Y : ndarray (..., N, m)

        Returns
        -------
        ndarray (..., N, m + m_dummy)
        """
        if not self.dummy_layout:
            return Y
        return np.concatenate([Y, np.zeros(Y.shape[:-1] + (len(self.dummy_layout),))], axis=-1)

    def riccati_error(self, exc):
        """A :class:`RiccatiError` naming the layouts whose gain failed.

        Parameters
        ----------
        exc : RiccatiError
            The error of the batched Riccati solve (its ``problems`` are batch indices).

        Returns
        -------
        RiccatiError
        """
        names = "; ".join(", ".join(s.label for s in self.layouts[b]) for b in exc.problems)
        return RiccatiError(f"steady-state gain failed for the layout(s) [{names}]: {exc}", exc.problems)

    def estimates(self, states, innovations, gain, P_prior, Y, reports, t0=0.0, terms=None):
        """One :class:`Estimate` per layout from the filter's output in modal coordinates.

        States go back to physical ``[u; u'; f]`` and gains to the physical state.

        Parameters
        ----------
        states : ndarray (B, N, n_a)
            Filtered modal states.
        innovations : ndarray (B, N, m)
        gain : ndarray (B, n_a, m)
        P_prior : ndarray (B, n_a, n_a)
        Y : ndarray (B, N, m)
            The measurements.
        reports : list of DetectabilityReport
            One per layout.
        t0 : float
            Time of the first step (s).
        terms : ndarray (B, N, m), optional
            The log-likelihood terms of the innovations.

        Returns
        -------
        list of Estimate
        """
        nx, m = self.nx, self.m
        states = states @ self.Ta.T
        gains = (self.Ta @ gain)[..., :m]              # the real channels' (dummies are the filter's own)
        S_innov = innovation_covariance(self.G_a, P_prior, self.R)[:, :m, :m]
        innovations = innovations[..., :m]
        terms = None if terms is None else terms[..., :m]
        return [Estimate(self.structure, l, self.locs, self.dt, states[b, :, :nx], states[b, :, nx:] @ self.H.T,
                         innovations[b], gains[b], reports[b], Y[b], S_innov[b],
                         (self.A_a, self.G_a[b], gain[b]), t0=t0, loglik_terms=None if terms is None else terms[b])
                for b, l in enumerate(self.layouts)]

    def smooth(self, est, b, Y, steady):
        """The smoothed estimate of layout ``b`` (:func:`core_akf.smoother.smooth` on the modal
        matrices): the filtered ``est`` with its states and forces ``x_k|N``, and
        :attr:`Estimate.force_std` and :attr:`Estimate.strain_std` their standard deviations; the
        innovations, the gain and the likelihood stay those of the filter.

        Parameters
        ----------
        est : Estimate
            The filtered estimate of layout ``b``.
        b : int
            The layout's index.
        Y : ndarray (N, m)
            Its measurements.
        steady : bool
            The steady-state smoother.

        Returns
        -------
        Estimate
            A new estimate.
        """
        from .smoother import smooth

        res = smooth(self.A_a, self.G_a[b], self.Q_a, self.R[b], self.extend(Y), x0=self.z0, P0=self.Pz0, steady=steady,
                     covariances=None, outputs=self.std_rows())
        return self.with_std(est, res.states, res.output_std)

    def std_rows(self):
        """The rows whose standard deviations a smoothed estimate carries.

        Returns
        -------
        ndarray (n_p + n_strain, n_a)
            The forces, then every strain output, on the modal state.
        """
        return np.vstack([self.filter_model.force_rows(), self.filter_model.strain_rows()])

    def with_std(self, est, states, std):
        """A smoothed estimate.

        Parameters
        ----------
        est : Estimate
            The filtered estimate of the same steps (its innovations and likelihood are kept).
        states : ndarray (N, n_a)
            The smoothed modal states.
        std : ndarray (N, n_p + n_strain)
            The standard deviations of :meth:`std_rows`.

        Returns
        -------
        Estimate
        """
        from dataclasses import replace

        states = states @ self.Ta.T
        n_p = self.H.shape[0]
        return replace(est, states=states[:, :self.nx], forces=states[:, self.nx:] @ self.H.T, force_std=std[:, :n_p],
                       strain_std=std[:, n_p:])


def estimate(structure: Structure, sensors: Layout, forces: Forces, measurements: Measurements, dt: float, *,
             model_error_cov: Covariance, force_increment_cov: Covariance | None = None, noise_cov: NoiseCovariance,
             steady: bool | None = None, allow_undetectable: bool = False, x0: ArrayLike | None = None,
             P0: ArrayLike | None = None, smooth: bool = False, force_model: ForceModel | None = None,
             dummy: DummyMeasurements | None = None) -> Estimate:
    """Estimate unknown forces and the full response with the AKF.

    Parameters
    ----------
    structure : Structure
        The filter's model (it may differ from the true structure: that is model error).
    sensors : sequence of sensor specs
        ``Sensor`` objects or strings such as ``"acc:4:y"``, ``"strain:5"``.
    forces : sequence
        Force locations ``"node:direction"`` or ``(node, direction)``.
    measurements : ndarray (N, m)
        One column per sensor in layout order (SI: m/m, m/s^2, m/s, m).
    dt : float
        Sampling interval (s).
    model_error_cov : float, ndarray
        ``Q``: variance level(s) of the state model error per step, per physical DOF
        (displacements then velocities: scalar, vector or matrix); see :func:`state_covariance`.
    force_increment_cov : float, ndarray, optional
        ``S``: variance of the force increment per step (N^2) of the random-walk force model
        (required with it; leave it out with a Matérn ``force_model``).
    noise_cov : float, ndarray or dict
        ``R``: measurement-noise variance(s), e.g. ``{"strain": (1e-6)**2, "acc": 0.01**2}``.
    steady : bool or None
        True: the steady-state gain (fast); False: the time-varying filter.  None (default,
        :data:`core_akf.defaults.DEFAULTS`): the steady-state filter, or the time-varying one for
        an undetectable set run with ``allow_undetectable`` (no steady state exists there).
    allow_undetectable : bool
        Run even if the PBH test fails (the estimate will drift).
    x0 : array_like (2n + n_g,), optional
        Prior mean of the augmented state ``[u; u'; xi]`` at step 0 (default zero); ``xi = f``
        (``n_g = n_p``) for the random walk, the force states of a Matérn model otherwise.
    P0 : float or array_like, optional
        Prior covariance at step 0 (a level, variances or the matrix; default ``Q_a``, with the
        stationary covariance of a Matérn model's force states); the steady-state filter does not
        use it.
    smooth : bool
        Smooth the states with the whole record (the RTS smoother, :func:`core_akf.smoother.smooth`):
        forces and strains are then the smoothed ones, with their standard deviations
        (:attr:`Estimate.force_std`, :attr:`Estimate.strain_std`).  Smoothing helps only a model
        the data agree with: check the consistency first (calibrate).
    force_model : ForceModel, optional
        The forces' prior (:mod:`core_akf.forcemodels`): default the random walk of
        ``force_increment_cov``; a Matérn model (``ForceModel("matern32", std=..., timescale=...)``)
        makes accelerometer-only sets detectable for zero-mean loads.
    dummy : DummyMeasurements, optional
        Zero pseudo-measurements of displacements or strains, appended to the sensors (they keep a
        random-walk filter on accelerations from drifting).

    Returns
    -------
    Estimate

    Examples
    --------
    >>> import numpy as np
    >>> from core_akf.models import s17_truss
    >>> est = estimate(s17_truss(), ["strain:13", "acc:8:y"], ["8:y"], np.zeros((100, 2)), 1e-3,
    ...                model_error_cov=1e-16, force_increment_cov=1e4, noise_cov={"strain": 1e-14, "acc": 1e-4})
    >>> est.forces.shape, est.strains.shape
    ((100, 1), (100, 34))
    """
    layout = as_layout(sensors)
    Y = as_finite_array(measurements, "measurements", ndim=2)
    if Y.shape[1] != len(layout):
        raise AKFInputError(f"measurements have {Y.shape[1]} columns for {len(layout)} sensors")
    return estimate_batch(structure, [layout], forces, Y[None], dt, model_error_cov=model_error_cov,
                          force_increment_cov=force_increment_cov, noise_cov=noise_cov, steady=steady,
                          allow_undetectable=allow_undetectable, x0=x0, P0=P0, smooth=smooth,
                          force_model=force_model, dummy=dummy)[0]
