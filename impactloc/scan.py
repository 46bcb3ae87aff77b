"""Location scan (IMP §3): for every candidate impact location and every SE/AD role split, run
the AKF with an assumed force at that location on the SE sensors and compare its prediction of
the AD sensors with their measurements.  The impact location is the one with the lowest mean
AD error over the splits (the spread breaks ties).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from core_akf.checks import AKFInputError, FloatArray, ForceLocation, Layout, Measurements, as_measurements, as_n_jobs, is_real, shortened
from core_akf.defaults import default, resolve_modes
from core_akf.filter import FilterModel
from core_akf.filter.kernels import steady_outputs
from core_akf.forcemodels import ForceModel
from core_akf.metrics import rms, rms_error
from core_akf.sensors import as_layout, parse_force_locations, sees_accelerations
from core_akf.statespace import SubsetDetectability

from .roles import RoleSplit

if TYPE_CHECKING:
    from core_akf.structure import Structure

#: budget of (filters x steps x states) per kernel call: bounds memory (~16 bytes each)
_CALL_BUDGET = 6_000_000


@dataclass(frozen=True)
class Covariances:
    """Assumed AKF covariance levels.

    Attributes
    ----------
    model_error : float -- ``Q``, variance per step per physical DOF (m^2 and (m/s)^2)
    force_increment : float -- ``S``, variance of the force increment per step (N^2); under a
        Matérn force model (:class:`ImpactModel` ``force_model``) the variance of the force
        itself, ``std^2`` (N^2)
    noise : dict -- ``R``, measurement-noise variance per sensor kind (SI^2), e.g.
        ``{"strain": 1e-12, "acc": 1e-4}``

    Examples
    --------
    >>> c = Covariances(model_error=1e-16, force_increment=1e6, noise={"strain": 1e-12, "acc": 1e-4})
    >>> c.as_dict()["noise_acc"]
    0.0001
    """

    model_error: float
    force_increment: float
    noise: dict

    def __post_init__(self):
        for name in ("model_error", "force_increment"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise AKFInputError(f"{name} must be a finite variance >= 0, got {v!r}")
        if self.force_increment <= 0:
            raise AKFInputError("force_increment (S) must be > 0: the force must be free to change")
        for kind, v in self.noise.items():
            if not (np.isfinite(v) and v > 0):
                raise AKFInputError(f"noise variance for {kind!r} must be finite and > 0, got {v!r}")

    def as_dict(self) -> dict[str, float]:
        """The levels as a flat dict for tables and JSON.

        Returns
        -------
        dict
            ``model_error``, ``force_increment`` and ``noise_KIND`` per sensor kind.
        """
        return {"model_error": self.model_error, "force_increment": self.force_increment,
                **{f"noise_{k}": v for k, v in self.noise.items()}}

    def force_model(self, base: ForceModel | None = None) -> ForceModel:
        """The force model of these levels.

        Parameters
        ----------
        base : ForceModel, optional
            A Matérn model whose kind and time scale to keep (its std becomes
            ``sqrt(force_increment)``); None or a random walk: the random walk of ``force_increment``.

        Returns
        -------
        ForceModel
        """
        if base is None or not base.stationary:
            return ForceModel("random_walk", increment_cov=self.force_increment, hold="zero" if base is None else base.hold)
        return base.with_std(float(np.sqrt(self.force_increment)))


def default_covariances(sensors: Layout, measurements: Measurements, model_error: float = default("model_error_cov"),
                        force_increment: float = default("impact_force_increment_cov"),
                        relative_noise: float = default("impact_relative_noise")) -> Covariances:
    """Assumed levels before tuning.

    ``Q`` and ``S`` as given, ``R`` per sensor kind from the data,
    ``(relative_noise x median RMS of that kind's channels)^2``.

    Parameters
    ----------
    sensors : sequence of sensor specs
        The installed layout.
    measurements : array_like (N, m)
        The record (SI).
    model_error : float
        ``Q`` level (m^2 and (m/s)^2 per step).
    force_increment : float
        ``S`` (N^2 per step).
    relative_noise : float
        Assumed noise as a share of the channels' RMS.

    Returns
    -------
    Covariances

    Examples
    --------
    >>> import numpy as np
    >>> Y = np.column_stack([np.full(10, 2e-6), np.full(10, 0.5)])
    >>> c = default_covariances(["strain:5", "acc:8:y"], Y, relative_noise=0.1)
    >>> round(c.noise["strain"] / (0.1 * 2e-6) ** 2, 6), round(c.noise["acc"] / (0.1 * 0.5) ** 2, 6)
    (1.0, 1.0)
    """
    layout = as_layout(sensors)
    Y = np.asarray(measurements, float)
    noise = {}
    for kind in dict.fromkeys(s.kind for s in layout):
        cols = [i for i, s in enumerate(layout) if s.kind == kind]
        level = float(np.median(np.sqrt(np.nanmean(Y[:, cols] ** 2, axis=0))))     # over the observed samples
        noise[kind] = (relative_noise * level) ** 2 if level > 0 else 1.0
    return Covariances(model_error, force_increment, noise)


def candidate_locations(structure: Structure, direction: str, nodes: Sequence[int] | None = None) -> list[ForceLocation]:
    """Candidate impact locations.

    Parameters
    ----------
    structure : Structure
    direction : str
        The force direction ("y", "w").
    nodes : sequence of int, optional
        Node ids (1-based), each checked (default every free node in ``direction``).

    Returns
    -------
    list of (int, str)

    Examples
    --------
    >>> from core_akf.models import s17_truss
    >>> locs = candidate_locations(s17_truss(), "y")
    >>> len(locs), locs[:2]                     # every joint free in y (not the supports 1 and 18)
    (16, [(2, 'y'), (3, 'y')])
    """
    if nodes is None:
        nodes = [int(n) for n in structure.user_node_ids if _free(structure, int(n), direction)]
        if not nodes:
            raise AKFInputError(f"no free node moves in direction {direction!r}")
    bad = [n for n in nodes if not (is_real(n) and np.isfinite(n) and n == int(n))]
    if bad:
        raise AKFInputError(f"candidate node(s) {shortened(repr(bad[:5]))} are not node numbers (whole numbers, 1-based)")
    return parse_force_locations(structure, [(int(n), direction) for n in nodes])


def _free(structure, node, direction):
    try:
        structure.dof_index(node, direction)
        return True
    except (AKFInputError, ValueError, KeyError):
        return False


class ImpactModel:
    """The filter model prepared once for a scan.

    One :class:`core_akf.filter.model.FilterModel` per candidate location (cached), all sharing
    the structure's modes.  Picklable.

    Parameters
    ----------
    structure : Structure
        The filter's model.
    sensors : sequence of sensor specs
        The installed layout.
    dt : float
        Time step (s).
    n_modes : int, "auto" or None
        None keeps the full model; ``"auto"`` keeps the modes below 10x the sampling rate with a
        static correction for the rest.  On the IMP plate that drops the 60 shear/rotation modes
        above 28 kHz and keeps the 30 bending modes (n_a 181 -> 61, the scan 5x faster; the true
        location fits as well as with the full model, the wrong ones score differently but stay
        far worse).  A cut at the sampling rate itself is too deep: a 4 ms impact excites modes up
        to a few kHz and the identification fails.
    force_model : ForceModel, optional
        The impact's prior: None, the random walk (the paper's); a Matérn model (its kind and time
        scale; the std is ``sqrt(Covariances.force_increment)``).
    """

    def __init__(self, structure: Structure, sensors: Layout, dt: float, n_modes: int | str | None = None,
                 force_model: ForceModel | None = None):
        if force_model is not None and not isinstance(force_model, ForceModel):
            raise AKFInputError(f"force_model must be a core_akf.forcemodels.ForceModel (or None: the random walk), got "
                                f"{type(force_model).__name__}")
        self.full = structure
        self.force_model = force_model if force_model is not None and force_model.stationary else None
        self.hold = "zero" if force_model is None else force_model.hold
        self.layout = as_layout(sensors)
        self.dt = float(dt)
        self.n_modes = resolve_modes(n_modes, structure, dt, sees_accelerations(self.layout))
        self.kinds = np.array([s.kind for s in self.layout])
        self._systems = {}
        self._detectability = {}

    def filter_model(self, loc: ForceLocation) -> tuple[FilterModel, FloatArray]:
        """The filter model of a force location, built once.

        Parameters
        ----------
        loc : (int, str)
            The force location.

        Returns
        -------
        fm : FilterModel
        G_a : ndarray (m, n_a)
            The observation rows of all installed sensors.
        """
        if loc not in self._systems:        # a Matérn model with unit std: Q_f scales with std^2
            unit = self.force_model.with_std(1.0) if self.force_model is not None else None if self.hold == "zero" \
                else ForceModel("random_walk", increment_cov=0.0, hold=self.hold)   # S comes with each Q_a call
            fm = FilterModel(self.full, [loc], self.dt, self.n_modes, force_model=unit)
            self._systems[loc] = (fm, fm.observation(self.layout))
        return self._systems[loc]

    def system(self, loc: ForceLocation) -> tuple[FloatArray, FloatArray]:
        """The augmented system for a force at a location.

        Parameters
        ----------
        loc : (int, str)
            The force location.

        Returns
        -------
        A_a : ndarray (n_a, n_a)
            Augmented modal transition.
        G_a : ndarray (m, n_a)
            Observation rows of *all* installed sensors.
        """
        fm, G_a = self.filter_model(loc)
        return fm.A_a, G_a

    def detectable(self, loc: ForceLocation, se: Sequence[int]) -> bool:
        """PBH detectability of a force at a location from some of the sensors.

        Parameters
        ----------
        loc : (int, str)
            The force location.
        se : sequence of int
            Indices of the SE sensors (0-based, into the installed layout).

        Returns
        -------
        bool
        """
        if loc not in self._detectability:
            self._detectability[loc] = SubsetDetectability(self.full, self.layout, [loc], self.force_model)
        return self._detectability[loc].detectable(se)

    def Q_a(self, cov: Covariances, loc: ForceLocation) -> FloatArray:
        """The augmented process covariance of a force location.

        Parameters
        ----------
        cov : Covariances
        loc : (int, str)

        Returns
        -------
        ndarray (n_a, n_a)
        """
        fm = self.filter_model(loc)[0]
        if self.force_model is None:
            return fm.Q_a(cov.model_error, cov.force_increment)
        Q = fm.Q_a(cov.model_error)
        Q[fm.n_states:, fm.n_states:] *= cov.force_increment         # the unit-std Q_f times std^2
        return Q

    def noise(self, cov: Covariances) -> FloatArray:
        """The measurement-noise variance of every installed sensor.

        Parameters
        ----------
        cov : Covariances

        Returns
        -------
        ndarray (m,)

        Raises
        ------
        AKFInputError
            For a sensor kind without a noise variance.
        """
        missing = sorted(set(self.kinds) - set(cov.noise))
        if missing:
            raise AKFInputError(f"covariances have no noise variance for sensor kind(s) {missing}")
        return np.array([cov.noise[k] for k in self.kinds])


def check_skip(skip, dt, n_steps):
    """The samples a ``skip`` of seconds leaves out, checked: a time >= 0 that leaves samples.

    Parameters
    ----------
    skip : float
        Seconds at the record's start left out of the AD error.
    dt : float
        Time step (s).
    n_steps : int
        Samples of the record.

    Returns
    -------
    int
    """
    if not (is_real(skip) and np.isfinite(skip) and skip >= 0):
        raise AKFInputError(f"skip must be a time >= 0 (s), got {shortened(repr(skip))}")
    skip_n = int(round(skip / dt))
    if skip_n >= n_steps - 1:
        raise AKFInputError(f"skip = {skip} s leaves no samples of the {n_steps * dt:.3g} s record")
    return skip_n


def rms_errors(pred, Y_ad, skip=0):
    """RMS error per filter and AD channel over samples ``skip..N-1``.

    Parameters
    ----------
    pred : ndarray (B, N, a)
        Predicted AD channels.
    Y_ad : ndarray (B, N, a)
        Measured AD channels (NaN where missing: left out).
    skip : int
        Samples left out at the start.

    Returns
    -------
    abs_err : ndarray (B, a)
        In the channels' units.
    rel_err : ndarray (B, a)
        Relative to the RMS of the measured channel.
    """
    pred, Y_ad = pred[:, skip:], Y_ad[:, skip:]
    if np.isnan(Y_ad).any():                       # over the observed samples of each channel
        err = np.sqrt(np.nanmean((pred - Y_ad) ** 2, axis=1))
        return err, err / np.maximum(np.sqrt(np.nanmean(Y_ad ** 2, axis=1)), np.finfo(float).tiny)
    err = rms_error(pred, Y_ad, axis=1)
    return err, err / np.maximum(rms(Y_ad, axis=1), np.finfo(float).tiny)


def location_errors(model, loc, splits, Y, covs, skip=0):
    """AD errors of every (covariance set, split) at one location.

    Parameters
    ----------
    model : ImpactModel
    loc : (int, str)
        The force location.
    splits : list of RoleSplit
    Y : ndarray (N, m)
        The record (SI).
    covs : list of Covariances
    skip : int
        Samples left out at the start.

    Returns
    -------
    abs_err, rel_err : ndarray (n_covs, n_splits, n_ad)
        NaN for undetectable splits.
    """
    covs = list(covs)
    A_a, G_all = model.system(loc)
    n = A_a.shape[0]
    N = Y.shape[0]
    n_ad = len(splits[0].ad)
    abs_err = np.full((len(covs), len(splits), n_ad), np.nan)
    rel_err = np.full_like(abs_err, np.nan)
    ok = [j for j, s in enumerate(splits) if model.detectable(loc, s.se)]
    jobs = [(c, j) for c in range(len(covs)) for j in ok]
    per_call = max(1, _CALL_BUDGET // (N * n))
    noise = [model.noise(c) for c in covs]
    Qs = [model.Q_a(c, loc) for c in covs]
    for start in range(0, len(jobs), per_call):
        chunk = jobs[start:start + per_call]
        se = np.array([splits[j].se for _, j in chunk])
        ad = np.array([splits[j].ad for _, j in chunk])
        G = G_all[se]                                        # (b, m_se, n)
        H = G_all[ad]
        R = np.stack([np.diag(noise[c][list(splits[j].se)]) for c, j in chunk])
        Q = np.stack([Qs[c] for c, _ in chunk])
        Yse = np.ascontiguousarray(np.swapaxes(Y[:, se], 0, 1))   # (b, N, m_se)
        Yad = np.swapaxes(Y[:, ad], 0, 1)
        pred = steady_outputs(A_a, G, Q, R, Yse, H)
        e_abs, e_rel = rms_errors(pred, Yad, skip)
        for k, (c, j) in enumerate(chunk):
            abs_err[c, j], rel_err[c, j] = e_abs[k], e_rel[k]
    return abs_err, rel_err


def _scan_task(locs, model, splits, Y, cov, skip):
    return [location_errors(model, loc, splits, Y, [cov], skip) for loc in locs]


@dataclass
class ScanResult:
    """Outcome of :func:`scan`.

    Attributes
    ----------
    frame : pandas.DataFrame
        One row per (location, split): ``node``, ``direction``, ``split``, ``ad_sensors``,
        ``error`` (mean relative RMS error at the AD sensors), ``detectable`` and the mean
        absolute error per AD sensor kind (``error_strain`` in m/m, ``error_acc`` in m/s^2).
    summary : pandas.DataFrame
        One row per location, best first: ``mean``, ``std``, ``n_splits``, ``votes`` (share of
        splits whose own best location it is), ``rank``.
    identified : (int, str)
        The location of the lowest mean (spread as tie-breaker).
    confidence : float
        Share of the splits that pick the identified location on their own, scaled down when even
        the best location explains the AD data poorly (mean relative AD error above 0.5, down to
        0 at 1: no better than predicting zero), and 0 with a single candidate (nothing to compare).
    margin : float
        (runner-up mean - best mean) / pooled std of the two: separation in units of the spread;
        small (< ~1) means two locations are hard to tell apart.
    errors : ndarray (n_locations, n_splits)
        Relative AD errors.
    locations : list of (int, str)
    splits : list of RoleSplit
    covariances : Covariances
        The levels of the scan.
    warnings : list of str
        Why the confidence is low, in plain language.
    """

    frame: object
    summary: object
    identified: tuple
    confidence: float
    margin: float
    errors: np.ndarray = field(repr=False, default=None)   # (n_locations, n_splits) relative errors
    locations: list = field(default_factory=list)
    splits: list = field(default_factory=list)
    covariances: Covariances = None
    warnings: list = field(default_factory=list)

    def ranking(self) -> list[dict]:
        """The locations, best first.

        Returns
        -------
        list of dict
            ``{"node", "direction", "mean", "std"}`` per location.
        """
        return [{"node": int(r.node), "direction": r.direction, "mean": float(r.mean), "std": float(r.std)}
                for r in self.summary.itertuples()]


def _chunks(items, n):
    k = math.ceil(len(items) / max(n, 1))
    return [items[i:i + k] for i in range(0, len(items), k)]


def check_measurements(layout, Y):
    """A record checked for a layout.

    Parameters
    ----------
    layout : sequence of Sensor
        The installed layout, m sensors.
    Y : array_like (N, m)

    Returns
    -------
    ndarray (N, m)

    Raises
    ------
    AKFInputError
        For text or infinite values (NaN is a missing sample), another number of columns, or fewer
        than 10 samples.
    """
    Y = as_measurements(Y, "measurements", ndim=2)
    if Y.shape[1] != len(layout):
        raise AKFInputError(f"measurements have {Y.shape[1]} columns for {len(layout)} installed sensors")
    if Y.shape[0] < 10:
        raise AKFInputError(f"only {Y.shape[0]} samples: too short a record to locate anything")
    return Y


def scan(structure: Structure, sensors: Layout, measurements: Measurements, dt: float, splits: Sequence[RoleSplit], *,
         candidates: Sequence[ForceLocation], covariances: Covariances, skip: float = 0.0,
         n_modes: int | str | None = "auto", n_jobs: int = 1, progress: bool = False,
         model: ImpactModel | None = None) -> ScanResult:
    """Scan candidate impact locations over all role splits.

    Parameters
    ----------
    structure : Structure
        The filter's model.
    sensors : sequence of sensor specs
        The installed layout, m sensors.
    measurements : array_like (N, m)
        The record (SI), columns in layout order.
    dt : float
        Time step (s).
    splits : list of RoleSplit
    candidates : list of (int, str)
        Candidate locations ``(node, direction)`` (see :func:`candidate_locations`).
    covariances : Covariances
        The assumed levels.
    skip : float
        Seconds at the start left out of the AD errors (filter start-up).
    n_modes : int, "auto" or None
        Filter model reduction with static correction (see :class:`ImpactModel`); None for the
        full model.
    n_jobs : int
        joblib workers over locations; the backend is the caller's (``joblib.parallel_config``),
        so a dask or ray cluster works.
    progress : bool
        A tqdm bar over locations (shown once the scan runs longer than 1 s).
    model : ImpactModel, optional
        A prepared model to reuse (its cached per-location matrices).

    Returns
    -------
    ScanResult

    Examples
    --------
    The impact of :func:`impactloc.locate`'s example, scanned over four candidate joints:

    >>> from core_akf.models import s17_truss
    >>> from impactloc import role_splits, simulate_impact
    >>> sensors = ["strain:5", "strain:9", "strain:13", "strain:22", "strain:26", "acc:6:y", "acc:10:y"]
    >>> Y = simulate_impact(s17_truss(), sensors, "14:y").measurements
    >>> res = scan(s17_truss(), sensors, Y, 1e-3, role_splits(sensors, 2), candidates=[(j, "y") for j in (10, 12, 14, 16)],
    ...            covariances=default_covariances(sensors, Y))
    >>> res.identified, len(res.splits)
    ((14, 'y'), 10)
    """
    from functools import partial

    from joblib import effective_n_jobs

    from core_akf.tasks import run_tasks

    layout = as_layout(sensors)
    Y = check_measurements(layout, measurements)
    if not splits:
        raise AKFInputError("no role splits given")
    if not all(isinstance(s, RoleSplit) for s in splits):
        raise AKFInputError("splits must be RoleSplit objects (see impactloc.role_splits)")
    if len({len(s.ad) for s in splits}) > 1:
        raise AKFInputError("all role splits must hold the same number of AD sensors")
    bad = [i for s in splits for i in s.se + s.ad if not 0 <= i < len(layout)]
    if bad:
        raise AKFInputError(f"role splits refer to sensor index {bad[0]}, but only {len(layout)} sensors are installed")
    locs = parse_force_locations(structure, candidates)
    if not locs:
        raise AKFInputError("no candidate locations")
    skip_n = check_skip(skip, dt, Y.shape[0])
    n_jobs = as_n_jobs(n_jobs)
    model = model or ImpactModel(structure, layout, dt, n_modes)
    if n_jobs == 1:
        it = locs
        if progress:
            from tqdm.auto import tqdm
            it = tqdm(locs, desc="scan", unit="location", leave=False, delay=1.0)
        results = [location_errors(model, loc, splits, Y, [covariances], skip_n) for loc in it]
    else:
        groups = _chunks(locs, effective_n_jobs(n_jobs))
        out = run_tasks(partial(_scan_task, model=model, splits=splits, Y=Y, cov=covariances, skip=skip_n), groups, n_jobs)
        results = [r for group in out for r in group]
    rel = np.stack([r[1][0] for r in results])        # (n_loc, n_splits, n_ad)
    ab = np.stack([r[0][0] for r in results])
    return _summarise(layout, locs, splits, rel, ab, covariances)


def _summarise(layout, locs, splits, rel, ab, covariances):
    import pandas as pd

    err = np.nanmean(rel, axis=2) if rel.size else rel     # (n_loc, n_splits)
    kinds = np.array([s.kind for s in layout])
    rows = []
    for i, (node, d) in enumerate(locs):
        for j, sp in enumerate(splits):
            row = {"node": node, "direction": d, "split": j,
                   "ad_sensors": " ".join(layout[k].label for k in sp.ad),
                   "detectable": bool(np.isfinite(err[i, j])), "error": err[i, j]}
            for kind in dict.fromkeys(kinds[list(sp.ad)]):
                cols = [c for c, k in enumerate(sp.ad) if kinds[k] == kind]
                row[f"error_{kind}"] = float(np.mean(ab[i, j, cols]))
            rows.append(row)
    frame = pd.DataFrame(rows)
    valid = np.isfinite(err)
    if not valid.any():
        raise AKFInputError("no (location, split) pair is detectable: the SE sensors see no static "
                            "response from any candidate location")
    # votes: each split's own best location
    votes = np.zeros(len(locs))
    for j in range(err.shape[1]):
        col = err[:, j]
        if np.isfinite(col).any():
            votes[int(np.nanargmin(col))] += 1
    n_valid_splits = max(1, int(np.isfinite(err).any(axis=0).sum()))
    with np.errstate(all="ignore"):
        mean = np.array([np.nanmean(r) if np.isfinite(r).any() else np.inf for r in err])
        std = np.array([np.nanstd(r) if np.isfinite(r).any() else np.inf for r in err])
    summary = pd.DataFrame({"node": [l[0] for l in locs], "direction": [l[1] for l in locs], "mean": mean,
                            "std": std, "n_splits": valid.sum(axis=1), "votes": votes / n_valid_splits})
    summary = summary.sort_values(["mean", "std"], kind="stable").reset_index(drop=True)
    summary["rank"] = np.arange(1, len(summary) + 1)
    best = summary.iloc[0]
    identified = (int(best.node), best.direction)
    notes = []
    fit = float(np.clip((1.0 - best["mean"]) / (1.0 - _WELL_EXPLAINED), 0.0, 1.0))
    confidence = float(best["votes"]) * fit
    if len(summary) > 1:
        second = summary.iloc[1]
        pooled = math.sqrt(0.5 * (best["std"] ** 2 + second["std"] ** 2))
        margin = float((second["mean"] - best["mean"]) / pooled) if pooled > 0 else math.inf
    else:
        margin = math.inf
        confidence = 0.0
        notes.append("only one candidate location: nothing to compare it with, so the data cannot confirm it "
                     "(confidence 0); give several candidates to locate an impact")
    if best["mean"] > _WELL_EXPLAINED:
        notes.append(f"no candidate explains the data well: the best one (node {identified[0]}) leaves a mean relative "
                     f"AD error of {best['mean']:.2f} (1 = no better than predicting zero); the impact may lie outside "
                     "the candidates, or the model, sensors or data do not match")
    return ScanResult(frame, summary, identified, confidence, margin, err, list(locs), list(splits),
                      covariances, notes)


#: a location whose AD predictions leave at most this relative error explains the data well
#: (the IMP cases leave 0.04-0.24); above it the confidence is scaled down to 0 at an error of 1
_WELL_EXPLAINED = 0.5
