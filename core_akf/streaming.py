"""Records without end: the AKF run chunk by chunk with its state carried over, in constant memory.

:class:`Estimator` holds one filter (its matrices, the steady-state gain, the last filtered state
and, for the time-varying form, the covariance) and turns each chunk of measurements into an
:class:`~core_akf.filter.Estimate` of that chunk alone.  Feeding a record in chunks of any sizes
gives the estimate of the whole record (to rounding: the fixed-gain recursion is the same
recursion, only started at other steps).  :meth:`Estimator.state` / :meth:`Estimator.restore`
save and reload what is carried over, so a run stopped after any chunk continues where it ended.

>>> from core_akf.models import s17_truss
>>> import numpy as np
>>> est = Estimator(s17_truss(), ["strain:13", "acc:8:y"], ["8:y"], 1e-3, model_error_cov=1e-16,
...                 force_increment_cov=1e4, noise_cov={"strain": 1e-14, "acc": 1e-4})
>>> first = est.update(np.zeros((100, 2)))
>>> second = est.update(np.zeros((50, 2)))
>>> est.n_steps, float(second.time[0])
(150, 0.1)
"""
from __future__ import annotations

import hashlib
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from .checks import as_finite_array
from .exceptions import AKFInputError
from .filter import FilterSetup, ModalBlockTransition, innovation_covariance, time_varying_filter
from .forcemodels import DummyMeasurements, ForceModel, as_force_model
from .likelihood import loglik_terms
from .recursion import lti_response
from .riccati import RiccatiError, steady_gain
from .sensors import as_layout, parse_force_locations
from .statespace import check_detectable
from .types import ArrayLike, Covariance, Forces, Layout, Measurements, NoiseCovariance

if TYPE_CHECKING:
    from .filter import Estimate
    from .structure import Structure


class CheckpointError(AKFInputError):
    """A saved filter state that does not belong to this filter (another structure, sensor set,
    force set, time step or covariances) or is not a filter state at all."""


class Estimator:
    """The AKF over a record delivered in chunks.

    Each :meth:`update` returns the :class:`~core_akf.filter.Estimate` of its chunk; the memory
    held between chunks is the filter's matrices and one state, whatever the record's length.

    Parameters
    ----------
    structure : Structure
        The filter's model.
    sensors : sequence of sensor specs
        The layout, m channels.
    forces : sequence of force specs
        The unknown force locations.
    dt : float
        Time step (s).
    model_error_cov, force_increment_cov, noise_cov
        Q, S and R as in :func:`core_akf.filter.estimate`.
    steady : bool or None
        The steady-state filter (None: where the set is detectable).
    allow_undetectable : bool
        Run even if the PBH test fails.
    x0, P0 : optional
        Prior mean and covariance of the augmented state, as in :func:`core_akf.filter.estimate`.
    t0 : float
        Time of the record's first step (s); the chunks' :attr:`~core_akf.filter.Estimate.time`
        continues from it.
    switch_tol : float
        The time-varying filter continues with its (then constant) gain once its covariance
        changes by less than this, relatively (as :func:`core_akf.filter.filter_states`).
    smooth_lag : int or "auto", optional
        Smooth with this many steps of the record after each step
        (:class:`core_akf.smoother.FixedLagSmoother`, steady filter only): :meth:`update` then
        returns the smoothed estimate of the steps ``smooth_lag`` behind the input, with
        :attr:`~core_akf.filter.Estimate.force_std` and ``strain_std``, and :meth:`finish` the
        last ones.
    force_model, dummy : optional
        The force model and dummy measurements, as in :func:`core_akf.filter.estimate`.

    Examples
    --------
    A record in two chunks gives the estimate of the record in one piece:

    >>> import numpy as np
    >>> from core_akf import estimate, simulate
    >>> from core_akf.models import s17_truss
    >>> sensors, R = ["strain:13", "acc:8:y"], {"strain": 1e-14, "acc": 1e-4}
    >>> Y = simulate(s17_truss(), sensors, ["8:y"], np.full((300, 1), 100.0), 1e-3, relative_noise=0.02,
    ...              seed=0).measurements
    >>> est = Estimator(s17_truss(), sensors, ["8:y"], 1e-3, model_error_cov=1e-16, force_increment_cov=1e4,
    ...                 noise_cov=R)
    >>> parts = np.vstack([est.update(Y[:120]).forces, est.update(Y[120:]).forces])
    >>> whole = estimate(s17_truss(), sensors, ["8:y"], Y, 1e-3, model_error_cov=1e-16, force_increment_cov=1e4,
    ...                  noise_cov=R).forces
    >>> bool(np.allclose(parts, whole, rtol=1e-9, atol=1e-9 * np.abs(whole).max()))
    True
    """

    def __init__(self, structure: Structure, sensors: Layout, forces: Forces, dt: float, *, model_error_cov: Covariance,
                 force_increment_cov: Covariance | None = None, noise_cov: NoiseCovariance, steady: bool | None = None,
                 allow_undetectable: bool = False, x0: ArrayLike | None = None, P0: Covariance | None = None,
                 t0: float = 0.0, switch_tol: float = 1e-14, smooth_lag: int | str | None = None,
                 force_model: ForceModel | None = None, dummy: DummyMeasurements | None = None):
        if not np.isfinite(dt) or dt <= 0:
            raise AKFInputError(f"dt must be a positive time step in seconds, got {dt!r}")
        self.layout = as_layout(sensors)
        self.locs = parse_force_locations(structure, forces)
        force_model = as_force_model(force_model, force_increment_cov)
        dummies = [] if dummy is None else dummy.layout(structure, self.layout)
        self.report = check_detectable(structure, list(self.layout) + dummies, self.locs, allow_undetectable, force_model)
        if steady is None:
            steady = self.report.detectable
        if steady and not self.report.detectable:
            raise AKFInputError("the steady-state AKF does not exist for an undetectable sensor set "
                                f"({', '.join(s.label for s in self.layout)}); use steady=False")
        self.setup = FilterSetup(structure, [self.layout], self.locs, dt, model_error_cov, None,
                                  noise_cov, x0, P0, force_model, dummy)
        self.dt, self.t0, self.switch_tol = float(dt), float(t0), float(switch_tol)
        self.model_error_cov, self.force_increment_cov = model_error_cov, force_increment_cov
        self.steady = bool(steady)
        s = self.setup
        self._transition = None if steady else ModalBlockTransition.detect(s.A_a, structure.n)
        self._GA = s.G_a[0] @ s.A_a
        self.n_steps = 0
        self._z = None                     # last filtered state (modal coordinates), None before step 0
        if steady:
            try:
                P, L = steady_gain(s.A_a[None], s.G_a, s.Q_a[None], s.R)
            except RiccatiError as exc:
                raise s.riccati_error(exc) from None
            # contiguous copies: a restored state is contiguous too, and BLAS may round a strided
            # operand differently, so a resumed run would differ in the last bits
            self._P, self._L = np.ascontiguousarray(P[0]), np.ascontiguousarray(L[0])
        else:
            self._P = s.Q_a.copy() if s.Pz0 is None else 0.5 * (s.Pz0 + s.Pz0.T)
            self._L = None
        self._switched = steady            # True: the fixed-gain recursion runs
        self.lagged = None
        if smooth_lag is not None:
            from .smoother import FixedLagSmoother

            if not steady:
                raise AKFInputError("fixed-lag smoothing runs on the steady-state filter (steady=True); the "
                                    "time-varying filter has no constant smoother gain")
            self.lagged = FixedLagSmoother(s.A_a, s.G_a[0], s.R[0], self._P, self._L, smooth_lag, s.std_rows())
        self.n_returned = 0                # steps returned (behind n_steps by the steps the smoother holds)
        self._fingerprint = self._digest()

    @property
    def n_channels(self):
        return len(self.layout)

    def _prior(self):
        """The prior mean of the next step (modal coordinates)."""
        if self._z is None:
            return np.zeros(self.setup.A_a.shape[0]) if self.setup.z0 is None else self.setup.z0
        return self.setup.A_a @ self._z

    def update(self, chunk: Measurements) -> Estimate:
        """Filter the next chunk of the record.

        Parameters
        ----------
        chunk : array_like (k, m)
            Measurements (SI, columns in sensor order).

        Returns
        -------
        Estimate
            The chunk's estimate (its ``time`` continues the record).
        """
        Y = np.asarray(chunk, dtype=float)
        if Y.ndim != 2 or Y.shape[1] != self.n_channels:
            raise AKFInputError(f"a chunk must have shape (steps, {self.n_channels}) for the sensors "
                                f"{[s.label for s in self.layout]}; got {Y.shape}")
        bad = np.argwhere(~np.isfinite(Y))
        if bad.size:
            r, c = bad[0]
            raise AKFInputError(f"measurements: {np.count_nonzero(~np.isfinite(Y))} NaN/infinite value(s) in the chunk "
                                f"starting at step {self.n_steps}; first at step {self.n_steps + r} "
                                f"(t = {self.t0 + (self.n_steps + r) * self.dt:.9g} s), channel {self.layout[c].label!r}")
        t0 = self.t0 + self.n_steps * self.dt
        Y_real, Y = Y, self.setup.extend(Y)           # with the dummy channels' zeros
        if Y.shape[0] == 0 and self.lagged is not None:
            return self._smoothed(*self.lagged.update(np.empty((0, self.setup.A_a.shape[0])), Y, Y, Y_real, Y))
        if Y.shape[0] == 0:
            return self.setup.estimates(np.zeros((1, 0, self.setup.A_a.shape[0])), Y[None], self._gain()[None],
                                        self._P[None], Y_real[None], [self.report], t0=t0,
                                        terms=np.zeros((1, 0, Y.shape[1])))[0]
        s = self.setup
        x = self._prior()
        if self._switched:
            L = self._L
            I_LG = np.eye(x.size) - L @ s.G_a[0]        # as core_akf.filter._steady_filter forms them
            first = L @ Y[0] + I_LG @ x
            X = lti_response((I_LG @ s.A_a)[None], L[None], Y[None], first[None])[0]
            innov = np.empty_like(Y)
            innov[0] = Y[0] - s.G_a[0] @ x
            innov[1:] = Y[1:] - X[:-1] @ self._GA.T
            terms = loglik_terms(innov, innovation_covariance(s.G_a[0], self._P, s.R[0]))
        else:
            X, innov, L, P, switched, terms = time_varying_filter(
                s.A_a[None], s.G_a, s.Q_a[None], s.R, Y[None], x[None], self._P[None], self.switch_tol,
                self._transition)
            X, innov, L, self._P, terms = X[0], innov[0], L[0], np.ascontiguousarray(P[0]), terms[0]
            if switched:
                self._switched, self._L = True, np.ascontiguousarray(L)
        self._z = X[-1].copy()
        self.n_steps += Y.shape[0]
        if self.lagged is not None:
            return self._smoothed(*self.lagged.update(X, innov, innov, Y_real, terms))
        self.n_returned = self.n_steps
        return s.estimates(X[None], innov[None], L[None], self._P[None], Y_real[None], [self.report], t0=t0,
                           terms=terms[None])[0]

    def finish(self) -> Estimate:
        """The steps a fixed-lag smoother still holds, smoothed with the rest of the record (the
        end of the record); an estimate of no steps without ``smooth_lag``.

        Returns
        -------
        Estimate
        """
        if self.lagged is None:
            return self.update(np.empty((0, self.n_channels)))
        return self._smoothed(*self.lagged.finish())

    def _smoothed(self, X, std, innov, Y, terms):
        """The estimate of steps the fixed-lag smoother returned."""
        s = self.setup
        t0 = self.t0 + self.n_returned * self.dt
        self.n_returned += X.shape[0]
        est = s.estimates(X[None], innov[None], self._L[None], self._P[None], Y[None], [self.report], t0=t0,
                          terms=terms[None])[0]
        return s.with_std(est, X, std)

    def _gain(self):
        n_a, m = self.setup.A_a.shape[0], self.setup.G_a.shape[1]      # m: the channels with any dummies
        return self._L if self._L is not None else np.zeros((n_a, m))

    # ------------------------------------------------------------------ what is carried over
    def _digest(self):
        """A fingerprint of the filter (matrices, time step, sensors, forces): a saved state is
        only restored into the filter it came from."""
        h = hashlib.sha256()
        s = self.setup
        for a in (s.A_a, s.G_a, s.Q_a, s.R):
            h.update(np.ascontiguousarray(a).tobytes())
        h.update(repr((self.dt, self.t0, self.steady, [x.label for x in self.layout], self.locs)).encode())
        if self.lagged is not None:
            h.update(f"smooth_lag {self.lagged.lag}".encode())
        return h.hexdigest()

    def state(self) -> dict[str, np.ndarray]:
        """What the filter carries to the next chunk (``numpy.savez`` it).

        Returns
        -------
        dict of str to ndarray
            The steps done, the last filtered state, the covariance and gain, and a fingerprint.
        """
        n = self.setup.A_a.shape[0]
        return {"n_steps": np.array(self.n_steps), "z": np.full(n, np.nan) if self._z is None else self._z.copy(),
                "P": self._P.copy(), "L": self._gain().copy(), "switched": np.array(self._switched),
                "started": np.array(self._z is not None), "fingerprint": np.array(self._fingerprint),
                "n_returned": np.array(self.n_returned)} | ({} if self.lagged is None else self.lagged.state())

    def restore(self, state: Mapping[str, np.ndarray]) -> Estimator:
        """Continue from a :meth:`state` saved by this filter (the same job).

        Parameters
        ----------
        state : mapping of str to ndarray
            What :meth:`state` returned (as loaded from a checkpoint).

        Returns
        -------
        Estimator
            ``self``.

        Raises
        ------
        CheckpointError
            For a state of another filter, or not a filter state at all.
        """
        try:
            fingerprint = str(np.asarray(state["fingerprint"]))
            n_steps = int(state["n_steps"])
            z, P, L = (as_finite_array(state[k], k) if k != "z" else np.asarray(state[k], float) for k in ("z", "P", "L"))
            switched, started = bool(state["switched"]), bool(state["started"])
        except (KeyError, TypeError, ValueError, AKFInputError) as exc:
            raise CheckpointError(f"not a saved filter state ({type(exc).__name__}: {exc})") from None
        if fingerprint != self._fingerprint:
            raise CheckpointError("the saved filter state belongs to another filter (structure, sensors, forces, dt, "
                                  "covariances or filter form differ); start the run anew")
        if self.lagged is not None:
            try:
                self.lagged.restore(state)
            except (KeyError, AKFInputError) as exc:
                raise CheckpointError(f"the saved state lacks the steps the fixed-lag smoother held ({exc})") from None
        self.n_returned = int(state["n_returned"]) if "n_returned" in state else n_steps
        self.n_steps, self._P, self._switched = n_steps, np.ascontiguousarray(P), switched
        self._L = np.ascontiguousarray(L) if switched else None
        self._z = z.copy() if started else None
        return self


# ---------------------------------------------------------------------------------- time-parallel
def zero_state_end(F: ArrayLike, L: ArrayLike, Y: ArrayLike, block: int = 256) -> np.ndarray:
    """The last state of ``x_k = F x_k-1 + L y_k`` over ``Y`` from ``x_-1 = 0``.

    ``x_N-1 = sum_i F^(N-1-i) L y_i``, summed block by block: the Markov parameters
    ``[L, F L, ..., F^(b-1) L]`` of one block meet every block of the record in one matrix
    product (about ``n m`` operations per step instead of the recursion's ``n^2``), and the
    blocks are joined by Horner's rule with ``F^b``.

    Parameters
    ----------
    F : ndarray (n, n)
        The closed-loop transition.
    L : ndarray (n, m)
        The input matrix (the gain).
    Y : ndarray (N, m)
        The inputs.
    block : int
        Steps per block.

    Returns
    -------
    ndarray (n,)

    Examples
    --------
    >>> import numpy as np
    >>> F, L = np.array([[0.5]]), np.array([[1.0]])
    >>> float(zero_state_end(F, L, np.ones((3, 1)))[0])      # 0.25 + 0.5 + 1
    1.75
    """
    F, L, Y = (np.asarray(a, float) for a in (F, L, Y))
    n, m = L.shape
    N = Y.shape[0]
    if N == 0:
        return np.zeros(n)
    b = max(1, min(int(block), N))
    markov = np.empty((b, n, m))                        # F^d L, d = 0 .. b-1
    markov[0] = L
    for d in range(1, b):
        markov[d] = F @ markov[d - 1]
    pad = (-N) % b
    blocks = np.vstack([np.zeros((pad, m)), Y]).reshape(-1, b, m)[:, ::-1]     # newest step first in each block
    parts = np.einsum("qdm,dnm->qn", blocks, markov)                            # each block's own contribution
    Fb = np.linalg.matrix_power(F, b)
    x = np.zeros(n)
    for v in parts:                                     # oldest block first: x <- F^b x + v
        x = Fb @ x + v
    return x


class TimeParallel:
    """The steady-state AKF over a record in pieces, the pieces filtered at the same time.

    With a constant gain the filtered state obeys ``x_k = F x_k-1 + L y_k`` (``F = (I - L G) A``),
    so a piece's states are its zero-state response plus the free response of the state it starts
    from.  Three steps:

    1. every piece's zero-state end state (:meth:`end_state`, :func:`zero_state_end`), in parallel;
    2. the start state of every piece, a short pass over the pieces' ends (:meth:`starts`);
    3. every piece filtered from its start state (:meth:`run`), in parallel: exactly the
       :class:`Estimator` of the sequential stream, restored at that step.

    Rainflow counts of the pieces merge as exactly
    (:meth:`core_akf.fatigue.FatigueAccumulator.merge`).

    Parameters
    ----------
    estimator : Estimator
        A steady-state estimator at the record's start (its matrices and prior are used; it is
        not changed).

    Examples
    --------
    >>> import numpy as np
    >>> from core_akf import simulate
    >>> from core_akf.models import s17_truss
    >>> sensors, R = ["strain:13", "acc:8:y"], {"strain": 1e-14, "acc": 1e-4}
    >>> Y = simulate(s17_truss(), sensors, ["8:y"], np.full((300, 1), 100.0), 1e-3, relative_noise=0.02,
    ...              seed=0).measurements
    >>> est = Estimator(s17_truss(), sensors, ["8:y"], 1e-3, model_error_cov=1e-16, force_increment_cov=1e4,
    ...                 noise_cov=R, steady=True)
    >>> tp = TimeParallel(est)
    >>> pieces = [Y[:100], Y[100:220], Y[220:]]
    >>> starts = tp.starts([tp.end_state(p) for p in pieces])           # 1 and 2
    >>> forces = np.vstack([tp.run(s, p).forces for s, p in zip(starts, pieces)])     # 3
    >>> whole = est.update(Y).forces
    >>> bool(np.allclose(forces, whole, rtol=1e-9, atol=1e-9 * np.abs(whole).max()))
    True
    """

    def __init__(self, estimator: Estimator):
        if not estimator.steady or estimator.lagged is not None:
            raise AKFInputError("the time-parallel filter needs the steady-state estimator (steady=True) without "
                                "fixed-lag smoothing")
        if estimator.n_steps:
            raise AKFInputError("the time-parallel filter starts from an estimator at the record's start")
        self.estimator = estimator
        s = estimator.setup
        self.L = estimator._L
        self.F = (np.eye(s.A_a.shape[0]) - self.L @ s.G_a[0]) @ s.A_a

    def end_state(self, Y: ArrayLike) -> tuple[np.ndarray, int]:
        """Step 1 for one piece: its zero-state end state and its length.

        Parameters
        ----------
        Y : ndarray (K, m)
            The piece's measurements (SI).

        Returns
        -------
        tuple
            ``(z_end (n_a,), K)``.
        """
        Y = self.estimator.setup.extend(as_finite_array(Y, "measurements", ndim=2))   # with the dummies' zeros
        return zero_state_end(self.F, self.L, Y), Y.shape[0]

    def starts(self, ends: list) -> list:
        """Step 2: the state before each piece (None for the first: the record's prior).

        Parameters
        ----------
        ends : list of (ndarray (n_a,), int)
            :meth:`end_state` of every piece, in record order.

        Returns
        -------
        list
            ``(state or None, first step)`` per piece.
        """
        x, step, out = None, 0, []
        A, s = self.estimator.setup.A_a, self.estimator.setup
        for z, K in ends:
            out.append((x, step))
            if K:
                # the prior's part: x_-1 is not a filtered state; the first step starts from the prior mean
                prior = np.zeros(A.shape[0]) if x is None and s.z0 is None else (s.z0 if x is None else A @ x)
                free = (np.eye(A.shape[0]) - self.L @ s.G_a[0]) @ prior            # F x_-1, or (I - L G) prior
                x = z + np.linalg.matrix_power(self.F, K - 1) @ free
            step += K
        return out

    def run(self, start: tuple, Y: ArrayLike) -> Estimate:
        """Step 3 for one piece: its estimate from its start state.

        Parameters
        ----------
        start : (ndarray or None, int)
            The piece's entry of :meth:`starts`.
        Y : ndarray (K, m)
            The piece's measurements.

        Returns
        -------
        Estimate
            With the piece's time.
        """
        import copy

        state, step = start
        est = copy.copy(self.estimator)
        est._z = None if state is None else np.asarray(state, float).copy()
        est.n_steps = est.n_returned = int(step)
        return est.update(Y)


def estimate_in_parallel(estimator: Estimator, pieces: list, map_pieces=map, on_piece=None) -> list:
    """Filter a record's pieces at the same time (:class:`TimeParallel`) with any ``map``.

    Parameters
    ----------
    estimator : Estimator
        A steady-state estimator at the record's start.
    pieces : list
        The record's pieces in order: arrays (K, m), or callables returning them (a file reader
        each, so that a worker reads its own piece).
    map_pieces : callable
        ``map_pieces(function, list) -> iterable`` in order: the builtin ``map`` (one process),
        joblib, or a dask client's ``lambda f, xs: client.gather(client.map(f, xs))``.
    on_piece : callable, optional
        ``on_piece(estimate, index) -> result``, run where the piece is filtered (the outputs of a
        piece: written files, fatigue counts, summaries), so that the estimates of months of data
        never travel; default the estimate itself.

    Returns
    -------
    list
        ``on_piece``'s result per piece, in record order.

    Examples
    --------
    >>> import numpy as np
    >>> from core_akf import simulate
    >>> from core_akf.models import s17_truss
    >>> sensors, R = ["strain:13", "acc:8:y"], {"strain": 1e-14, "acc": 1e-4}
    >>> Y = simulate(s17_truss(), sensors, ["8:y"], np.full((300, 1), 100.0), 1e-3, relative_noise=0.02,
    ...              seed=0).measurements
    >>> est = Estimator(s17_truss(), sensors, ["8:y"], 1e-3, model_error_cov=1e-16, force_increment_cov=1e4,
    ...                 noise_cov=R, steady=True)
    >>> peaks = estimate_in_parallel(est, [Y[:150], Y[150:]], on_piece=lambda e, i: float(e.forces.max()))
    >>> len(peaks)
    2
    """
    tp = TimeParallel(estimator)
    ends = list(map_pieces(_PieceEnd(tp), list(pieces)))
    starts = tp.starts(ends)
    return list(map_pieces(_PieceRun(tp, on_piece), [(i, s, p) for i, (s, p) in enumerate(zip(starts, pieces))]))


def _load(piece):
    return piece() if callable(piece) else piece


class _PieceEnd:
    """Step 1 on a worker (a picklable callable)."""

    def __init__(self, tp):
        self.tp = tp

    def __call__(self, piece):
        return self.tp.end_state(_load(piece))


class _PieceRun:
    """Step 3 on a worker."""

    def __init__(self, tp, on_piece):
        self.tp, self.on_piece = tp, on_piece

    def __call__(self, item):
        i, start, piece = item
        est = self.tp.run(start, _load(piece))
        return est if self.on_piece is None else self.on_piece(est, i)
