"""Covariance tuning at the identified location, two ways.

* The paper's (IMP §3, :func:`tune_covariances`): a genetic algorithm (on the engine of
  :mod:`core_akf.evolution`) over the log10 levels of ``Q`` (model error), ``S`` (force increment)
  and ``R`` (noise per sensor kind) that minimises the AD error, averaged over role splits.  The
  Kalman gain does not change when ``Q``, ``S`` and ``R`` are all scaled by one factor, so one
  noise level (the first sensor kind's) stays at its starting value and the GA searches the others
  relative to it: one gene fewer, no flat direction.
* Maximum likelihood (:func:`tune_covariances_ml`): the levels under which the whole record, all
  sensors together, is most probable (:func:`core_akf.calibration.calibrate`); the likelihood sees
  the absolute levels, so every level is fitted.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from core_akf.checks import AKFInputError, ForceLocation, Layout, Measurements
from core_akf.evolution import Algorithm, Evaluator, GeneticAlgorithm, best, blend, gaussian, tournament

from .roles import RoleSplit
from .scan import Covariances, ImpactModel, check_measurements, location_errors

if TYPE_CHECKING:
    from core_akf.structure import Structure

#: covariance sets per fitness batch / joblib task (each = n_splits filters, ~0.1 s)
_TASK = 4


#: a tuned level on a search bound is settled (not a warning) when moving it 3 decades further changes
#: the AD error by less than this fraction
BOUND_INSENSITIVE = 0.005


@dataclass
class TuningResult:
    """Outcome of :func:`tune_covariances`.

    Attributes
    ----------
    covariances : the best :class:`Covariances` found
    initial_error, tuned_error : mean relative AD error with the starting / tuned levels
    logbook : DataFrame, one row per generation (best, mean, std, evaluations, seconds)
    genes : names of the tuned log10 levels
    at_bound : {gene: "lower"|"upper"} for tuned levels on (within 1 % of the range of) a search
        bound where a level 3 decades further out changes the error: the optimum may lie beyond
        it; widen ``decades`` or move the starting levels
    settled : {gene: "lower"|"upper"} for levels on a bound beyond which the error no longer
        changes (within :data:`BOUND_INSENSITIVE`): e.g. no model error at all when the filter's
        model is exact.  Not a warning: any level past the bound gives the same estimate.
    method : "ga" or "ml"
        How the levels were tuned.
    messages : list of str
        Further warnings of the fit (maximum likelihood: a level the record does not identify).
    """

    covariances: Covariances
    initial_error: float
    tuned_error: float
    logbook: object
    genes: list = field(default_factory=list)
    at_bound: dict = field(default_factory=dict)
    settled: dict = field(default_factory=dict)
    method: str = "ga"
    messages: list = field(default_factory=list)

    @property
    def warnings(self):
        """Plain-language warnings (list of str): levels tuned to a search bound."""
        def level(gene):
            c = self.covariances
            return c.noise[gene[len("noise_"):]] if gene.startswith("noise_") else getattr(c, gene)

        return [f"covariance tuning stopped at the {side} search bound of {gene} ({level(gene):.3g}); the best "
                "level may lie beyond it: widen tuning.decades or start from other levels"
                for gene, side in self.at_bound.items()] + [f"covariance tuning: {m}" for m in self.messages]


def _to_covariances(x, names, start):
    vals = dict(zip(names, (10.0 ** v for v in x)))
    noise = dict(start.noise)
    for k in noise:
        if f"noise_{k}" in vals:
            noise[k] = vals[f"noise_{k}"]
    return Covariances(vals["model_error"], vals["force_increment"], noise)


def _split_sample(splits, n_splits, rng):
    """The role splits of the tuning: ``n_splits`` of them drawn with ``rng`` (all if fewer), in order."""
    picked = sorted(rng.choice(len(splits), size=min(n_splits, len(splits)), replace=False).tolist())
    return [splits[i] for i in picked]


class _TuningFitness:
    """Fitness of a batch of log10 covariance levels: the mean relative AD error over the tuning
    splits at the known location (``inf`` where a filter fails)."""

    def __init__(self, model, location, splits, Y, names, start, skip):
        self.model, self.location, self.splits, self.Y = model, location, splits, Y
        self.names, self.start, self.skip = names, start, skip

    def __call__(self, xs):
        covs = [_to_covariances(x, self.names, self.start) for x in xs]
        _, rel = location_errors(self.model, self.location, self.splits, self.Y, covs, self.skip)
        with np.errstate(all="ignore"):
            f = np.nanmean(rel, axis=(1, 2))
        return [float(v) if np.isfinite(v) else math.inf for v in f]


#: the widest search: +-10 decades around the starting levels (a factor 1e10 either way)
MAX_DECADES = 10.0


def check_decades(decades, name="decades"):
    """The half-width of the tuning's search box (decades of each level), checked before any work.

    Parameters
    ----------
    decades : float
        Between 0 (exclusive) and :data:`MAX_DECADES`.
    name : str
        What to call it in the message.

    Raises
    ------
    AKFInputError
        Outside that range (levels 10^400 times the start overflow to inf or 0).

    Examples
    --------
    >>> check_decades(3.0)
    """
    if not 0 < decades <= MAX_DECADES:
        raise AKFInputError(f"{name} = {decades!r} is the half-width of the search around the starting levels, in "
                            f"decades: it must be above 0 and at most {MAX_DECADES:g} (a factor 1e{MAX_DECADES:g} either "
                            "way; 3 is the default)")


class TuningGA(Algorithm):
    """An elitist real-coded GA on the log10 levels.

    The starting levels plus uniform draws in the box, tournament of 3, blend crossover (alpha
    0.3), Gaussian mutation, clipped to the box.

    Parameters
    ----------
    x0 : ndarray (g,)
        The starting log10 levels.
    lo, hi : ndarray (g,)
        The box.
    population : int
    crossover, mutation : float
        Probabilities.
    decades : float
        Half-width of the box (sets the mutation's step).
    """

    def __init__(self, x0, lo, hi, population, crossover, mutation, decades):
        self.x0, self.lo, self.hi, self.size = x0, lo, hi, population
        self.cx, self.mut, self.sigma = crossover, mutation, 0.4 * decades / 3

    def initial(self, rng, pyrng):
        return [self.x0.tolist()] + [rng.uniform(self.lo, self.hi).tolist() for _ in range(self.size - 1)]

    def check_genome(self, genome):
        return super().check_genome(genome) and len(genome) == len(self.x0) and bool(
            np.all((np.asarray(genome) >= self.lo) & (np.asarray(genome) <= self.hi)))

    def next_generation(self, population, generation, rng, pyrng, evaluate):
        elite = best(population, 1)[0].copy()
        offspring = [i.copy() for i in tournament(population, len(population) - 1, 3, pyrng)]
        for a, b in zip(offspring[::2], offspring[1::2]):
            if pyrng.random() < self.cx:
                blend(a, b, 0.3, pyrng)
                del a.fitness.values, b.fitness.values
        for ind in offspring:
            if pyrng.random() < self.mut:
                gaussian(ind, self.sigma, 0.5, pyrng)
                del ind.fitness.values
        for ind in offspring:
            ind[:] = np.clip(ind, self.lo, self.hi).tolist()
        return [elite] + offspring

    def record(self, population):
        row = super().record(population)
        row["infeasible_in_population"] = int(sum(not math.isfinite(i.fitness.values[0]) for i in population))
        return row


def tune_covariances(structure: Structure, sensors: Layout, measurements: Measurements, dt: float,
                     location: ForceLocation, splits: Sequence[RoleSplit], *, start: Covariances, decades: float = 3.0,
                     population: int = 12, generations: int = 8, n_splits: int = 8, crossover: float = 0.7,
                     mutation: float = 0.3, seed: int = 0, skip: float = 0.0, n_modes: int | str | None = "auto",
                     n_jobs: int = 1, progress: bool = False, model: ImpactModel | None = None) -> TuningResult:
    """Tune the AKF covariance levels with a GA at a known force location.

    Parameters
    ----------
    structure : Structure
        The filter's model.
    sensors : sequence of sensor specs
        The installed layout.
    measurements : array_like (N, m)
        The record (SI).
    dt : float
        Time step (s).
    location : (int, str)
        The identified impact location ``(node, direction)``.
    splits : list of RoleSplit
        Role splits; ``n_splits`` of them (a seeded sample; all if fewer) make the fitness.
    start : Covariances
        The assumed levels; the search spans +-``decades`` around them.
    decades : float
        Half-width of the search box (decades of each level).
    population, generations : int
        GA settings (elitism keeps the best one).
    n_splits : int
        Role splits in the fitness.
    crossover, mutation : float
        Probabilities.
    seed : int
        The whole run repeats exactly for one seed, whatever ``n_jobs``.
    skip : float
        Seconds at the start left out of the AD errors.
    n_modes : int, "auto" or None
        Filter model reduction (see :class:`ImpactModel`).
    n_jobs : int
        joblib workers over the population (backend from ``joblib.parallel_config``).
    progress : bool
        A progress bar.
    model : ImpactModel, optional
        A prepared model to reuse (its cached per-location matrices).

    Returns
    -------
    TuningResult

    Examples
    --------
    A one-generation search around the assumed levels (the best is never worse than the start):

    >>> from core_akf.models import s17_truss
    >>> from impactloc import default_covariances, role_splits, simulate_impact
    >>> sensors = ["strain:5", "strain:9", "strain:13", "strain:22", "strain:26", "acc:6:y", "acc:10:y"]
    >>> Y = simulate_impact(s17_truss(), sensors, "14:y").measurements
    >>> res = tune_covariances(s17_truss(), sensors, Y, 1e-3, (14, "y"), role_splits(sensors, 2),
    ...                        start=default_covariances(sensors, Y), population=4, generations=1, seed=0)
    >>> res.tuned_error <= res.initial_error, sorted(res.genes)[:2]
    (True, ['force_increment', 'model_error'])
    """
    if population < 2 or generations < 0:
        raise AKFInputError("population must be >= 2 and generations >= 0")
    check_decades(decades)
    model = model or ImpactModel(structure, sensors, dt, n_modes)
    Y = check_measurements(model.layout, measurements)
    skip_n = int(round(skip / dt))
    rng = np.random.default_rng(seed)
    if not splits:
        raise AKFInputError("no role splits given")
    tune_splits = _split_sample(splits, n_splits, rng)
    kinds = list(dict.fromkeys(s.kind for s in model.layout))
    names = ["model_error", "force_increment"] + [f"noise_{k}" for k in kinds[1:]]
    x0 = np.log10([start.model_error if start.model_error > 0 else 1e-20, start.force_increment]
                  + [start.noise[k] for k in kinds[1:]])
    lo, hi = x0 - decades, x0 + decades

    evaluator = Evaluator(_TuningFitness(model, location, tune_splits, Y, names, start, skip_n), decode=list,
                          n_jobs=n_jobs, batch=_TASK)
    algorithm = TuningGA(x0, lo, hi, population, crossover, mutation, decades)
    res = GeneticAlgorithm(algorithm, evaluator, generations=generations, seed=seed,
                           progress="tuning" if progress else None, hall_of_fame=0).run()
    initial_error = evaluator.cache[tuple(x0.tolist())][0]
    best_x, (best_f,) = res.hall_of_fame[0]
    edge = 0.01 * (hi - lo)
    at_bound = {g: ("lower" if v <= l + e else "upper") for g, v, l, h, e in zip(names, best_x, lo, hi, edge)
                if v <= l + e or v >= h - e}
    # a level at a bound matters only if moving it further changes the error: probe once, 3 decades out
    settled = {}
    for g, side in list(at_bound.items()):
        probe = list(best_x)
        probe[names.index(g)] += -3.0 if side == "lower" else 3.0
        beyond = evaluator([tuple(probe)])[0][0]
        if abs(beyond - best_f) <= BOUND_INSENSITIVE * abs(best_f):
            settled[g] = side
            del at_bound[g]
    return TuningResult(_to_covariances(list(best_x), names, start), float(initial_error), float(best_f),
                        res.logbook, names, at_bound, settled)


#: the names of :func:`core_akf.calibration.calibrate` for the genes of :class:`TuningResult`
_ML_GENES = {"model_error_cov": "model_error", "force_increment_cov": "force_increment", "force_std": "force_increment"}


def tune_covariances_ml(structure: Structure, sensors: Layout, measurements: Measurements, dt: float,
                        location: ForceLocation, splits: Sequence[RoleSplit], *, start: Covariances,
                        decades: float = 3.0, n_splits: int = 8, seed: int = 0, skip: float = 0.0,
                        n_modes: int | str | None = "auto", model: ImpactModel | None = None) -> TuningResult:
    """Tune the AKF covariance levels by maximum likelihood at a known force location.

    The levels of ``S``, ``R`` per sensor kind and (when it starts above zero) ``Q`` that make the
    record most probable under the steady-state AKF fed by every sensor
    (:func:`core_akf.calibration.calibrate` on the filter model of the scan).  The AD errors before
    and after are those of :func:`tune_covariances` (the same split sample), to compare the two.

    Parameters
    ----------
    structure : Structure
        The filter's model.
    sensors : sequence of sensor specs
        The installed layout.
    measurements : array_like (N, m)
        The record (SI).
    dt : float
        Time step (s).
    location : (int, str)
        The identified impact location ``(node, direction)``.
    splits : list of RoleSplit
        Role splits; ``n_splits`` of them (a seeded sample, as the GA's) give the AD errors.
    start : Covariances
        The assumed levels; the search spans +-``decades`` around them.
    decades : float
        Half-width of the search (decades of each level).
    n_splits : int
        Role splits of the AD errors.
    seed : int
        The split sample.
    skip : float
        Seconds at the start left out of the AD errors.
    n_modes : int, "auto" or None
        Filter model reduction (see :class:`ImpactModel`).
    model : ImpactModel, optional
        A prepared model to reuse.

    Returns
    -------
    TuningResult
        ``method = "ml"``; ``logbook`` one row (log-likelihood before and after, filters run,
        seconds); ``messages`` the warnings of the fit.

    Examples
    --------
    >>> from core_akf.models import s17_truss
    >>> from impactloc import default_covariances, role_splits, simulate_impact
    >>> sensors = ["strain:5", "strain:9", "strain:13", "strain:22", "strain:26", "acc:6:y", "acc:10:y"]
    >>> Y = simulate_impact(s17_truss(), sensors, "14:y").measurements
    >>> res = tune_covariances_ml(s17_truss(), sensors, Y, 1e-3, (14, "y"), role_splits(sensors, 2),
    ...                           start=default_covariances(sensors, Y))
    >>> res.method, sorted(res.genes)
    ('ml', ['force_increment', 'model_error', 'noise_acc', 'noise_strain'])
    """
    import time

    import pandas as pd

    from core_akf.calibration import calibrate

    check_decades(decades)
    if not splits:
        raise AKFInputError("no role splits given")
    t0 = time.perf_counter()
    model = model or ImpactModel(structure, sensors, dt, n_modes)
    Y = check_measurements(model.layout, measurements)
    k = model.n_modes
    filter_structure = structure if k is None else structure.memo(
        ("reduced with static correction", int(k)), lambda: structure.reduce(int(k), static_correction=True))
    force = "force_increment_cov" if model.force_model is None else "force_std"     # a Matérn model: its std
    parameters = ["noise_cov", force] + (["model_error_cov"] if start.model_error > 0 else [])
    fit = calibrate(filter_structure, model.layout, [location], Y, dt, parameters=parameters,
                    model_error_cov=start.model_error, force_model=start.force_model(model.force_model),
                    noise_cov=dict(start.noise), decades=decades)
    v = fit.values
    force_level = v["force_increment_cov"] if model.force_model is None else float(v["force_std"]) ** 2
    tuned = Covariances(v.get("model_error_cov", start.model_error), force_level,
                        {kind: v["noise_cov"].get(kind, level) for kind, level in start.noise.items()})
    sample = _split_sample(splits, n_splits, np.random.default_rng(seed))
    _, rel = location_errors(model, location, sample, Y, [start, tuned], int(round(skip / dt)))
    with np.errstate(all="ignore"):
        initial_error, tuned_error = (float(e) for e in np.nanmean(rel, axis=(1, 2)))
    genes = [_ML_GENES.get(n, n.replace("noise_cov:", "noise_")) for n in fit.multipliers]
    logbook = pd.DataFrame([{"loglik_before": fit.loglik_before, "loglik_after": fit.loglik_after,
                             "evaluations": fit.evaluations, "seconds": time.perf_counter() - t0}])
    messages = [w.replace("noise_cov:", "noise_").replace("force_increment_cov", "force_increment")
                .replace("model_error_cov", "model_error") for w in fit.warnings]
    return TuningResult(tuned, initial_error, tuned_error, logbook, genes, method="ml", messages=messages)
