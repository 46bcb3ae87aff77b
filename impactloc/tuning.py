"""Covariance tuning (IMP §3): a DEAP genetic algorithm over the log10 levels of ``Q`` (model
error), ``S`` (force increment) and ``R`` (noise per sensor kind) that minimises the AD error at
the identified location, averaged over role splits.

The Kalman gain does not change when ``Q``, ``S`` and ``R`` are all scaled by one factor, so one
noise level (the first sensor kind's) stays at its starting value and the GA searches the others
relative to it: one gene fewer, no flat direction.
"""
from __future__ import annotations

import math
import random
import time
from dataclasses import dataclass, field

import numpy as np

from core_akf.exceptions import AKFInputError

from .scan import Covariances, ImpactModel, check_measurements, location_errors

#: covariance sets per fitness batch / joblib task (each = n_splits filters, ~0.1 s)
_TASK = 4


def _creator():
    """DEAP creator classes, made once per process (never pickled: workers get plain lists)."""
    from deap import base, creator

    if not hasattr(creator, "ImpactTuneFitness"):
        creator.create("ImpactTuneFitness", base.Fitness, weights=(-1.0,))
        creator.create("ImpactTuneIndividual", list, fitness=creator.ImpactTuneFitness)
    return creator


@dataclass
class TuningResult:
    """Outcome of :func:`tune_covariances`.

    covariances : the best :class:`Covariances` found
    initial_error, tuned_error : mean relative AD error with the starting / tuned levels
    logbook : DataFrame, one row per generation (best, mean, std, evaluations, seconds)
    genes : names of the tuned log10 levels
    at_bound : {gene: "lower"|"upper"} for tuned levels on (within 1 % of the range of) a search
        bound: the optimum may lie beyond it; widen ``decades`` or move the starting levels
    """

    covariances: Covariances
    initial_error: float
    tuned_error: float
    logbook: object
    genes: list = field(default_factory=list)
    at_bound: dict = field(default_factory=dict)

    @property
    def warnings(self):
        """Plain-language warnings (list of str): levels tuned to a search bound."""
        def level(gene):
            c = self.covariances
            return c.noise[gene[len("noise_"):]] if gene.startswith("noise_") else getattr(c, gene)

        return [f"covariance tuning stopped at the {side} search bound of {gene} ({level(gene):.3g}); the best "
                "level may lie beyond it: widen tuning.decades or start from other levels"
                for gene, side in self.at_bound.items()]


def _to_covariances(x, names, start):
    vals = dict(zip(names, (10.0 ** v for v in x)))
    noise = dict(start.noise)
    for k in noise:
        if f"noise_{k}" in vals:
            noise[k] = vals[f"noise_{k}"]
    return Covariances(vals["model_error"], vals["force_increment"], noise)


def _fitness_task(model, loc, splits, Y, covs, skip):
    _, rel = location_errors(model, loc, splits, Y, covs, skip)
    with np.errstate(all="ignore"):
        f = np.nanmean(rel, axis=(1, 2))
    return [float(v) if np.isfinite(v) else math.inf for v in f]


def tune_covariances(structure, sensors, measurements, dt, location, splits, *, start, decades=3.0,
                     population=12, generations=8, n_splits=8, crossover=0.7, mutation=0.3, seed=0,
                     skip=0.0, n_modes="auto", n_jobs=1, progress=False, model=None):
    """Tune the AKF covariance levels with a GA (DEAP) at a known force location.

    Parameters
    ----------
    location : (node, direction) -- the identified impact location
    splits : role splits; ``n_splits`` of them (a seeded sample; all if fewer) make the fitness
    start : :class:`Covariances` -- the assumed levels; the search spans +-``decades`` around them
    population, generations, crossover, mutation : GA settings (elitism keeps the best one)
    seed : int -- the whole run repeats exactly for one seed, whatever ``n_jobs``
    n_jobs : joblib workers over the population (backend from ``joblib.parallel_config``)

    Returns
    -------
    :class:`TuningResult`
    """
    import pandas as pd
    from deap import base, tools
    from joblib import Parallel, delayed

    if population < 2 or generations < 0:
        raise AKFInputError("population must be >= 2 and generations >= 0")
    if not decades > 0:
        raise AKFInputError(f"decades must be > 0, got {decades}")
    model = model or ImpactModel(structure, sensors, dt, n_modes)
    Y = check_measurements(model.layout, measurements)
    skip_n = int(round(skip / dt))
    rng = np.random.default_rng(seed)
    if not splits:
        raise AKFInputError("no role splits given")
    picked = sorted(rng.choice(len(splits), size=min(n_splits, len(splits)), replace=False).tolist())
    tune_splits = [splits[i] for i in picked]
    kinds = list(dict.fromkeys(s.kind for s in model.layout))
    names = ["model_error", "force_increment"] + [f"noise_{k}" for k in kinds[1:]]
    x0 = np.log10([start.model_error if start.model_error > 0 else 1e-20, start.force_increment]
                  + [start.noise[k] for k in kinds[1:]])
    lo, hi = x0 - decades, x0 + decades

    def evaluate(xs):
        # fixed-size chunks: the batch composition (and so every rounding) does not depend on n_jobs
        covs = [_to_covariances(x, names, start) for x in xs]
        chunks = [covs[i:i + _TASK] for i in range(0, len(covs), _TASK)]
        if n_jobs == 1 or len(chunks) == 1:
            parts = [_fitness_task(model, location, tune_splits, Y, c, skip_n) for c in chunks]
        else:
            parts = Parallel(n_jobs=n_jobs)(delayed(_fitness_task)(model, location, tune_splits, Y, c, skip_n)
                                            for c in chunks)
        return [f for p in parts for f in p]

    creator = _creator()
    tb = base.Toolbox()
    state = random.getstate()            # DEAP's operators draw from the global `random`
    random.seed(seed)
    try:
        pop = [creator.ImpactTuneIndividual(x0.tolist())]
        pop += [creator.ImpactTuneIndividual(rng.uniform(lo, hi).tolist()) for _ in range(population - 1)]
        tb.register("mate", tools.cxBlend, alpha=0.3)
        tb.register("mutate", tools.mutGaussian, mu=0.0, sigma=0.4 * decades / 3, indpb=0.5)
        tb.register("select", tools.selTournament, tournsize=3)
        for ind, f in zip(pop, evaluate([list(p) for p in pop])):
            ind.fitness.values = (f,)
        initial_error = pop[0].fitness.values[0]
        rows = []
        t0 = time.perf_counter()
        bar = None
        if progress:
            from tqdm.auto import tqdm
            bar = tqdm(total=generations, desc="tuning", unit="gen", leave=False, delay=1.0)
        for gen in range(generations + 1):
            if gen > 0:
                elite = tools.selBest(pop, 1)[0]
                offspring = [tb.clone(i) for i in tb.select(pop, len(pop) - 1)]
                for a, b in zip(offspring[::2], offspring[1::2]):
                    if random.random() < crossover:
                        tb.mate(a, b)
                        del a.fitness.values, b.fitness.values
                for ind in offspring:
                    if random.random() < mutation:
                        tb.mutate(ind)
                        del ind.fitness.values
                for ind in offspring:
                    ind[:] = np.clip(ind, lo, hi).tolist()
                fresh = [ind for ind in offspring if not ind.fitness.valid]
                for ind, f in zip(fresh, evaluate([list(i) for i in fresh])):
                    ind.fitness.values = (f,)
                pop = [tb.clone(elite)] + offspring
                n_eval = len(fresh)
                if bar is not None:
                    bar.update(1)
            else:
                n_eval = len(pop)
            fits = np.array([i.fitness.values[0] for i in pop])
            finite = fits[np.isfinite(fits)]
            rows.append({"generation": gen, "best": float(fits.min()),
                         "mean": float(finite.mean()) if finite.size else math.inf,
                         "std": float(finite.std()) if finite.size else math.nan,
                         "infeasible": int((~np.isfinite(fits)).sum()), "evaluations": n_eval,
                         "seconds": time.perf_counter() - t0})
        if bar is not None:
            bar.close()
    finally:
        random.setstate(state)
    best = tools.selBest(pop, 1)[0]
    edge = 0.01 * (hi - lo)
    at_bound = {g: ("lower" if v <= l + e else "upper") for g, v, l, h, e in zip(names, best, lo, hi, edge)
                if v <= l + e or v >= h - e}
    return TuningResult(_to_covariances(list(best), names, start), float(initial_error), float(best.fitness.values[0]),
                        pd.DataFrame(rows), names, at_bound)
