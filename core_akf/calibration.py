"""Learning the model and the covariances from a record: maximum likelihood over the stiffness
factor and the covariance levels (Q, S, R per sensor kind).

The log-likelihood of the innovations (:mod:`core_akf.filter.likelihood`) says how probable a record is
under a filter's model and covariances; it peaks at the model that made the record.  Each
evaluation runs the steady-state filter straight to the innovations (one batched Riccati solve
and the lifted recursion to the predicted channels, :func:`steady_logliks`), so a whole stack of
parameter sets costs little more than one: the gradient's central differences and a grid scan
run as one batch each.

The parameters are searched in logarithms (a factor 2 up is as far as a factor 2 down):
``stiffness_factor`` multiplies the starting model's stiffness (every frequency by its square
root); ``damping`` multiplies its modal damping ratio; ``noise_cov`` multiplies R, one factor per
sensor kind; ``force_increment_cov`` and ``model_error_cov`` multiply S and Q; ``force_std`` and
``force_timescale`` multiply the standard deviation and the time scale of a Matérn force model
(:mod:`core_akf.forcemodels`), one factor for all forces; ``force_band`` multiplies both edges of a
Butterworth model's band.  The stiffness is scanned on a grid first (the likelihood
of a frequency can have several peaks); then L-BFGS-B refines all of them together.  Standard
errors come from the curvature of the log-likelihood at the optimum (the observed information),
and robust ones from the per-step scores as well (the sandwich, :mod:`core_akf.inference`): the
first hold only if the model made the record, the second also when it did not (a force prior
that does not fit the loads, the usual case), and a warning names the parameters where the two
differ by more than :data:`core_akf.inference.MISFIT_RATIO`.

A force prior's parameters can also be fitted by the Whittle likelihood of the record's signal
bins (:mod:`core_akf.whittle`, ``method`` of :func:`calibrate`): band-limited loads leave most
frequency bins empty, and a Matérn prior fitted to every bin by the time-domain likelihood bends
to them.  ``method = "auto"`` chooses by the share of bins that hold signal.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .checks import AKFInputError, Covariance, Forces, Layout, Measurements, NoiseCovariance, as_measurements
from .covariances import noise_covariance
from .defaults import default
from .filter import kernels
from .filter.kernels import steady_logliks
from .filter.model import Filter
from .forcemodels import DummyMeasurements, ForceModel, as_force_model
from .inference import MISFIT_RATIO, information_ratio, sandwich_covariance
from .whittle import SIGNAL_RATIO, output_spectrum, signal_bins, stationary, structural_part, whittle_terms

if TYPE_CHECKING:
    import pandas as pd

    from .structure import Structure

#: the parameters :func:`calibrate` can learn
PARAMETERS = ("stiffness_factor", "frequencies", "damping", "noise_cov", "force_increment_cov", "model_error_cov",
              "force_std", "force_timescale", "force_band")
#: the parameters of a stationary force model that may be learnt one per force (``force_std:forces``)
FORCE_PARAMETERS = ("force_std", "force_timescale", "force_band")
#: central-difference step of the gradient and the curvature, in natural-log units (a 1e-4 relative change)
LOG_STEP = 1e-4
#: ``model_error_cov`` is searched this many times the decades below its start (once above): a
#: truth without model error lies at Q -> 0, which the job's Q (1e-16) is 6 decades above on S17
MODEL_ERROR_DECADES_BELOW = 2
#: central-difference step of the curvature (standard errors), in natural-log units
CURVATURE_STEP = 10 * LOG_STEP
#: on a record of this many steps or more, the search runs on its first :data:`HEAD_FRACTION` before
#: the whole (:func:`_maximise`): the grid and most iterations at a fraction of the cost
HEAD_FROM = 32768
HEAD_FRACTION = 0.25
#: the search's gradient tolerance in units of the curvature (about per standard error): the search
#: of a record's head, which only starts the whole record's, and the whole record's search in the
#: head's metric, where the likelihood is nearly round, stop at 0.01 of a standard error from the
#: optimum (the ambient S17 fit: 105 filters fewer, every factor moved by less than 0.01 of its
#: robust error); a plain search keeps :data:`GTOL`
ROUGH_GTOL = 1e-2
#: the plain search's gradient tolerance, per unit of each parameter's curvature
GTOL = 1e-4
#: the one factor ``frequencies`` fits on the frequencies of every mode it does not list: left at
#: the model's, the uncalibrated modes pull the listed ones (quasi-static response, aliasing)
REST_FREQUENCIES = "frequencies:rest"
#: a Butterworth force model's band is learnt up to this fraction of the Nyquist frequency
BAND_BELOW_NYQUIST = 0.95
#: the likelihoods that fit a force prior (``method`` of :func:`calibrate`)
METHODS = ("auto", "time", "whittle")
#: ``method = "auto"`` fits a force prior by the Whittle likelihood when at most this fraction of the
#: record's frequency bins stand above its noise floor (:func:`core_akf.whittle.signal_bins`)
AUTO_SIGNAL_FRACTION = 0.5
#: points of the grid that scans a stiffness, a frequency or a time scale before the joint search
GRID_POINTS = 25
#: finer grids (each over two steps of the one before) around the best point of the grid
GRID_REFINEMENTS = 2
#: a parameter whose log-likelihood changes by less than this over its whole search range is not
#: identifiable from the record
FLAT = 1e-3
#: the factors (decades either side of 1) at which :func:`_held_levels` tries a held covariance level
HELD_GRID = (-4.0, -3.0, -2.0, -1.0, 0.0, 1.0, 2.0)
#: a held level whose best factor raises the log-likelihood by more than this (half the 0.1 %
#: quantile of chi-squared with one degree of freedom) does not fit the record
HELD_LOGLIK = 5.4
#: a fitted parameter that learning a held level would move by more than this many robust
#: standard errors is named in a warning
HELD_MOVE = 2.0
#: what :func:`calibrate` does with a held level the record rejects and a fitted parameter leans on
HELD_POLICIES = ("learn", "warn")
#: a log-factor whose standard error exceeds this (the factor uncertain to more than e-fold) is
#: named as poorly identified by the record
POORLY_IDENTIFIED = 1.0


@dataclass
class CalibrationResult:
    """Outcome of :func:`calibrate`.

    Attributes
    ----------
    values : dict
        The fitted values: ``stiffness_factor`` relative to the structure given;
        ``frequency_factors``, the factors on the frequencies of modes 1..k (the rest factor for a
        mode not fitted on its own); ``rest_frequency_factor``, the one factor on every mode
        ``frequencies`` does not list (``frequencies:rest``); ``damping_factor``, the factor on its
        modal damping ratio; ``noise_cov`` a dict of variances per sensor kind (SI^2) when R was
        given per kind and learnt per kind, else a list of variances per channel;
        ``force_increment_cov`` and ``model_error_cov`` levels; ``force_std`` (N) and
        ``force_timescale`` (s) of a Matérn force model, one per force; ``force_band`` (Hz,
        ``[f_low, f_high]``, or one per force) of a Butterworth model.
    multipliers : dict
        The fitted factor of each parameter on its starting value (``noise_cov:acc``,
        ``noise_cov:strain:13``, ``frequencies:2``, ...).
    std_errors : dict
        The standard error of each factor, relative (the standard error of its natural log,
        from the observed information); NaN where the curvature is not negative.  Right only
        if the model made the record.
    loglik_before, loglik_after : float
        The record's log-likelihood with the starting and the fitted values.
    warnings : list of str
        A fit on a search bound, a flat likelihood (a parameter the record cannot identify), robust
        errors far from the observed ones, a fitted parameter that leans on a held level
        (:attr:`held_levels`).
    evaluations : int
        Filters run.
    seconds : float
        Wall time.
    force_model : ForceModel or None
        The fitted force model (the starting one with ``force_std``/``force_timescale`` applied);
        None for the random walk (its ``S`` is in :meth:`apply`).
    layout : tuple of Sensor
        The layout of the fit.
    consistency_before, consistency_after : dict
        Per channel, the innovation RMS over its predicted standard deviation (after the first 5 %
        of the record; about 1 when the model and the covariances fit) with the starting and the
        fitted values.
    robust_std_errors : dict
        The same keys as ``std_errors``: the robust (sandwich) standard errors from the per-step
        scores with their autocorrelation (:func:`core_akf.inference.sandwich_covariance`); they
        hold also when the model does not fit the record (a wrong force prior).
    hac_bandwidth : float
        The autocorrelation lags (steps) the robust errors took into account (frequency bins when
        only a Whittle fit ran).
    method : str
        The likelihood that fitted the force prior: ``"whittle"`` (its spectrum against the record's
        periodogram over the signal bins; every other parameter by the time-domain likelihood after
        it) or ``"time"``.
    method_reason : str
        Why that likelihood: as asked, or the rule of ``method = "auto"`` with the record's figures.
    filter_modes : int or None
        The modes of the reduced filter the fit ran on (``n_modes``); None: the structure as given.
    notes : list of str
        What the fit did beyond the parameters asked: ``frequencies`` under a stationary force
        prior fits the prior's two parameters with them, unless ``parameters`` names one.
    whittle_loglik : tuple of float or None
        The Whittle log-likelihood of the signal bins before and after its fit (None for
        ``"time"``).  The time-domain ``loglik_after`` may then be below ``loglik_before``: it
        also weighs the bins without signal, which the Whittle fit leaves out on purpose.
    held_levels : dict
        The covariance levels the fit held (``model_error_cov``, ``force_increment_cov``,
        ``noise_cov:<kind>``) that do not fit the record: by level, ``loglik_gain`` (how much the
        log-likelihood rises at its best factor, the fitted parameters held), ``best_factor`` and
        ``moves``, the change in robust standard errors that learning the level as well would
        make to each fitted parameter (one Newton step).  A move beyond :data:`HELD_MOVE` is a
        warning naming the parameter: its value leans on the held level.
    """

    values: dict
    multipliers: dict
    std_errors: dict
    loglik_before: float
    loglik_after: float
    warnings: list = field(default_factory=list)
    evaluations: int = 0
    seconds: float = 0.0
    force_model: object = None
    layout: tuple = ()
    consistency_before: dict = field(default_factory=dict)
    consistency_after: dict = field(default_factory=dict)
    robust_std_errors: dict = field(default_factory=dict)
    hac_bandwidth: float = 0.0
    method: str = "time"
    method_reason: str = ""
    whittle_loglik: tuple | None = None
    filter_modes: int | None = None
    notes: list = field(default_factory=list)
    held_levels: dict = field(default_factory=dict)

    def summary(self) -> pd.DataFrame:
        """The fit as a table, as ``akf calibrate`` prints it: a row per parameter (``kind``
        "parameter": its ``factor``, relative ``std_error`` and ``robust_std_error``) and a row per channel (``kind``
        "consistency": innovation RMS over predicted, ``before`` and ``after``).  ``attrs`` holds
        the log-likelihood before and after, the filters run, the seconds and the warnings.

        Returns
        -------
        pandas.DataFrame
        """
        import pandas as pd

        rows = [{"kind": "parameter", "name": n, "factor": f, "std_error": self.std_errors[n],
                 "robust_std_error": self.robust_std_errors.get(n, np.nan)} for n, f in self.multipliers.items()]
        rows += [{"kind": "consistency", "name": c, "before": b, "after": self.consistency_after.get(c, np.nan)}
                 for c, b in self.consistency_before.items()]
        frame = pd.DataFrame(rows, columns=["kind", "name", "factor", "std_error", "robust_std_error", "before", "after"])
        frame.attrs = {k: v for k, v in self.to_dict().items() if k in ("loglik_before", "loglik_after", "evaluations",
                                                                          "seconds", "warnings")}
        return frame

    def to_dict(self) -> dict:
        """The fit's JSON block: factors and their standard errors (observed information and
        robust, with the same keys), the log-likelihood and the
        consistency per channel before and after, the warnings, the filters run and the seconds.

        Returns
        -------
        dict
        """
        return {"multipliers": dict(self.multipliers), "std_errors": dict(self.std_errors),
                "robust_std_errors": dict(self.robust_std_errors), "hac_bandwidth_steps": self.hac_bandwidth,
                "loglik_before": self.loglik_before, "loglik_after": self.loglik_after,
                "consistency_before": dict(self.consistency_before), "consistency_after": dict(self.consistency_after),
                "warnings": list(self.warnings), "evaluations": self.evaluations, "seconds": self.seconds,
                "method": self.method, "method_reason": self.method_reason,
                "whittle_loglik": None if self.whittle_loglik is None else list(self.whittle_loglik),
                "filter_modes": self.filter_modes, "notes": list(self.notes), "held_levels": dict(self.held_levels)}

    def apply(self, structure: Structure, sensors: Layout, model_error_cov: Covariance, force_increment_cov: Covariance,
              noise_cov: NoiseCovariance) -> tuple:
        """The filter's model and covariances with the fitted factors.

        Parameters
        ----------
        structure : Structure
            The starting model the fit began from.
        sensors : sequence of sensor specs
            The layout.
        model_error_cov, force_increment_cov, noise_cov
            The starting Q, S and R.

        Returns
        -------
        structure : Structure
            The model with the fitted stiffness factor.
        model_error_cov, force_increment_cov : float or ndarray
            Q and S with their fitted factors (S None under a Matérn force model: see
            :attr:`force_model`).
        noise_cov : ndarray (m, m)
            R with its fitted factor per sensor kind.
        """
        m = self.multipliers
        model = structure if "stiffness_factor" not in m else structure.scaled(m["stiffness_factor"])
        model = with_frequencies(model, m)
        if "damping" in m:
            model = model.with_damping(np.asarray(structure.damping, float) * m["damping"])
        R = noise_covariance(sensors, noise_cov)
        if R.shape[0] != len(self.layout):
            raise AKFInputError(f"the fit was made for {len(self.layout)} sensors; got {R.shape[0]}")
        scale = noise_scale(self.layout, m)
        R = R * np.outer(scale, scale)
        Q = np.asarray(model_error_cov, float) * m.get("model_error_cov", 1.0)
        S = None if force_increment_cov is None else np.asarray(force_increment_cov, float) * m.get("force_increment_cov", 1.0)
        return model, Q, S, R


def noise_scale(layout: Layout, multipliers: dict) -> np.ndarray:
    """The standard-deviation factor of each channel: the square root of its kind's factor
    (``noise_cov:acc``) times its own (``noise_cov:acc:8:y``).

    Parameters
    ----------
    layout : sequence of Sensor
        m sensors.
    multipliers : dict
        Factors on the noise variances by name, as :attr:`CalibrationResult.multipliers`.

    Returns
    -------
    ndarray (m,)
    """
    return np.array([np.sqrt(multipliers.get(f"noise_cov:{s.kind}", 1.0) * multipliers.get(f"noise_cov:{s.label}", 1.0))
                     for s in layout])


def frequency_factors(multipliers: dict) -> np.ndarray:
    """The factors on the frequencies of modes 1..k (``frequencies:rest``, or 1, for a mode not
    fitted on its own).

    Parameters
    ----------
    multipliers : dict
        Factors by name, as :attr:`CalibrationResult.multipliers` (``frequencies:<mode>``,
        ``frequencies:rest``).

    Returns
    -------
    ndarray (k,)
        Empty without a ``frequencies:<mode>`` entry.
    """
    fitted = {int(n.split(":")[1]): v for n, v in multipliers.items()
              if n.startswith("frequencies:") and n != REST_FREQUENCIES}
    factors = np.full(max(fitted, default=0), float(multipliers.get(REST_FREQUENCIES, 1.0)))
    for k, v in fitted.items():
        factors[k - 1] = v
    return factors


def with_frequencies(structure: Structure, multipliers: dict) -> Structure:
    """``structure`` with the fitted frequencies of ``multipliers``: each ``frequencies:<mode>``
    on its mode and ``frequencies:rest`` on every other mode (a stiffness factor of its square,
    the listed modes then set on their own).

    Parameters
    ----------
    structure : Structure
    multipliers : dict
        Factors by name, as :attr:`CalibrationResult.multipliers`.

    Returns
    -------
    Structure
        ``structure`` itself without a ``frequencies:`` entry.
    """
    rest = float(multipliers.get(REST_FREQUENCIES, 1.0))
    model = structure if rest == 1.0 else structure.scaled(rest ** 2)
    factors = frequency_factors(multipliers)
    return model if not factors.size or np.all(factors == rest) else model.with_frequency_factors(factors / rest)


class _Problem:
    """The log-likelihood as a function of the log-factors ``u`` of the chosen parameters: an
    optimiser over :meth:`Filter.with_structure` and :meth:`Filter.with_levels` of one filter."""

    def __init__(self, base, Y, names, modes=(), residual=None):
        self.base, self.modes = base, tuple(modes)
        # a reduced filter's dropped modes' noise (m, m), in base's R: the response to the model
        # error, so it scales with Q's factor, not with the channels' noise factors
        self.residual = residual
        layout, locs = base.layouts[0], base.locs
        self.layout, self.locs = layout, locs
        self.kinds = sorted({s.kind for s in layout})
        self.names = []
        for name in names:
            if name == "noise_cov":
                self.names += [f"noise_cov:{k}" for k in self.kinds]
            elif name == "noise_cov:channels":
                self.names += [f"noise_cov:{s.label}" for s in layout]
            elif name == "frequencies":
                self.names += [f"frequencies:{k}" for k in self.modes]
                if base.structure.n > len(self.modes):
                    self.names.append(REST_FREQUENCIES)
            elif name in tuple(f"{b}:forces" for b in FORCE_PARAMETERS):
                self.names += [f"{name.split(':')[0]}:{node}:{d}" for node, d in locs]
            else:
                self.names.append(name)
        self._filters = {}
        self.evaluations = 0
        self.best = -np.inf
        self._on_head = False
        self.expected = 0                 # the evaluations the fit is expected to take (set by calibrate)
        self.progress = None              # called as progress(evaluations, expected, best log-likelihood)
        self.Y = base.extend(Y)

    def model_filter(self, p):
        """The filter of the model parameters in ``p`` (log-factors by name), kept per set."""
        freq = tuple(round(float(p.get(f"frequencies:{k}", 0.0)), 12) for k in (*self.modes, "rest"))
        key = (round(float(p.get("stiffness_factor", 0.0)), 12), round(float(p.get("damping", 0.0)), 12), freq)
        if key == (0.0, 0.0, (0.0,) * len(freq)):
            return self.base
        if key not in self._filters:
            structure = self.base.structure
            model = structure if key[0] == 0.0 else structure.scaled(float(np.exp(key[0])))
            if any(freq):
                model = with_frequencies(model, {f"frequencies:{k}": np.exp(x) for k, x in zip((*self.modes, "rest"), freq)})
            if key[1] != 0.0:
                model = model.with_damping(np.asarray(structure.damping, float) * np.exp(key[1]))
            self._filters[key] = self.base.with_structure(model)
            if len(self._filters) > 64:
                self._filters.pop(next(iter(self._filters)))
        return self._filters[key]

    def filter_at(self, u):
        """The :class:`~core_akf.filter.Filter` of the log-factors ``u``."""
        p = dict(zip(self.names, u))
        std, scale_t = self.force_factors(p)
        q, r = np.exp(p.get("model_error_cov", 0.0)), noise_scale(self.layout, {n: np.exp(x) for n, x in p.items()})
        f = self.model_filter(p).with_levels(q=q, s=np.exp(p.get("force_increment_cov", 0.0)) * std ** 2, r=r,
                                             timescale=scale_t)
        if self.residual is not None and (q != 1.0 or np.any(r != 1.0)):
            m = len(self.residual)
            f.R = np.array(f.R, float)                 # R r r^T scaled the dropped modes' noise too: q instead
            f.R[..., :m, :m] += (q - np.outer(r, r)) * self.residual
        return f

    def matrices(self, u):
        """``(A_a, G_a, Q_a, R)`` of the log-factors ``u``."""
        f = self.filter_at(u)
        return f.A_a, f.G_a[0], f.Q_a, f.R[0]

    def force_factors(self, p):
        """The factors on each force's std and time scale of the log-factors ``p`` (by name): one
        for all (``force_std``) times one per force (``force_std:8:y``).  A factor on a band
        (``force_band``) is the inverse of one on the time scale.

        Returns
        -------
        std, timescale : ndarray (n_p,)
        """
        u = {}
        for base in FORCE_PARAMETERS:
            own = np.array([p.get(f"{base}:{node}:{d}", 0.0) for node, d in self.locs])
            u[base] = p.get(base, 0.0) + own
        return np.exp(u["force_std"]), np.exp(u["force_timescale"] - u["force_band"])

    def consistency(self, u):
        """Per channel, the innovation RMS over its predicted standard deviation under the log-factors
        ``u``: one steady kernel run, and the estimate's own diagnostics
        (:func:`~core_akf.filter.results.sensor_diagnostics`)."""
        f = self.filter_at(u)
        est = f.estimates(kernels.steady(f, self.Y[None], loglik=True), self.Y[None, :, :len(self.layout)])[0]
        return {d["channel"]: d["consistency"] for d in est.diagnostics()}

    def logliks(self, U, per_step=False):
        """The log-likelihood at every row of ``U`` (one batch), (B,); per step (B, N) with ``per_step``."""
        mats = [self.matrices(u) for u in np.atleast_2d(U)]
        self.evaluations += len(mats)
        A, G, Q, R = (np.stack(x) for x in zip(*mats))
        out = steady_logliks(A, G, Q, R, self.Y, per_step=per_step)
        total = out.sum(axis=1) if per_step else out
        finite = total[np.isfinite(total)]
        if finite.size and not self._on_head:         # the best of the whole record only
            self.best = max(self.best, float(finite.max()))
        self.report_progress()
        return out

    @contextmanager
    def on_head(self, fraction):
        """Within the block, the likelihood is that of the record's first ``fraction``."""
        Y = self.Y
        self.Y, self._on_head = Y[:max(1, int(Y.shape[0] * fraction))], True
        try:
            yield
        finally:
            self.Y, self._on_head = Y, False

    def report_progress(self):
        """Tell ``progress`` the evaluations so far, the expected count (never below them) and the
        best log-likelihood."""
        if self.progress is not None:
            self.expected = max(self.expected, self.evaluations)
            self.progress(self.evaluations, self.expected, self.best)


def calibrate(structure: Structure, sensors: Layout, forces: Forces, measurements: Measurements, dt: float, *,
              parameters: list[str], model_error_cov: Covariance, force_increment_cov: Covariance | None = None,
              noise_cov: NoiseCovariance, stiffness_range: tuple[float, float] | None = None,
              decades: float | None = None, modes: Sequence[int] | None = None,
              force_model: ForceModel | None = None, dummy: DummyMeasurements | None = None,
              start: dict | None = None, progress: Callable[[int, int, float], None] | None = None,
              method: str = "auto", n_modes: int | str | None = None, held: str = "warn") -> CalibrationResult:
    """Fit the filter's model and covariances to a record by maximum likelihood.

    Parameters
    ----------
    structure : Structure
        The starting model (the filter's model before calibration).
    sensors : sequence of sensor specs
        The layout, m channels; it must be detectable (the steady-state filter is used).
    forces : sequence of force specs
        The unknown force locations.
    measurements : array_like (N, m)
        The record (SI); NaN is a missing sample (the steady filter's likelihood with its cached gains per
        pattern of observed channels, :func:`core_akf.filter.kernels.steady_gapped`).
    dt : float
        Time step (s).
    parameters : list of str
        What to learn, a subset of :data:`PARAMETERS`: ``noise_cov`` learns one factor per sensor
        kind of the layout; ``noise_cov:<kind>`` (``noise_cov:acc``) the factor of one kind only,
        ``noise_cov:channels`` one factor per channel; ``frequencies`` a factor per mode of
        ``modes`` and one on every other mode (``frequencies:rest``), with a stationary force
        prior's two parameters unless one of them is named (see :attr:`CalibrationResult.notes`);
        ``force_std`` and ``force_timescale`` the parameters of a Matérn ``force_model``
        (one factor for all forces; ``force_std:forces``, ``force_timescale:forces`` one per force),
        ``force_std`` and ``force_band`` those of a Butterworth one (a factor on both band edges).
    model_error_cov, force_increment_cov, noise_cov
        The starting Q, S and R, as in :func:`core_akf.filter.estimate`.
    stiffness_range : (float, float), optional
        The range of the stiffness factor (default ``calibration_stiffness_range`` of
        :data:`core_akf.defaults.DEFAULTS`).
    decades : float, optional
        The covariance factors are searched this many decades either side of 1 (default
        ``calibration_decades``).
    modes : sequence of int, optional
        The modes (1-based) whose frequencies ``frequencies`` learns (default
        :func:`calibration_modes`).
    force_model, dummy : optional
        The force model (its parameters are the starting ones) and dummy measurements, as in
        :func:`core_akf.filter.estimate`.
    start : dict, optional
        Starting factors by name, as :attr:`CalibrationResult.multipliers` (``"frequencies:2":
        0.976``, from an operational modal analysis): the search starts there, and a frequency or
        stiffness factor with a start is not scanned on a grid.  Each must lie inside its search
        range.
    progress : callable, optional
        Called after every batch of filters as ``progress(evaluations, expected, best)``: the
        filters run so far, the number the fit is expected to take (an estimate: the grid, 30
        gradient steps and the curvature; it grows when exceeded) and the best log-likelihood so
        far.  ``akf calibrate`` draws it as a progress bar with an ETA.
    method : {"auto", "time", "whittle"}
        The likelihood that fits a stationary force prior's parameters (``force_std``,
        ``force_timescale``, ``force_band``): ``"time"`` the filter's likelihood of every sample;
        ``"whittle"`` the Whittle likelihood over the record's signal bins (the frequency bins
        where it stands :data:`core_akf.whittle.SIGNAL_RATIO` times above its noise floor,
        :mod:`core_akf.whittle`), the other parameters then by the time-domain likelihood with the
        force prior held; ``"auto"`` (default) takes the Whittle likelihood for a Matérn prior when at most
        :data:`AUTO_SIGNAL_FRACTION` of the bins hold signal (band-limited loads: the time-domain
        likelihood would fit the prior to the empty bins), else the time-domain one (loads that
        fill the band, a Butterworth prior whose band leaves the empty bins empty, a random
        walk, a record with holes).
    n_modes : int or "band", optional
        Fit on a filter of the structure's lowest modes with a static correction, the dropped
        modes' response to the model error added to R
        (:meth:`~core_akf.filter.model.FilterModel.residual_noise`), as placement does: an int,
        or ``"band"`` for the modes below 3x the Nyquist frequency
        (:func:`core_akf.defaults.band_modes`).  That added noise scales with the factor on
        ``model_error_cov`` when Q is learnt, not with the channels' noise factors.  The factors
        found apply to ``structure`` as given (:meth:`CalibrationResult.apply`).  Default: the
        structure as given.  A model with many modes far above the record's band fits several
        times faster (a 147-DOF 3-D truss at 512 Hz: 117 modes, 3x faster, the stiffness factor
        within 2e-6 of the full model's).
    held : {"learn", "warn"}
        What to do with a covariance level the fit held (``model_error_cov``, the random walk's
        ``force_increment_cov``, the noise of a sensor kind not learnt) that the record rejects
        and on which a fitted parameter leans (:attr:`CalibrationResult.held_levels`: its best
        factor raises the log-likelihood by more than :data:`HELD_LOGLIK`, and learning it would
        move a fitted parameter by more than :data:`HELD_MOVE` robust standard errors):
        ``"learn"`` fits again with those levels learnt as well, from the first fit's values
        (said in :attr:`CalibrationResult.notes`; the refit costs about as many filters again);
        ``"warn"`` (default) keeps them and names the parameters in a warning.

    Returns
    -------
    CalibrationResult

    Raises
    ------
    AKFInputError
        For an unknown parameter, a parameter given twice, a record too short to identify
        anything, a starting level of zero for a covariance to scale, damping to fit on a model
        whose damping is not a modal ratio, a likelihood that is not finite at the start, an
        unknown ``method``, or ``"whittle"`` where it cannot run (no force parameter, dummy
        measurements, missing samples, an unstable model, too few signal bins).

    Examples
    --------
    A record of the true S17 truss, and a filter model 5 % too stiff:

    >>> import numpy as np
    >>> from core_akf import simulate
    >>> from core_akf.loads import band_limited_white_noise
    >>> from core_akf.models import s17_truss
    >>> sensors, loads = ["strain:13", "strain:26", "acc:8:y"], band_limited_white_noise(2000, 1e-3, 200.0, 0, 50, seed=1)
    >>> sim = simulate(s17_truss(), sensors, ["8:y"], loads[:, None], 1e-3, relative_noise=0.02, seed=0)
    >>> fit = calibrate(s17_truss().scaled(1.05), sensors, ["8:y"], sim.measurements, 1e-3,
    ...                 parameters=["stiffness_factor"], model_error_cov=1e-16, force_increment_cov=1e3,
    ...                 noise_cov=np.diag(sim.noise_std ** 2))
    >>> round(1.05 * fit.values["stiffness_factor"], 2), fit.loglik_after > fit.loglik_before
    (1.0, True)
    """
    return _calibrate(structure, sensors, forces, measurements, dt, parameters=parameters,
                      model_error_cov=model_error_cov, force_increment_cov=force_increment_cov, noise_cov=noise_cov,
                      stiffness_range=stiffness_range, decades=decades, modes=modes, force_model=force_model,
                      dummy=dummy, start=start, progress=progress, method=method, n_modes=n_modes, held=held)


def _calibrate(structure: Structure, sensors: Layout, forces: Forces, measurements: Measurements, dt: float, *,  # noqa: C901
               parameters: list[str], model_error_cov: Covariance, force_increment_cov: Covariance | None = None,
               noise_cov: NoiseCovariance, stiffness_range: tuple[float, float] | None = None,
               decades: float | None = None, modes: Sequence[int] | None = None,
               force_model: ForceModel | None = None, dummy: DummyMeasurements | None = None,
               start: dict | None = None, progress: Callable[[int, int, float], None] | None = None,
               method: str = "auto", n_modes: int | str | None = None, held: str = "warn",
               information: tuple | None = None) -> CalibrationResult:
    """:func:`calibrate`; ``information`` ``(names, -H)``: the observed information of an earlier
    fit of some of the parameters, whose optimum ``start`` holds -- the refit that learns a held
    level as well searches the whole record from there in that metric (no grid, no head)."""
    start_time = time.perf_counter()
    if held not in HELD_POLICIES:
        raise AKFInputError(f"held must be one of {list(HELD_POLICIES)}, got {held!r}")
    Y = as_measurements(measurements, "measurements", ndim=2)
    force_model = as_force_model(force_model, force_increment_cov)
    if not isinstance(parameters, str) and not (isinstance(parameters, (list, tuple)) and all(isinstance(n, str) for n in parameters)):
        raise AKFInputError(f"parameters must be a list of parameter names (e.g. [\"stiffness_factor\"]), got {parameters!r}")
    asked = list([parameters] if isinstance(parameters, str) else parameters)
    asked_method, asked_modes = method, modes
    own = ("force_std", "force_band") if force_model.kind == "butterworth" else ("force_std", "force_timescale")
    if force_model.stationary and "force_increment_cov" in asked:
        raise AKFInputError(f"force_increment_cov is the random walk's S; the {force_model.kind} force model learns "
                            f"{own[0]} and {own[1]}")
    if not force_model.stationary and any(n.startswith(FORCE_PARAMETERS) for n in asked):
        raise AKFInputError("force_std and force_timescale are the parameters of a Matérn force model (matern12, "
                            "matern32 or matern52), force_std and force_band those of a Butterworth one; the random "
                            "walk learns force_increment_cov")
    other = [n for n in asked if n.startswith(FORCE_PARAMETERS) and not n.startswith(own)]
    if other:
        raise AKFInputError(f"cannot calibrate {other} of the {force_model.kind} force model: its parameters are "
                            f"{own[0]} and {own[1]}")
    filter_structure, residual, n_kept = _reduced(structure, sensors, forces, dt, n_modes, force_model, model_error_cov,
                                                  parameters, modes)
    base = Filter(filter_structure, [sensors], forces, dt, model_error_cov=model_error_cov,
                  noise_cov=noise_cov if residual is None else noise_covariance(sensors, noise_cov) + residual,
                  steady=True, force_model=force_model, dummy=dummy)
    layout, locs = base.layouts[0], base.locs
    names = _check_parameters(parameters, layout)
    notes = []
    if "frequencies" in names and force_model.stationary and not any(n.startswith(FORCE_PARAMETERS) for n in names):
        names += list(own)
        notes.append(f"frequencies: the force prior's {own[0]} and {own[1]} were fitted with them (a prior whose "
                     "spectrum slopes at a mode, unlike the loads', moves that mode's frequency)")
    if Y.shape[1] != len(layout):
        raise AKFInputError(f"measurements have {Y.shape[1]} columns for {len(layout)} sensors")
    force_model.parameters(len(locs))
    if "damping" in names and not _modal_ratio(structure.damping):
        raise AKFInputError(f"damping is calibrated as a factor on the model's modal damping ratio; this model's damping "
                            f"is {structure.damping!r} (give it a modal ratio, e.g. 0.01)")
    _level(model_error_cov, "model_error_cov", "model_error_cov" in names)
    if not force_model.stationary:
        _level(force_model.increment_cov, "force_increment_cov", "force_increment_cov" in names)
    modes = _check_modes(filter_structure, dt, modes) if "frequencies" in names else ()
    problem = _Problem(base, Y, names, modes, residual)
    problem.progress = progress
    if Y.shape[0] < 10 * (len(problem.names) + 1):
        raise AKFInputError(f"a record of {Y.shape[0]} steps is too short to identify {len(problem.names)} parameter(s)")
    bounds = _bounds(problem, force_model, Y.shape[0], stiffness_range, decades)
    u0 = np.zeros(len(problem.names))
    problem.expected = _expected_evaluations(problem.names, start)
    before = float(problem.logliks(u0)[0])
    if not np.isfinite(before):
        raise AKFInputError("the log-likelihood at the starting values is not finite (no steady-state filter): "
                            "check the covariances")
    given = _check_start(start, problem.names, bounds)
    method, reason, bins = _method(method, problem, force_model, Y)
    spectral = [j for j, n in enumerate(problem.names) if method == "whittle" and n.startswith(FORCE_PARAMETERS)]
    rest = [j for j in range(len(problem.names)) if j not in spectral]
    u = np.zeros(len(problem.names))
    errors, robust, bandwidth, warnings, whittle, held_found = {}, {}, 0.0, [], None, {}
    for part in ("whittle", "time"):
        free = spectral if part == "whittle" else rest
        if not free:
            continue
        view = _Whittle(problem, bins, u, free) if part == "whittle" else _Subset(problem, u, free)
        v0 = np.zeros(len(free))
        at_start = before if part == "time" and not spectral else float(view.logliks(v0)[0])
        metric = None if part == "whittle" else _refit_metric(view, information, given, [bounds[j] for j in free])
        v = _maximise(view, v0, [bounds[j] for j in free], at_start, given, metric)
        u[free] = v
        if part == "whittle":
            whittle = (at_start, float(view.logliks(v)[0]))
        e, r, bandwidth, w, H = _curvature(view, v, [bounds[j] for j in free], at_start)
        errors |= e
        robust |= r
        warnings += w
        if part == "time":         # the levels the fit held: do they fit, and what would learning them move?
            rejected = _held_levels(problem, Y, u, free, H, e, r, [bounds[j] for j in free], force_model)
            leaning = _leaning(rejected) if held == "learn" else {}
            learn = list(leaning)
            if learn:                  # fit again with them learnt, from here
                first = {n: float(np.exp(x)) for n, x in zip(problem.names, u)}
                for level in learn:            # its best factor, inside the refit's search range
                    lo, hi = _level_bounds(level, decades)
                    first[level] = float(np.clip(rejected[level]["best_factor"], np.exp(0.999 * lo), np.exp(0.999 * hi)))
                offset, best = problem.evaluations, problem.best
                fit = _calibrate(structure, sensors, forces, measurements, dt, parameters=[*asked, *learn],
                                model_error_cov=model_error_cov, force_increment_cov=None,
                                noise_cov=noise_cov, stiffness_range=stiffness_range, decades=decades,
                                modes=asked_modes, force_model=force_model, dummy=dummy, start=first,
                                progress=None if progress is None else _carried(progress, offset, best),
                                method=asked_method, n_modes=n_modes, held=held,
                                information=([problem.names[j] for j in free], -H))
                fit.notes = [*notes, *_learnt_notes(rejected, leaning),
                             *(n for n in fit.notes if n not in notes)]
                fit.held_levels = {**{lv: {**rejected[lv], "learnt": True} for lv in learn}, **fit.held_levels}
                fit.evaluations += offset
                fit.seconds = time.perf_counter() - start_time
                return fit
            held_found = rejected
            warnings += _held_warnings(rejected)
    after = float(problem.logliks(u)[0])
    errors = {n: errors[n] for n in problem.names}
    robust = {n: robust[n] for n in problem.names}
    multipliers = {n: float(np.exp(x)) for n, x in zip(problem.names, u)}
    values = _values(multipliers, names, noise_cov, model_error_cov, force_model.increment_cov, layout)
    fitted_force = _fitted_force(problem, force_model, multipliers, names, values)
    consistency = [problem.consistency(v) for v in (np.zeros(len(u)), u)]      # two kernel runs
    return CalibrationResult(values, multipliers, errors, before, after, warnings, problem.evaluations,
                             time.perf_counter() - start_time, fitted_force, layout, *consistency, robust, bandwidth,
                             method, reason, whittle, n_kept, notes, held_found)


def _maximise(problem, u0, bounds, before, given, metric=None):
    """The log-factors of ``problem`` (a :class:`_Subset` or a :class:`_Whittle`) that maximise
    its log-likelihood: a grid for what sets a frequency (:func:`_grid_start`) or the ``given``
    starts, then L-BFGS-B with central differences in one batch; never worse than ``u0``.

    On a long record (:data:`HEAD_FROM` steps or more) the grid and the search run on its first
    :data:`HEAD_FRACTION` first, and the whole record's search starts from there: the same
    optimum for a fraction of the filters' length.  Given a ``metric`` (a refit from an earlier
    optimum, :func:`_refit_metric`), the whole record is searched from the ``given`` starts in it."""
    given = {n: v for n, v in given.items() if n in problem.names}
    if metric is not None:
        u = np.array([np.log(given[n]) if n in given else x for n, x in zip(problem.names, u0)])
        return _local_search(problem, u, bounds, before, metric, gtol=ROUGH_GTOL)
    n_steps = problem.problem.Y.shape[0] if isinstance(problem, _Subset) else 0
    if n_steps >= HEAD_FROM:
        with problem.problem.on_head(HEAD_FRACTION):
            head_before = float(problem.logliks(u0[None])[0])
            u_head = _local_search(problem, _start(problem, u0, bounds, head_before, given), bounds, head_before,
                                   gtol=ROUGH_GTOL)
            inside = all(lo + 1e-3 < x < hi - 1e-3 for x, (lo, hi) in zip(u_head, bounds))
            # the head's information, scaled to the record's length: the metric of the record's search
            metric = -_hessian(problem, u_head, CURVATURE_STEP) / HEAD_FRACTION if inside else None
        if float(problem.logliks(u_head[None])[0]) > before:
            return _local_search(problem, u_head, bounds, before, metric, gtol=ROUGH_GTOL)
    return _local_search(problem, _start(problem, u0, bounds, before, given), bounds, before)


def _refit_metric(problem, information, given, bounds):
    """The metric of a refit's search (:func:`_maximise`): the earlier fit's information
    ``(names, -H)`` for its parameters, and for each new one its curvature at the start (two
    filters each), no correlation with the others; None without ``information``, where a
    parameter has no start, or where the metric is not positive definite."""
    if information is None or any(n not in given for n in problem.names):
        return None
    names, info = information
    k = len(problem.names)
    u = np.array([np.log(given[n]) for n in problem.names])
    new = [i for i, n in enumerate(problem.names) if n not in names]
    M = np.zeros((k, k))
    old = [i for i in range(k) if i not in new]
    at = [names.index(problem.names[i]) for i in old]
    M[np.ix_(old, old)] = info[np.ix_(at, at)]
    if new:
        E = np.zeros((len(new), k))
        E[np.arange(len(new)), new] = LOG_STEP
        lo, hi = np.array(bounds).T
        ll = problem.logliks(np.vstack([u, np.clip(u + E, lo, hi), np.clip(u - E, lo, hi)]))
        M[new, new] = -(ll[1:len(new) + 1] + ll[len(new) + 1:] - 2 * ll[0]) / LOG_STEP ** 2
    try:
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        return None
    return M


def _start(problem, u0, bounds, before, given):
    """Where the local search starts: the grid of :func:`_grid_start`, and the ``given`` starts
    where they do better than the job's values."""
    u0 = _grid_start(problem, u0, bounds, before, set(given))
    for j, name in enumerate(problem.names):
        if name in given:
            u0[j] = np.log(given[name])
    if given and not problem.logliks(u0)[0] > before:       # a start no better than the job's values: not taken
        u0 = _grid_start(problem, np.zeros(len(problem.names)), bounds, before)
    return u0


def _local_search(problem, u0, bounds, before, metric=None, gtol=GTOL):
    """L-BFGS-B from ``u0`` with central differences in one batch, in units of each parameter's
    curvature at ``u0`` -- or, given a ``metric`` (k, k) close to the negative Hessian, in the
    coordinates ``w = factor^T (u - u0)`` of its Cholesky factor, where the likelihood is nearly
    round (unbounded there, the log-factors clipped to ``bounds``); it stops where the gradient in
    those units is below ``gtol``.  Zeros where it ends no better than ``before``."""
    from scipy.linalg import solve_triangular
    from scipy.optimize import minimize

    k = len(u0)
    lo, hi = np.transpose(bounds)
    first = _differences(problem, u0)
    try:
        factor = None if metric is None else np.linalg.cholesky(metric)
    except np.linalg.LinAlgError:
        factor = None
    if factor is None:
        # each parameter's curvature at the start (about its standard error): the factors' errors span
        # five decades (a flat mode against the stiffness of every other one), and unscaled L-BFGS-B
        # crawls along the flat ones
        scale = np.sqrt(np.clip(-np.nan_to_num(first[2]) if np.isfinite(first[0]) else 0.0, 1.0, None))
        point, to_w = (lambda w: u0 + w / scale), (lambda g: g / scale)
        w_bounds = [((a - x) * d, (b - x) * d) for a, b, x, d in zip(lo, hi, u0, scale)]
    else:
        point = lambda w: np.clip(u0 + solve_triangular(factor, w, trans="T", lower=True), lo, hi)  # noqa: E731
        to_w, w_bounds = (lambda g: solve_triangular(factor, g, lower=True)), None     # d/dw = factor^-1 d/du

    def negative(w):
        ll, grad, _ = first if not np.any(w) else _differences(problem, point(w))
        if not np.isfinite(ll):
            return np.inf, np.zeros(k)
        return -ll, -to_w(np.nan_to_num(grad))

    fit = minimize(negative, np.zeros(k), jac=True, method="L-BFGS-B", bounds=w_bounds,
                   options={"maxiter": 200, "ftol": 1e-12, "gtol": gtol})
    u = np.clip(point(fit.x), lo, hi)
    if not float(problem.logliks(u[None])[0]) >= before:        # never worse than the start
        return np.zeros(k)
    return u


def _differences(problem, u):
    """The log-likelihood at ``u`` and its central differences, one batch of ``2k + 1`` filters:
    value, gradient and diagonal curvature."""
    k = len(u)
    ll = problem.logliks(np.vstack([u, u + LOG_STEP * np.eye(k), u - LOG_STEP * np.eye(k)]))
    return ll[0], (ll[1:k + 1] - ll[k + 1:]) / (2 * LOG_STEP), (ll[1:k + 1] + ll[k + 1:] - 2 * ll[0]) / LOG_STEP ** 2


class _Subset:
    """The likelihood of :class:`_Problem` over some of its log-factors (``free``), the others
    held at ``u``: what the time-domain fit searches after a Whittle fit of the force prior."""

    transient = True          # the filter's start-up: its first scores are left out of the robust errors

    def __init__(self, problem, u, free):
        self.problem, self.u, self.free = problem, np.array(u, float), list(free)
        self.names = [problem.names[j] for j in self.free]

    def full(self, V):
        """The whole log-factor vectors of the rows of ``V`` (B, len(free))."""
        U = np.tile(self.u, (len(V), 1))
        U[:, self.free] = V
        return U

    def logliks(self, V, per_step=False):
        """The time-domain log-likelihood at every row of ``V``, as :meth:`_Problem.logliks`."""
        return self.problem.logliks(self.full(np.atleast_2d(V)), per_step=per_step)


class _Whittle(_Subset):
    """The Whittle likelihood of the record's signal bins (:mod:`core_akf.whittle`) over the force
    prior's log-factors ``free``; the structure's decomposition is computed once (the force prior
    does not change it).  ``per_step`` gives each bin's term."""

    transient = False

    def __init__(self, problem, bins, u, free):
        super().__init__(problem, u, free)
        self.bins = bins
        A, G, Q, _ = problem.matrices(self.u)
        self.nx, self.m = problem.base.nx, len(problem.layout)
        self.part = structural_part(A, G[:self.m], Q, self.nx)

    def logliks(self, V, per_step=False):
        """The Whittle log-likelihood at every row of ``V``, (B,); per bin (B, K) with ``per_step``."""
        out = []
        for u in self.full(np.atleast_2d(V)):
            A, G, Q, R = self.problem.matrices(u)
            S = output_spectrum(A, G[:self.m], Q, R[:self.m, :self.m], self.nx, self.bins.omega, self.part)
            out.append(whittle_terms(S, self.bins))
        self.problem.evaluations += len(out)
        self.problem.report_progress()
        out = np.array(out)
        return out if per_step else out.sum(axis=1)


def _method(method, problem, force_model, Y):
    """The likelihood that fits the force prior (``"whittle"`` or ``"time"``), why, and the record's
    signal bins (None for ``"time"``): ``method`` as asked, or by the rule of ``"auto"``."""
    if method not in METHODS:
        raise AKFInputError(f"unknown calibration method {method!r}; use one of {list(METHODS)}")
    learnt = [n for n in problem.names if n.startswith(FORCE_PARAMETERS)]
    if method == "time":
        return "time", "the time-domain likelihood, as asked", None
    if not learnt:
        if method == "whittle":
            raise AKFInputError("the Whittle likelihood fits a stationary force model's parameters (force_std, "
                                "force_timescale, force_band); none of them is learnt")
        return "time", "no force-model parameter is learnt: the time-domain likelihood", None
    if method == "auto" and force_model.kind == "butterworth":
        return "time", ("the time-domain likelihood: a Butterworth prior's band puts no power where the loads have "
                        "none, so the empty bins do not pull it"), None
    why = None
    if problem.base.dummy_layout:
        why = "dummy measurements are not a stationary record"
    elif not np.all(np.isfinite(Y)):
        why = "the record has missing samples (the periodogram needs every sample)"
    elif not stationary(problem.base.A_a, problem.base.nx):
        why = "the model has a pole on or outside the unit circle (no stationary spectrum)"
    if why is None:
        bins = signal_bins(Y, np.diag(problem.base.R[0])[:len(problem.layout)])
        if bins.omega.size < 10 * len(learnt):
            why = (f"only {bins.omega.size} frequency bins stand {SIGNAL_RATIO:g}x above the noise floor (at least "
                   f"{10 * len(learnt)} are needed)")
    if why is not None:
        if method == "whittle":
            raise AKFInputError(f"the Whittle likelihood cannot fit this record: {why}")
        return "time", f"the time-domain likelihood: {why}", None
    band = f"{100 * bins.fraction:.0f} % of the record's frequency bins stand {SIGNAL_RATIO:g}x above the noise floor"
    if method == "whittle":
        return "whittle", f"the Whittle likelihood over the signal bins, as asked ({band})", bins
    if bins.fraction <= AUTO_SIGNAL_FRACTION:
        return "whittle", (f"{band}: the time-domain likelihood would fit the force prior to the empty bins, so the "
                           "Whittle likelihood over the signal bins fits it"), bins
    return "time", (f"{band}: the loads fill the band, so the time-domain likelihood fits the force prior"), None


def _reduced(structure, sensors, forces, dt, n_modes, force_model, model_error_cov, parameters, modes):
    """The structure the fit runs on, the dropped modes' noise to add to R (None) and the modes
    kept (None): ``n_modes`` of :func:`calibrate`, never fewer than the modes it calibrates."""
    from .defaults import band_modes
    from .filter.model import FilterModel
    from .sensors import as_layout

    if n_modes is None:
        return structure, None, None
    layout = as_layout(sensors)
    if n_modes == "band":
        k = band_modes(structure, dt, accelerations=any(s.kind == "acc" for s in layout))
    elif isinstance(n_modes, (int, np.integer)) and not isinstance(n_modes, bool) and n_modes >= 1:
        k = int(n_modes)
    else:
        raise AKFInputError(f"n_modes must be a positive integer or \"band\", got {n_modes!r}")
    if "frequencies" in ([parameters] if isinstance(parameters, str) else parameters):
        k = max(k, *_check_modes(structure, dt, modes))
    if k >= structure.n:
        return structure, None, None
    fm = FilterModel(structure, forces, dt, n_modes=k, force_model=force_model)
    return fm.structure, fm.residual_noise(layout, float(np.max(model_error_cov))), k


def _level_bounds(name, decades):
    """The search interval of a covariance level's log-factor: the decades either side of it, and
    for ``model_error_cov`` :data:`MODEL_ERROR_DECADES_BELOW` times as many below (no model error at
    all is a common truth)."""
    width = np.log(10.0) * default("calibration_decades", decades)
    return (-MODEL_ERROR_DECADES_BELOW * width if name == "model_error_cov" else -width), width


def _bounds(problem, force_model, n_steps, stiffness_range, decades):
    """The search interval of every log-factor: the ranges of the model's factors, the decades of
    the covariances (half of them for a std), and for a time scale what the record resolves."""
    ranges = {"stiffness_factor": default("calibration_stiffness_range", stiffness_range),
              "damping": default("calibration_damping_range"),
              "frequencies": default("calibration_frequency_range")}
    width = np.log(10.0) * default("calibration_decades", decades)
    bounds = [tuple(np.log(ranges[n.split(":")[0]])) if n.split(":")[0] in ranges else _level_bounds(n, decades)
              for n in problem.names]
    if not force_model.stationary:
        return bounds
    dt, locs = problem.base.dt, problem.locs
    labels = [f"{n}:{d}" for n, d in locs]
    if force_model.kind == "butterworth":
        band = force_model.parameters(len(locs))[1]
    else:
        ell = np.broadcast_to(np.asarray(force_model.timescale, float), (len(locs),))
    for j, name in enumerate(problem.names):
        if name.startswith("force_std"):       # a factor on a std: its variance spans the decades, as the others'
            bounds[j] = (-width / 2, width / 2)
        elif name.startswith("force_band"):    # the top of the band between ten cycles of the record and Nyquist
            top = band[:, 1] if name == "force_band" else band[[labels.index(name.split(":", 1)[1])], 1]
            bounds[j] = (max(-width, float(np.log(10.0 / (n_steps * dt) / np.min(top)))),
                         min(width, float(np.log(BAND_BELOW_NYQUIST * 0.5 / dt / np.max(top)))))
            if bounds[j][0] >= bounds[j][1]:
                raise AKFInputError(f"force_band {np.asarray(force_model.band).tolist()} Hz is outside what a record "
                                    f"of {n_steps} steps of {dt:g} s can resolve (ten cycles of the record to "
                                    "the Nyquist frequency)")
        elif name.startswith("force_timescale"):   # between one step and a tenth of the record: what it resolves
            own = ell if name == "force_timescale" else ell[labels.index(name.split(":", 1)[1])]
            bounds[j] = (max(-width, float(np.log(dt / np.min(own)))),
                         min(width, float(np.log(0.1 * n_steps * dt / np.max(own)))))
            if bounds[j][0] >= bounds[j][1]:
                raise AKFInputError(f"force_timescale {force_model.timescale!r} s is outside what a record of "
                                    f"{n_steps} steps of {dt:g} s can resolve (one step to a tenth of the record)")
    return bounds


def _check_start(start, names, bounds):
    """The starting factors of :func:`calibrate`, checked: known names, positive, in range."""
    given = dict(start or {})
    for name, value in given.items():
        if name not in names:
            raise AKFInputError(f"start: {name!r} is not a parameter of this fit; they are {names}")
        lo, hi = bounds[names.index(name)]
        if not (isinstance(value, (int, float, np.floating)) and value > 0 and lo <= np.log(value) <= hi):
            raise AKFInputError(f"start: {name} = {value!r} must be a factor inside its search range "
                                f"[{np.exp(lo):.4g}, {np.exp(hi):.4g}]")
    return {n: float(v) for n, v in given.items()}


def _scanned(name):
    """Whether :func:`_grid_start` scans ``name`` on a grid: what sets a frequency or a time scale."""
    return name == "stiffness_factor" or name.startswith(("frequencies:", "force_timescale", "force_band"))


def _expected_evaluations(names, start):
    """About how many filters a fit of ``names`` runs: the start, the grid of :func:`_grid_start`
    (:data:`GRID_POINTS` per scanned name and per refinement), 30 gradient steps of ``2k + 1`` filters and the curvature's
    (:func:`_curvature`, ``k^2 + k + 1``).  Only for the progress bar's ETA."""
    k = len(names)
    scanned = sum(1 for n in names if _scanned(n) and n not in (start or {}))
    return 2 + (GRID_POINTS * (1 + GRID_REFINEMENTS) * scanned + 1 if scanned else 0) + 30 * (2 * k + 1) + k * k + k + 1


def _grid_start(problem, u0, bounds, before, skip=frozenset()):
    """The start of the local search: a grid first for what sets a frequency, whose likelihood may
    have several peaks -- the stiffness factor, or each mode's factor on its own (one batch; the
    modes' peaks barely interact), and a force model's time scale.  Names in ``skip`` have a
    start of their own."""
    scanned = [j for j, n in enumerate(problem.names) if _scanned(n) and n not in skip]
    if not scanned:
        return u0
    grid = [np.linspace(*bounds[j], GRID_POINTS) for j in scanned]
    U = np.tile(u0, (sum(g.size for g in grid), 1))
    for i, (j, g) in enumerate(zip(scanned, grid)):
        U[i * g.size:(i + 1) * g.size, j] = g
    ll = problem.logliks(U).reshape(len(scanned), -1)
    start, best = u0.copy(), np.full(len(scanned), before)
    for i, j in enumerate(scanned):
        if np.max(ll[i]) > before:
            start[j], best[i] = grid[i][int(np.argmax(ll[i]))], np.max(ll[i])
    # a peak narrower than the grid's step (a long record, little noise) lies between two of its
    # points: finer grids either side of each best point, so that the joint search starts on it
    step = np.array([g[1] - g[0] for g in grid])
    for _ in range(GRID_REFINEMENTS):
        fine = [np.clip(start[j] + np.linspace(-1.0, 1.0, GRID_POINTS) * h, *bounds[j]) for j, h in zip(scanned, step)]
        U = np.tile(u0, (GRID_POINTS * len(scanned), 1))
        for i, (j, g) in enumerate(zip(scanned, fine)):
            U[i * GRID_POINTS:(i + 1) * GRID_POINTS, j] = g
        ll = problem.logliks(U).reshape(len(scanned), -1)
        for i, j in enumerate(scanned):
            if np.max(ll[i]) > best[i]:
                start[j], best[i] = fine[i][int(np.argmax(ll[i]))], np.max(ll[i])
        step = step * 2.0 / (GRID_POINTS - 1)
    return start if problem.logliks(start)[0] > before else u0


def _fitted_force(problem, force_model, multipliers, names, values):
    """The fitted Matérn force model (None for the random walk); its std and time scale go into ``values``."""
    if not force_model.stationary:
        return None
    factors = problem.force_factors({n: np.log(v) for n, v in multipliers.items()})
    # one factor for all forces keeps a single std or time scale single
    per_force = ("force_std:forces" in names,
                 "force_timescale:forces" in names or "force_band:forces" in names)
    factors = [f if each else float(f[0]) for each, f in zip(per_force, factors)]
    fitted = force_model.scaled(*factors)
    for name, value in (("force_std", fitted.std), ("force_timescale", fitted.timescale), ("force_band", fitted.band)):
        if name in names or f"{name}:forces" in names:
            value = np.asarray(value, float)
            values[name] = float(value) if value.ndim == 0 else value.tolist()
    return fitted


def calibration_modes(structure: Structure, dt: float) -> list[int]:
    """The modes whose frequencies ``frequencies`` calibrates by default.

    The lowest ``calibration_modes`` (:data:`core_akf.defaults.DEFAULTS`) modes below a quarter
    of the sampling rate (half the Nyquist frequency): the modes a record resolves well.  A mode
    the sensors or the loads do not see is named in a warning of the fit (a flat likelihood).

    Parameters
    ----------
    structure : Structure
        The starting model.
    dt : float
        Time step (s).

    Returns
    -------
    list of int
        1-based mode numbers.

    Examples
    --------
    >>> from core_akf.models import s17_truss
    >>> calibration_modes(s17_truss(), 1 / 4096)
    [1, 2, 3, 4]
    """
    f = structure.frequencies()
    below = np.flatnonzero(f < 0.25 / float(dt))
    if not below.size:
        raise AKFInputError(f"no mode lies below a quarter of the sampling rate ({0.25 / dt:.4g} Hz): the record cannot "
                            "resolve a frequency; sample faster")
    return [int(k) + 1 for k in below[:default("calibration_modes")]]


def _check_parameters(parameters, layout):
    """The parameter names, checked: known, each once, noise of kinds the layout has, and no two
    that overlap (the stiffness factor is every frequency at once)."""
    from .sensors import KINDS

    names = list(parameters) if not isinstance(parameters, str) else [parameters]
    if not names:
        raise AKFInputError(f"parameters: name at least one of {list(PARAMETERS)}")
    kinds = {s.kind for s in layout}
    for name in names:
        base, _, detail = str(name).partition(":")
        per_force = base in FORCE_PARAMETERS and detail == "forces"
        if base not in PARAMETERS or (detail and base != "noise_cov" and not per_force):
            raise AKFInputError(f"cannot calibrate {name!r}; the parameters are {list(PARAMETERS)}, and noise_cov:<kind> "
                                "or noise_cov:channels, force_std:forces, force_timescale:forces or force_band:forces "
                                "(one factor per force)")
        if detail and not per_force and detail != "channels" and detail not in kinds:
            what = "is not a sensor kind" if detail not in KINDS else "has no channel in this layout"
            raise AKFInputError(f"cannot calibrate {name!r}: {detail!r} {what}; the layout's kinds are "
                                f"{sorted(kinds)} (noise_cov:channels learns one factor per channel)")
    if len(set(names)) != len(names):
        raise AKFInputError(f"parameters name {sorted({n for n in names if names.count(n) > 1})} twice")
    noise = [n for n in names if n.startswith("noise_cov")]
    if len(noise) > 1 and ("noise_cov" in noise or "noise_cov:channels" in noise):
        raise AKFInputError(f"parameters {noise} overlap: noise_cov learns every kind, noise_cov:channels every channel; "
                            "give one of them, or kinds one by one")
    if "stiffness_factor" in names and "frequencies" in names:
        raise AKFInputError("stiffness_factor and frequencies overlap (frequencies fits a common factor on every "
                            "mode it does not list, which is a stiffness factor): calibrate one of them")
    for base in FORCE_PARAMETERS:
        if base in names and f"{base}:forces" in names:
            raise AKFInputError(f"{base} and {base}:forces overlap ({base} is one factor for every force): give one")
    return names


def _check_modes(structure, dt, modes):
    """The 1-based modes of ``frequencies``, checked (default :func:`calibration_modes`)."""
    if modes is None:
        return calibration_modes(structure, dt)
    out = [int(k) for k in np.atleast_1d(modes)]
    if not out or len(set(out)) != len(out) or any(k != m for k, m in zip(out, np.atleast_1d(modes))) \
            or not all(1 <= k <= structure.n for k in out):
        raise AKFInputError(f"modes must be distinct mode numbers between 1 and {structure.n}, got {modes!r}")
    f = structure.frequencies()
    above = [k for k in out if f[k - 1] >= 0.5 / float(dt)]
    if above:
        raise AKFInputError(f"modes {above} lie at or above the record's Nyquist frequency ({0.5 / dt:.4g} Hz; mode "
                            f"{above[0]} at {f[above[0] - 1]:.4g} Hz): a record sampled every {dt:.4g} s cannot see "
                            "them, so their frequencies cannot be learnt; leave them out or sample faster")
    return sorted(out)


def _modal_ratio(damping):
    """Whether a damping spec is a modal ratio (one, or one per mode) above zero."""
    if damping is None or isinstance(damping, (tuple, list)) and damping and isinstance(damping[0], str):
        return False
    ratio = np.asarray(damping, float)
    return bool(ratio.size and np.all(np.isfinite(ratio)) and np.all(ratio > 0))


def _level(value, name, scaled):
    """A covariance as given, checked that it can be scaled (not zero) when it is learnt."""
    if scaled and np.all(np.asarray(value, float) == 0):
        raise AKFInputError(f"{name} starts at 0: a level of zero cannot be scaled; give a small positive level "
                            "to start from")
    return value


def _hessian(problem, u, h, per_step=False):
    """The Hessian of the log-likelihood at ``u`` by central differences of step ``h``: one batch
    of ``k^2 + k + 1`` filters, ``u``, ``u +- h e_i`` and ``u +- h (e_i + e_j)``.

    The diagonal is the usual second difference; an off-diagonal entry is
    ``(f(++) + f(--) - f(+i) - f(-i) - f(+j) - f(-j) + 2 f) / (2 h^2)``, second-order accurate as
    the four-point formula, whose ``u +- h e_i +- h e_j`` need twice the filters.

    Returns
    -------
    H : ndarray (k, k)
    terms : ndarray (2k, N), only with ``per_step``
        The per-step log-likelihood terms at ``u + h e_i`` (rows ``0..k-1``) and ``u - h e_i``:
        the robust errors' scores (:func:`_robust`) from the same filters.
    """
    k = len(u)
    E = np.eye(k) * h
    pairs = [(i, j) for i in range(k) for j in range(i + 1, k)]
    points = np.vstack([u[None], u + E, u - E] + [np.array([s * (E[i] + E[j]) for i, j in pairs]).reshape(-1, k) + u
                                                  for s in (1, -1)])
    terms = problem.logliks(points, per_step=per_step)
    ll = terms.sum(axis=1) if per_step else terms
    up, down = ll[1:k + 1], ll[k + 1:2 * k + 1]
    both = ll[2 * k + 1:].reshape(2, len(pairs))
    H = np.diag((up - 2 * ll[0] + down) / h ** 2)
    for p, (i, j) in enumerate(pairs):
        H[i, j] = H[j, i] = (both[0, p] + both[1, p] - up[i] - down[i] - up[j] - down[j] + 2 * ll[0]) / (2 * h * h)
    return (H, terms[1:2 * k + 1]) if per_step else H


def _curvature(problem, u, bounds, before):
    """Standard errors of the log-factors from the observed information and robust ones (the
    sandwich of the per-step scores), and warnings for a fit on a bound, a parameter the
    likelihood does not see, or robust errors far from the others (a model that does not fit).

    Returns
    -------
    errors, robust : dict
        By parameter name.
    bandwidth : float
        The scores' HAC bandwidth (steps).
    warnings : list of str
    H : ndarray (k, k)
        The Hessian of the log-likelihood in the log-factors.
    """
    k = len(u)
    h = CURVATURE_STEP
    H, terms = _hessian(problem, u, h, per_step=True)
    warnings = []
    try:
        cov = np.linalg.inv(-H)
        std = np.sqrt(np.where(np.diag(cov) > 0, np.diag(cov), np.nan))
    except np.linalg.LinAlgError:
        std = np.full(k, np.nan)
    robust, bandwidth = _robust(problem, terms, h, H)
    errors, named = {}, set()                   # named: a warning already says its errors mean little
    for i, name in enumerate(problem.names):
        lo, hi = bounds[i]
        errors[name] = float(std[i])
        named.add(name)
        if np.isclose(u[i], lo, atol=1e-3) or np.isclose(u[i], hi, atol=1e-3):
            side = "lower" if np.isclose(u[i], lo, atol=1e-3) else "upper"
            ends = problem.logliks(np.array([np.where(np.arange(k) == i, b, u) for b in (lo, hi)]))
            if np.nanmax(np.abs(ends - ends.max())) < FLAT:
                warnings.append(f"{name}: the likelihood is flat over its search range; the record cannot identify "
                                "it (keep its starting value, or add sensors that see it)")
            else:
                warnings.append(f"{name} was fitted at its {side} search bound (factor {np.exp(u[i]):.3g}): the "
                                "optimum may lie beyond it; widen the range or start closer")
        elif not np.isfinite(std[i]) or H[i, i] > -FLAT or std[i] > POORLY_IDENTIFIED:
            warnings.append(f"{name}: the likelihood barely changes with it near the optimum; the record does not "
                            "identify it well (its fitted value is uncertain)")
        else:
            named.discard(name)
    ratio = information_ratio(std, robust)
    off = [(n, r) for n, r in zip(problem.names, ratio)
           if n not in named and np.isfinite(r) and not 1 / MISFIT_RATIO <= r <= MISFIT_RATIO]
    if off:
        warnings.append("the model does not fit the record as its likelihood assumes: the robust standard errors are "
                        + ", ".join(f"{r:.2g}x ({n})" for n, r in off) + " the observed-information ones; use the robust "
                        "ones. Possible causes: a force prior whose spectrum is not the loads' (force_model), a model "
                        "error the filter does not allow for (model_error_cov), non-Gaussian noise (outliers, spikes)")
    return errors, dict(zip(problem.names, map(float, robust))), bandwidth, warnings, H


def _held_levels(problem, Y, u, free, H, observed, robust, bounds, force_model):
    """Whether each covariance level the fit held (Q, S, a sensor kind's R) fits the record, and
    what learning it as well would do to the fitted parameters.

    For each held level: the record's log-likelihood over its factor (:data:`HELD_GRID`, the
    fitted parameters held).  Where the best factor raises it by more than :data:`HELD_LOGLIK` (a
    likelihood-ratio test at 0.1 %), one Newton step of the fitted parameters ``free`` from there,
    ``-H'^-1 g``: ``g`` the gradient there and ``H'`` the fit's Hessian ``H`` with each diagonal
    taken there (the correlations kept), ``2 len(free)`` filters.  That is the change learning the
    level would make (the *expected parameter change* of a score test; the S17 fits: -2.8
    robust errors predicted for the stiffness factor, -2.81 found by the fit that learns Q).
    Parameters on a search bound, without a robust error or poorly identified (a flat likelihood,
    a standard error above :data:`POORLY_IDENTIFIED`) are held in the step.

    Returns
    -------
    dict
        By held level that does not fit: ``loglik_gain``, ``best_factor`` and ``moves`` (each
        fitted parameter's change in robust standard errors).
    """
    names = [problem.names[j] for j in free]
    held = [] if "model_error_cov" in problem.names or not np.any(problem.base.model_error_cov) else ["model_error_cov"]
    if not force_model.stationary and "force_increment_cov" not in problem.names:
        held.append("force_increment_cov")
    learnt = {n.split(":", 1)[1] for n in problem.names if n.startswith("noise_cov:")}
    held += [f"noise_cov:{k}" for k in problem.kinds
             if k not in learnt and not learnt & {s.label for s in problem.layout if s.kind == k}]
    errors = np.array([robust[n] for n in names])
    step = [i for i, j in enumerate(free) if np.isfinite(errors[i]) and H[i, i] < -FLAT
            and np.isfinite(observed[names[i]]) and observed[names[i]] <= POORLY_IDENTIFIED
            and bounds[i][0] + 1e-3 < u[j] < bounds[i][1] - 1e-3]
    out = {}
    grid = np.log(10.0) * np.asarray(HELD_GRID, float)
    for level in held if step else ():
        wider = _Problem(problem.base, Y, [*problem.names, level], problem.modes, problem.residual)
        wider._filters = problem._filters                 # the model's filters are the same
        U = np.tile(np.append(u, 0.0), (len(grid), 1))
        U[:, -1] = grid
        ll = np.nan_to_num(wider.logliks(U), nan=-np.inf)
        best = int(np.argmax(ll))
        gain = float(ll[best] - ll[int(np.argmin(np.abs(grid)))])
        if gain > HELD_LOGLIK:
            E = np.zeros((len(step), len(U[0])))
            E[np.arange(len(step)), [free[i] for i in step]] = LOG_STEP
            ends = wider.logliks(np.vstack([U[best] + E, U[best] - E]))
            up, down = ends[:len(step)], ends[len(step):]
            g = (up - down) / (2 * LOG_STEP)
            sub = H[np.ix_(step, step)]
            d = np.sqrt(np.clip((up + down - 2 * ll[best]) / LOG_STEP ** 2 / np.diag(sub), 1e-6, None))
            try:
                move = -np.linalg.solve(sub * np.outer(d, d), g) / errors[step]
            except np.linalg.LinAlgError:
                move = np.full(len(step), np.nan)
            out[level] = {"loglik_gain": gain, "best_factor": float(np.exp(grid[best])),
                          "moves": {names[i]: float(z) for i, z in zip(step, move)}}
        problem.evaluations += wider.evaluations
        problem.report_progress()
    return out


def _leaning(held):
    """By held level of :func:`_held_levels`, the fitted parameters it would move by more than
    :data:`HELD_MOVE` robust standard errors, ``[(name, move), ...]`` (the levels that move none
    left out)."""
    out = {}
    for level, found in held.items():
        moved = [(n, z) for n, z in found["moves"].items() if np.isfinite(z) and abs(z) > HELD_MOVE]
        if moved:
            out[level] = moved
    return out


def _carried(progress, offset, best):
    """A refit's progress callback: its filters counted after the ``offset`` of the first fit."""
    return lambda e, x, b: progress(e + offset, x + offset, max(b, best))


def _learnt_notes(held, leaning):
    """The note of each level of ``leaning`` (:func:`_leaning` of ``held``) that :func:`calibrate`
    learnt as well (``held="learn"``)."""
    return [f"{level} was learnt as well: the record rejects the job's value (the log-likelihood rises by "
            f"{held[level]['loglik_gain']:.3g} at {held[level]['best_factor']:.2g}x it), and holding it would have "
            "moved " + ", ".join(f"{n} by {z:+.1f}" for n, z in moved) + " robust standard errors "
            "(calibrate_held = \"learn\")" for level, moved in leaning.items()]


def _held_warnings(held):
    """The warning of each held level of :func:`_held_levels` that moves a fitted parameter by more
    than :data:`HELD_MOVE` robust standard errors."""
    warnings = []
    for level, moved in _leaning(held).items():
        found = held[level]
        warnings.append(f"{level} was held at the job's value, and the record favours another (the log-likelihood "
                        f"rises by {found['loglik_gain']:.3g} at {found['best_factor']:.2g}x it): learning it as "
                        "well would move " + ", ".join(f"{n} by {z:+.1f}" for n, z in moved)
                        + f" robust standard errors; add \"{level}\" to calibrate")
    return warnings


def _robust(problem, terms, h, H):
    """Robust standard errors of the log-factors: the sandwich of the observed information ``-H``
    and the per-step scores (central differences of step ``h`` of each step's log-likelihood
    term, ``terms`` (2k, N) at ``u +- h e_i`` from :func:`_hessian`), and the HAC bandwidth used.
    NaN where ``-H`` is not positive definite.

    The scores of the start-up transient (the first 5 %, as the consistency) are left out: the
    steady filter starts from a zero mean with its converged covariance, so its first innovations
    are far larger than predicted even when the model is right.  ``J`` of the rest is scaled to
    the whole record.  A Whittle likelihood's terms are its frequency bins: none is left out."""
    from .filter.results import skipped
    from .inference import hac_bandwidth

    k = len(H)
    n_steps = terms.shape[1]
    scores = ((terms[:k] - terms[k:]) / (2 * h)).T[skipped(n_steps) if problem.transient else 0:]   # (N', k)
    nan = np.full(k, np.nan)
    if not np.all(np.isfinite(scores)):
        return nan, 0.0
    try:
        np.linalg.cholesky(-H)
    except np.linalg.LinAlgError:
        return nan, 0.0
    bandwidth = hac_bandwidth(scores)
    V = sandwich_covariance(-H, scores * np.sqrt(n_steps / scores.shape[0]), bandwidth)
    return np.sqrt(np.where(np.diag(V) > 0, np.diag(V), np.nan)), bandwidth


def _values(multipliers, names, noise_cov, model_error_cov, force_increment_cov, layout):
    """The fitted values under the parameters' own names (see :class:`CalibrationResult`)."""
    out = {}
    if "stiffness_factor" in names:
        out["stiffness_factor"] = multipliers["stiffness_factor"]
    if "frequencies" in names:
        out["frequency_factors"] = frequency_factors(multipliers).tolist()
        if REST_FREQUENCIES in multipliers:
            out["rest_frequency_factor"] = multipliers[REST_FREQUENCIES]
    if "damping" in names:
        out["damping_factor"] = multipliers["damping"]
    if any(n.startswith("noise_cov") for n in names):
        if isinstance(noise_cov, dict) and "noise_cov:channels" not in names:
            out["noise_cov"] = {k: float(v) * multipliers.get(f"noise_cov:{k}", 1.0) for k, v in noise_cov.items()}
        else:
            out["noise_cov"] = (np.diag(noise_covariance(layout, noise_cov)) * noise_scale(layout, multipliers) ** 2).tolist()
    for name, level in (("force_increment_cov", force_increment_cov), ("model_error_cov", model_error_cov)):
        if name in names:
            value = np.asarray(level, float) * multipliers[name]
            out[name] = float(value) if value.ndim == 0 else value.tolist()
    return out
