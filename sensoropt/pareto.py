"""How many sensors are worth it: NSGA-II (DEAP ``selNSGA2``) over layouts of varying size,
minimising the average strain error and the number of sensors (or their cost).
"""
from __future__ import annotations

import math
import random
import time
from dataclasses import dataclass

import numpy as np

from core_akf.exceptions import AKFInputError

from .encoding import Encoding
from .ga import PENALTY, Evaluator


def _creator():
    from deap import base, creator

    if not hasattr(creator, "ParetoFitness"):
        creator.create("ParetoFitness", base.Fitness, weights=(-1.0, -1.0))
        creator.create("ParetoIndividual", list, fitness=creator.ParetoFitness)
    return creator


@dataclass
class ParetoResult:
    """front : DataFrame, one row per non-dominated layout (n_sensors, cost, error, sensors), by
    size;  logbook : DataFrame per generation;  evaluations, cache_hits"""

    front: object
    logbook: object
    evaluations: int
    cache_hits: int


def pareto(objective, structure, *, kinds=("ex", "ey", "gxy"), sizes=(1, 8), cost=None, population=60,
           generations=40, crossover=0.8, mutation=0.3, seed=0, n_jobs=1, progress=False, penalty=PENALTY):
    """Pareto front of average strain error vs number of sensors (or cost).

    Parameters
    ----------
    objective : a single-objective layout objective (e.g. :class:`StrainErrorObjective` built with
        an encoding of the same kinds; it is evaluated on layouts of every size in ``sizes``)
    structure : the plate (for the candidates)
    sizes : (min, max) number of sensors
    cost : dict kind -> cost per sensor (e.g. ``{"ex": 1, "ey": 1, "gxy": 1, "acc": 3}``);
        default one per sensor, i.e. the second objective is the sensor count

    Returns
    -------
    :class:`ParetoResult`
    """
    import pandas as pd
    from deap import tools

    population = 4 * math.ceil(population / 4)   # selTournamentDCD takes multiples of four
    lo, hi = int(sizes[0]), int(sizes[1])
    if not 1 <= lo <= hi:
        raise AKFInputError(f"sizes must satisfy 1 <= min <= max, got {sizes}")
    encs = {k: Encoding(structure, kinds=kinds, n_sensors=k) for k in range(lo, hi + 1)}
    base = encs[lo]
    cost = {k: 1.0 for k in base.kinds} if cost is None else {str(k): float(v) for k, v in cost.items()}
    missing = [k for k in base.kinds if k not in cost]
    if missing:
        raise AKFInputError(f"cost has no entry for kind(s) {missing}")
    creator = _creator()
    rng = np.random.default_rng(seed)
    state = random.getstate()
    random.seed(int(rng.integers(2 ** 31)))
    evaluate = Evaluator(objective, base, n_jobs=n_jobs, penalty=penalty)

    def layout_cost(l):
        return float(sum(cost[base.kind[i]] for i in l))

    def assess(inds):
        errs = evaluate([tuple(i) for i in inds])
        for ind, e in zip(inds, errs):
            ind.fitness.values = (e, layout_cost(ind))

    def vary_size(l):
        """Add or remove one sensor (keeps the size within ``sizes``)."""
        l = list(l)
        if (rng.random() < 0.5 and len(l) < hi) or len(l) == lo:
            free = np.setdiff1d(np.arange(len(base.candidates)), l)
            l.append(int(rng.choice(free)))
        else:
            l.pop(int(rng.integers(len(l))))
        return tuple(sorted(l))

    try:
        pop = []
        for j in range(population):
            k = lo + j % (hi - lo + 1)
            pop.append(creator.ParetoIndividual(encs[k].random_layout(rng)))
        assess(pop)
        pop = tools.selNSGA2(pop, len(pop))
        rows, t0 = [], time.perf_counter()
        bar = None
        if progress:
            from tqdm.auto import tqdm
            bar = tqdm(total=generations, desc="NSGA-II", unit="gen", leave=False, delay=1.0)
        for gen in range(generations + 1):
            if gen > 0:
                parents = tools.selTournamentDCD(pop, len(pop))
                kids = [tuple(p) for p in parents]
                for j in range(0, len(kids) - 1, 2):
                    if rng.random() < crossover:
                        a, b = kids[j], kids[j + 1]
                        union = sorted(set(a) | set(b))
                        kids[j] = tuple(sorted(int(i) for i in rng.choice(union, size=len(a), replace=False)))
                        kids[j + 1] = tuple(sorted(int(i) for i in rng.choice(union, size=len(b), replace=False)))
                for j in range(len(kids)):
                    if rng.random() < mutation:
                        kids[j] = encs[len(kids[j])].mutate(kids[j], rng)
                    if rng.random() < mutation:
                        kids[j] = vary_size(kids[j])
                offspring = [creator.ParetoIndividual(k) for k in kids]
                assess(offspring)
                pop = tools.selNSGA2(pop + offspring, population)
            front = tools.sortNondominated(pop, len(pop), first_front_only=True)[0]
            errs = np.array([i.fitness.values[0] for i in pop])
            rows.append({"generation": gen, "front_size": len({tuple(i) for i in front}),
                         "best_error": float(errs.min()), "mean_error": float(errs.mean()),
                         "evaluations": evaluate.evaluations, "cache_hits": evaluate.hits,
                         "infeasible": evaluate.infeasible, "seconds": time.perf_counter() - t0})
            if bar is not None and gen > 0:
                bar.update(1)
        if bar is not None:
            bar.close()
    finally:
        random.setstate(state)
    # the non-dominated set over everything evaluated (the cache), not only the last population
    best = {}
    for l, e in evaluate.cache.items():
        if e >= evaluate.penalty:      # infeasible (e.g. fewer static sensors than forces)
            continue
        c = layout_cost(l)
        if e < best.get(c, (math.inf,))[0]:
            best[c] = (e, l)
    front_rows, best_so_far = [], math.inf
    for c in sorted(best):
        e, l = best[c]
        if e < best_so_far:
            best_so_far = e
            front_rows.append({"n_sensors": len(l), "cost": c, "error": e, "sensors": " ".join(base.sensors(l))})
    return ParetoResult(pd.DataFrame(front_rows), pd.DataFrame(rows), evaluate.evaluations, evaluate.hits)
