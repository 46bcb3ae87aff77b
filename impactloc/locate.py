"""The whole identification: role splits -> location scan -> covariance tuning -> force and
response reconstruction (IMP §3), plus the figures of IMP Figs. 4-8."""
from __future__ import annotations

import time
from typing import TYPE_CHECKING

from core_akf.checks import ArrayLike, Layout

if TYPE_CHECKING:
    from core_akf.structure import Structure

    from .scan import Covariances
from dataclasses import dataclass, field

import numpy as np

from core_akf.checks import AKFInputError, as_measurements, as_n_jobs, as_seed
from core_akf.forcemodels import ForceModel
from core_akf.sensors import as_layout

from .reconstruct import reconstruct
from .roles import role_splits
from .scan import ImpactModel, candidate_locations, check_skip, default_covariances, scan
from .tuning import check_decades, tune_covariances, tune_covariances_ml

#: units of the numbers in :meth:`LocateResult.to_dict` (and ``akf locate --json``)
#: the settings of tune_covariances a locate's ``tuning`` may give
TUNING_KEYS = ("population", "generations", "n_splits", "decades", "crossover", "mutation")
LOCATE_UNITS = {"confidence": "share of role splits (0-1)", "margin": "runner-up distance in pooled spreads",
                "peak_force": "N", "time_of_peak": "s", "duration": "s", "impulse": "N s",
                "ranking.mean": "relative RMS error at the AD sensors", "ranking.std": "relative RMS error",
                "covariances": "model_error m^2 (per step), force_increment N^2 (per step), noise SI^2",
                "ad_error_before_tuning": "relative RMS error", "ad_error_after_tuning": "relative RMS error",
                "seconds": "s"}


@dataclass
class LocateResult:
    """Outcome of :func:`locate`.

    Attributes
    ----------
    scan : ScanResult
    tuning : TuningResult or None
    reconstruction : Reconstruction
        With the tuned covariances.
    initial : Reconstruction
        With the assumed covariances.
    seconds : dict
        Wall time per stage (s).
    record_notes : list of str
        What the record says of itself, set by its reader's caller (units of other files, channels
        at rates of their own, gaps); first among :attr:`warnings`.
    """

    scan: object
    tuning: object
    reconstruction: object
    initial: object
    seconds: dict = field(default_factory=dict)
    record_notes: list = field(default_factory=list)

    @property
    def identified(self):
        return self.scan.identified

    @property
    def warnings(self):
        """Why a result should be read with care (list of str): what the record says of itself
        (units, channels at other rates, gaps), low confidence, tuning at a bound."""
        return list(self.record_notes) + list(self.scan.warnings) + (self.tuning.warnings if self.tuning is not None
                                                                     else [])

    def to_dict(self) -> dict:
        """JSON-ready summary: identified node, confidence, margin, force characteristics, ranking.

        Returns
        -------
        dict
        """
        node, d = self.scan.identified
        out = {"identified": int(node), "direction": d, "confidence": self.scan.confidence,
               "margin": self.scan.margin if np.isfinite(self.scan.margin) else None,
               **self.reconstruction.summary.as_dict(),
               "covariances": (self.tuning.covariances if self.tuning else self.scan.covariances).as_dict(),
               "ranking": self.scan.ranking(), "warnings": self.warnings, "seconds": self.seconds,
               "units": LOCATE_UNITS}
        if self.tuning is not None:
            out["tuning"] = self.tuning.method
            out["ad_error_before_tuning"] = self.tuning.initial_error
            out["ad_error_after_tuning"] = self.tuning.tuned_error
        return out


def locate(structure: Structure, sensors: Layout, measurements: ArrayLike, dt: float, *, n_ad: int, direction: str,
           ad_kinds: tuple[str, ...] = ("strain",), candidates: list[int] | None = None,
           covariances: Covariances | None = None, tune: bool | str = True, max_splits: int | None = None,
           n_modes: int | str | None = "auto", skip: float = 0.0, n_jobs: int = 1, seed: int = 0,
           progress: bool = False, tuning: dict | None = None, force_model: ForceModel | None = None) -> LocateResult:
    """Locate an impact and reconstruct its force history.

    Parameters
    ----------
    structure : Structure
        The FE model (the filter's model).
    sensors : sequence of sensor specs
        The installed layout, m sensors.
    measurements : array_like (N, m)
        The record (SI), columns in layout order.
    dt : float
        Time step (s).
    n_ad : int
        AD (held-back) sensors per role split.
    direction : str
        Force direction at the candidates ("y" on the truss, "w" on a plate).
    ad_kinds : tuple of str
        Sensor kinds that may be AD (see :func:`impactloc.role_splits`).
    candidates : list of int, optional
        Candidate node ids, 1-based (default: every free node in ``direction``).
    covariances : Covariances, optional
        The assumed levels (default :func:`default_covariances`).
    tune : bool, "ga" or "ml"
        Tune the covariances at the identified location: True or "ga" with the paper's GA
        (:func:`tune_covariances`; its levels are kept if they lower the AD error), "ml" by maximum
        likelihood (:func:`tune_covariances_ml`; its levels are kept), False not at all.
    max_splits : int, optional
        Cap on the role splits (a seeded sample).
    n_modes : int, "auto" or None
        Filter model reduction for the scan and the tuning (see :class:`ImpactModel`).
    skip : float
        Seconds at the start left out of the AD errors (filter start-up).
    n_jobs : int
        joblib workers (backend from ``joblib.parallel_config``).
    seed : int
        Role-split sample and GA seed.
    progress : bool
        Progress bars.
    tuning : dict, optional
        Options of :func:`tune_covariances` (population, generations, n_splits, decades,
        crossover, mutation); with ``tune="ml"`` only n_splits and decades apply.
    force_model : ForceModel, optional
        The impact's prior (:class:`ImpactModel`): None, the random walk; a Matérn model, whose std
        is then ``sqrt(covariances.force_increment)`` (tuned in its place).

    Returns
    -------
    LocateResult

    Examples
    --------
    A 10 kN, 4 ms impact at joint 14 of the S17 truss (:func:`simulate_impact`), found among four
    candidate joints:

    >>> from core_akf.models import s17_truss
    >>> from impactloc import simulate_impact
    >>> sensors = ["strain:5", "strain:9", "strain:13", "strain:22", "strain:26", "acc:6:y", "acc:10:y"]
    >>> Y = simulate_impact(s17_truss(), sensors, "14:y").measurements
    >>> res = locate(s17_truss(), sensors, Y, 1e-3, n_ad=2, direction="y", candidates=[10, 12, 14, 16],
    ...              tune=False)
    >>> res.scan.identified, res.scan.confidence
    ((14, 'y'), 1.0)
    """
    method = {True: "ga", False: None, "ga": "ga", "ml": "ml"}.get(tune, "?") if isinstance(tune, (bool, str)) else "?"
    if method == "?":
        raise AKFInputError(f"tune must be True, False, \"ga\" or \"ml\", got {tune!r}")
    layout = as_layout(sensors)
    Y = as_measurements(measurements, ndim=2)
    seed, n_jobs = as_seed(seed), as_n_jobs(n_jobs)
    check_skip(skip, dt, Y.shape[0])
    if tuning is not None and not isinstance(tuning, dict):
        raise AKFInputError(f"tuning must be a dict of tune_covariances settings ({', '.join(TUNING_KEYS)}), got "
                            f"{type(tuning).__name__}")
    unknown = sorted(set(tuning or {}) - set(TUNING_KEYS))
    if unknown:
        raise AKFInputError(f"tuning has unknown setting(s) {unknown}; use {', '.join(TUNING_KEYS)}")
    if tuning and "decades" in tuning:
        check_decades(tuning["decades"], "tuning decades")           # before the scan, not after it
    splits = role_splits(layout, n_ad, ad_kinds, max_splits=max_splits, seed=seed)
    cands = candidate_locations(structure, direction, candidates)
    cov = covariances or default_covariances(layout, Y)
    seconds = {}
    t = time.perf_counter()
    model = ImpactModel(structure, layout, dt, n_modes, force_model)
    res = scan(structure, layout, Y, dt, splits, candidates=cands, covariances=cov, skip=skip, n_modes=n_modes,
               n_jobs=n_jobs, progress=progress, model=model)
    seconds["scan"] = time.perf_counter() - t
    tuned = None
    best_cov = cov
    if method is not None:
        t = time.perf_counter()
        opts = dict(tuning or {})
        if method == "ga":
            tuned = tune_covariances(structure, layout, Y, dt, res.identified, splits, start=cov, seed=seed, skip=skip,
                                     n_jobs=n_jobs, progress=progress, model=model, **opts)
        else:
            unused = sorted(set(opts) - {"n_splits", "decades"})
            if unused:
                raise AKFInputError(f"tune = \"ml\" fits by maximum likelihood: the GA settings {unused} do not apply")
            tuned = tune_covariances_ml(structure, layout, Y, dt, res.identified, splits, start=cov, seed=seed,
                                        skip=skip, model=model, **opts)
        seconds["tuning"] = time.perf_counter() - t
        if method == "ml" or tuned.tuned_error < tuned.initial_error:
            best_cov = tuned.covariances
    t = time.perf_counter()
    initial = reconstruct(structure, layout, Y, dt, res.identified, cov, n_modes, model.force_model)
    final = reconstruct(structure, layout, Y, dt, res.identified, best_cov, n_modes, model.force_model) \
        if best_cov is not cov else initial
    seconds["reconstruction"] = time.perf_counter() - t
    seconds["total"] = sum(seconds.values())
    return LocateResult(res, tuned, final, initial, seconds)
