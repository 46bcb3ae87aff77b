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

import copy
import hashlib
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from ..checks import (
    AKFInputError,
    ArrayLike,
    Covariance,
    Forces,
    Layout,
    Measurements,
    NoiseCovariance,
    as_finite_array,
    check_numeric_kind,
)
from ..forcemodels import DummyMeasurements, ForceModel
from . import kernels
from .model import Filter
from .riccati import RiccatiError, steady_gain

if TYPE_CHECKING:
    from ..structure import Structure
    from .results import Estimate


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
        changes by less than this, relatively (as :func:`core_akf.filter.matrices.filter_states`).
    smooth_lag : int or "auto", optional
        Smooth with this many steps of the record after each step
        (:class:`core_akf.filter.smoother.FixedLagSmoother`, steady filter only): :meth:`update` then
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
        self.filter = f = Filter(structure, [sensors], forces, dt, model_error_cov=model_error_cov,
                                 force_increment_cov=force_increment_cov, noise_cov=noise_cov, steady=steady,
                                 allow_undetectable=allow_undetectable, x0=x0, P0=P0, force_model=force_model,
                                 dummy=dummy)
        self.layout, self.locs, self.report = f.layouts[0], f.locs, f.reports[0]
        self.dt, self.t0, self.switch_tol = f.dt, float(t0), float(switch_tol)
        self.steady = f.steady
        self.n_steps = 0
        self._z = None                     # last filtered state (modal coordinates), None before step 0
        if self.steady:
            try:
                P, L = steady_gain(f.A_a[None], f.G_a, f.Q_a[None], f.R)
            except RiccatiError as exc:
                raise f.riccati_error(exc) from None
            # contiguous copies: a restored state is contiguous too, and BLAS may round a strided
            # operand differently, so a resumed run would differ in the last bits
            self._P, self._L = np.ascontiguousarray(P[0]), np.ascontiguousarray(L[0])
        else:
            self._P = f.Q_a.copy() if f.Pz0 is None else 0.5 * (f.Pz0 + f.Pz0.T)
            self._L = None
        self._switched = self.steady       # True: the fixed-gain recursion runs
        self._seen_tail = None             # the observed samples of the last steps, None while all are
        self._hole_P = None                # the prior covariance of the exact recursion through a hole
        self.lagged = None
        if smooth_lag is not None:
            from .smoother import FixedLagSmoother

            if not self.steady:
                raise AKFInputError("fixed-lag smoothing runs on the steady-state filter (steady=True); the "
                                    "time-varying filter has no constant smoother gain")
            self.lagged = FixedLagSmoother(f.A_a, f.G_a[0], f.R[0], self._P, self._L, smooth_lag, f.model.output_rows())
        self.n_returned = 0                # steps returned (behind n_steps by the steps the smoother holds)
        self._fingerprint = self._digest()

    @property
    def model_error_cov(self):
        """Q as given (per physical DOF, see :func:`~core_akf.covariances.state_covariance`)."""
        return self.filter.model_error_cov

    @property
    def force_model(self):
        """The forces' prior (:class:`~core_akf.forcemodels.ForceModel`)."""
        return self.filter.force_model

    @property
    def gain(self):
        """The constant gain (n_a, m_f) in modal coordinates, None while the time-varying filter runs."""
        return self._L

    def smooth(self, est: Estimate, Y: Measurements) -> Estimate:
        """The smoothed estimate of a whole record this estimator filtered in one chunk.

        Parameters
        ----------
        est : Estimate
            What :meth:`update` returned for the whole record (from the record's start).
        Y : ndarray (N, m)
            The record.

        Returns
        -------
        Estimate
            With :attr:`~core_akf.filter.Estimate.force_std` and ``strain_std``.
        """
        return self.filter.smooth(est, 0, np.asarray(Y, float))

    @property
    def n_channels(self):
        return len(self.layout)

    def _prior(self):
        """The prior mean of the next step (modal coordinates)."""
        if self._z is None:
            return np.zeros(self.filter.A_a.shape[0]) if self.filter.z0 is None else self.filter.z0
        return self.filter.A_a @ self._z

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
        check_numeric_kind(chunk, "a chunk of measurements")
        try:
            Y = np.asarray(chunk, dtype=float)
        except (TypeError, ValueError) as exc:
            raise AKFInputError(f"a chunk of measurements must be numeric (NaN for a missing sample): {exc}") from None
        if Y.ndim != 2 or Y.shape[1] != self.n_channels:
            raise AKFInputError(f"a chunk must have shape (steps, {self.n_channels}) for the sensors "
                                f"{[s.label for s in self.layout]}; got {Y.shape}")
        bad = np.argwhere(np.isinf(Y))
        if bad.size:
            r, c = bad[0]
            raise AKFInputError(f"measurements: {len(bad)} infinite value(s) in the chunk starting at step "
                                f"{self.n_steps}; first at step {self.n_steps + r} "
                                f"(t = {self.t0 + (self.n_steps + r) * self.dt:.9g} s), channel {self.layout[c].label!r} "
                                "(a missing sample is NaN)")
        t0 = self.t0 + self.n_steps * self.dt
        f = self.filter
        Y_real, Y = Y, f.extend(Y)           # with the dummy channels' zeros
        if Y.shape[0] == 0 and self.lagged is not None:
            return self._smoothed(*self.lagged.update(np.empty((0, f.A_a.shape[0])), Y, Y, Y_real, Y))
        if Y.shape[0] == 0:
            empty = kernels.FilterRun(np.zeros((1, 0, f.A_a.shape[0])), Y[None], self._gain()[None], self._P[None],
                                      self._switched, np.zeros((1, 0, Y.shape[1])))
            return f.estimates(empty, Y_real[None], t0=t0)[0]
        x = self._prior()
        seen = ~np.isnan(Y)
        gapped = not seen.all()
        if self._switched and (self.steady or not gapped):     # the time-varying filter is exact through a hole
            run = kernels.with_gain(f, Y[None], self._L[None], self._P[None], x[None], loglik=True,
                                    seen_before=None if self._seen_tail is None else self._seen_tail[None],
                                    carry=None if self._hole_P is None else self._hole_P[None],
                                    at_start=self._z is None)
            self._hole_P = (None if run.hole_P is None or not np.all(np.isfinite(run.hole_P[0]))
                            else np.ascontiguousarray(run.hole_P[0]))
        else:
            run = kernels.time_varying(f, Y[None], (x[None], self._P[None]), loglik=True, switch_tol=self.switch_tol)
            self._P = np.ascontiguousarray(run.P_prior[0])
            self._switched = run.switched
            self._L = np.ascontiguousarray(run.gain[0]) if run.switched else None
        self._remember(seen)
        X, innov, terms = run.states[0], run.innovations[0], run.loglik_terms[0]
        self._z = X[-1].copy()
        self.n_steps += Y.shape[0]
        if self.lagged is not None:
            # a missing sample corrects nothing: its innovation counts as zero in the lagged sum
            return self._smoothed(*self.lagged.update(X, np.nan_to_num(innov) if gapped else innov, innov, Y_real,
                                                      terms))
        self.n_returned = self.n_steps
        return f.estimates(run, Y_real[None], t0=t0)[0]

    def _remember(self, seen):
        """Keep the observed samples of the last steps (a pattern of live channels that runs on
        into the next chunk; :func:`core_akf.filter.kernels.steady_gapped`)."""
        if self._seen_tail is None and seen.all():
            return
        tail = seen if self._seen_tail is None else np.vstack([self._seen_tail, seen])
        tail = tail[-kernels.HISTORY:]
        self._seen_tail = None if tail.all() else np.ascontiguousarray(tail)

    def restarted_at(self, step: int) -> Estimator:
        """A copy of this estimator that starts again from its prior at a step (after a gap in the
        record too long to predict through).

        Parameters
        ----------
        step : int
            The record step the copy filters next.

        Returns
        -------
        Estimator
        """
        out = copy.copy(self)
        out._z, out._seen_tail, out._hole_P = None, None, None
        out.n_steps = out.n_returned = int(step)
        if not self.steady:
            f = self.filter
            out._P = f.Q_a.copy() if f.Pz0 is None else 0.5 * (f.Pz0 + f.Pz0.T)
            out._switched, out._L = False, None
        if self.lagged is not None:
            out.lagged = self.lagged.fresh()
        return out

    def started_at(self, state: ArrayLike | None, step: int) -> Estimator:
        """A copy of this steady estimator that continues from a filtered state at a step.

        Parameters
        ----------
        state : ndarray (n_a,) or None
            The filtered modal state of the step before ``step`` (None: the record's start).
        step : int
            The step the copy filters next.

        Returns
        -------
        Estimator
        """
        out = copy.copy(self)
        out._z = None if state is None else np.asarray(state, float).copy()
        out.n_steps = out.n_returned = int(step)
        return out

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
        t0 = self.t0 + self.n_returned * self.dt
        self.n_returned += X.shape[0]
        run = kernels.FilterRun(X[None], innov[None], self._L[None], self._P[None], True, terms[None])
        return self.filter.with_std(self.filter.estimates(run, Y[None], t0=t0)[0], X, std)

    def _gain(self):
        n_a, m = self.filter.A_a.shape[0], self.filter.G_a.shape[1]      # m: the channels with any dummies
        return self._L if self._L is not None else np.zeros((n_a, m))

    # ------------------------------------------------------------------ what is carried over
    def _digest(self):
        """A fingerprint of the filter (matrices, time step, sensors, forces): a saved state is
        only restored into the filter it came from."""
        h = hashlib.sha256()
        f = self.filter
        for a in (f.A_a, f.G_a, f.Q_a, f.R):
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
        n = self.filter.A_a.shape[0]
        return {"n_steps": np.array(self.n_steps), "z": np.full(n, np.nan) if self._z is None else self._z.copy(),
                "P": self._P.copy(), "L": self._gain().copy(), "switched": np.array(self._switched),
                "started": np.array(self._z is not None), "fingerprint": np.array(self._fingerprint),
                "n_returned": np.array(self.n_returned),
                "seen_tail": np.ones((0, self.filter.G_a.shape[1]), bool) if self._seen_tail is None else self._seen_tail.copy(),
                "hole_P": np.zeros((0, n)) if self._hole_P is None else self._hole_P.copy()} | \
            ({} if self.lagged is None else self.lagged.state())

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
        tail = np.asarray(state["seen_tail"], bool) if "seen_tail" in state else np.ones((0, self.filter.G_a.shape[1]), bool)
        if tail.ndim != 2 or tail.shape[1] != self.filter.G_a.shape[1]:
            raise CheckpointError(f"the saved state's observed-sample tail has shape {tail.shape}; expected (steps, "
                                  f"{self.filter.G_a.shape[1]})")
        self._seen_tail = None if tail.all() else np.ascontiguousarray(tail)
        n = self.filter.A_a.shape[0]
        hole = np.asarray(state["hole_P"], float) if "hole_P" in state else np.zeros((0, n))
        if hole.shape not in ((0, n), (n, n)) or not np.all(np.isfinite(hole)):
            raise CheckpointError(f"the saved state's hole covariance has shape {hole.shape} or is not finite; expected "
                                  f"({n}, {n}) or none")
        self._hole_P = np.ascontiguousarray(hole) if hole.shape == (n, n) else None
        self.n_steps, self._P, self._switched = n_steps, np.ascontiguousarray(P), switched
        self._L = np.ascontiguousarray(L) if switched else None
        self._z = z.copy() if started else None
        return self
