"""How many sensors are worth it: NSGA-II over layouts of varying size, minimising the average
strain error and the number of sensors (or their cost), configured on the GA engine of
:mod:`core_akf.evolution` (DEAP's ``selNSGA2`` for the survival).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from core_akf.checks import AKFInputError
from core_akf.evolution import Algorithm, Evaluator, GeneticAlgorithm, individual_class, tournament_dcd

from .encoding import STRAIN_KINDS, PlateGrid
from .ga import BATCH, PENALTY, check_run_size

if TYPE_CHECKING:
    from core_akf.structure import Structure

    from .encoding import CandidateSet
    from .objective import Objective


@dataclass
class ParetoResult:
    """Outcome of :func:`pareto`.

    Attributes
    ----------
    front : pandas.DataFrame
        One row per non-dominated layout (n_sensors, cost, error, sensors), by size.
    logbook : pandas.DataFrame
        One row per generation.
    evaluations, cache_hits : int
        Counters.
    """

    front: object
    logbook: object
    evaluations: int
    cache_hits: int


class ParetoGA(Algorithm):
    """NSGA-II on layouts of ``lo..hi`` sensors.

    DCD tournament, a crossover that draws each child's sensors from the union of its parents',
    per-sensor mutation and adding or removing one sensor, survival by ``selNSGA2``.

    Parameters
    ----------
    encodings : dict
        Sensor count -> :class:`~sensoropt.encoding.PlateGrid` of that count.
    lo, hi : int
        The smallest and largest layout.
    population : int
        A multiple of 4.
    crossover, mutation : float
        Probabilities.
    """

    individual = individual_class(2)

    def __init__(self, encodings, lo, hi, population, crossover, mutation):
        self.encs, self.lo, self.hi = encodings, lo, hi
        self.size, self.cx, self.mut = population, crossover, mutation
        self.base = encodings[lo]

    def initial(self, rng, pyrng):
        return [self.encs[self.lo + j % (self.hi - self.lo + 1)].random_layout(rng) for j in range(self.size)]

    def check_genome(self, genome):
        return isinstance(genome, list) and self.lo <= len(genome) <= self.hi and self.encs[len(genome)].is_genome(genome)

    def after_initial(self, population):
        from deap import tools

        return tools.selNSGA2(population, len(population))

    def _vary_size(self, layout, rng):
        """Add or remove one sensor (keeps the size within the bounds)."""
        layout = list(layout)
        if (rng.random() < 0.5 and len(layout) < self.hi) or len(layout) == self.lo:
            free = np.setdiff1d(self.base.allowed_indices(), layout)
            layout.append(int(rng.choice(free)))
        else:
            layout.pop(int(rng.integers(len(layout))))
        return tuple(sorted(layout))

    def next_generation(self, population, generation, rng, pyrng, evaluate):
        from deap import tools

        kids = [tuple(p) for p in tournament_dcd(population, len(population), pyrng)]
        for j in range(0, len(kids) - 1, 2):
            if rng.random() < self.cx:
                a, b = kids[j], kids[j + 1]
                union = sorted(set(a) | set(b))
                kids[j] = tuple(sorted(int(i) for i in rng.choice(union, size=len(a), replace=False)))
                kids[j + 1] = tuple(sorted(int(i) for i in rng.choice(union, size=len(b), replace=False)))
        for j in range(len(kids)):
            if rng.random() < self.mut:
                kids[j] = self.encs[len(kids[j])].mutate(kids[j], rng)
            if rng.random() < self.mut:
                kids[j] = self._vary_size(kids[j], rng)
        offspring = evaluate([self.individual(k) for k in kids])
        return tools.selNSGA2(population + offspring, self.size)

    def record(self, population):
        from deap import tools

        front = tools.sortNondominated(population, len(population), first_front_only=True)[0]
        errs = np.array([i.fitness.values[0] for i in population])
        return {"front_size": len({tuple(i) for i in front}), "best_error": float(errs.min()),
                "mean_error": float(errs.mean())}


class _ErrorAndCost:
    """Fitness of a batch of layouts (genome keys): (strain error, cost); an error that is not a
    finite number becomes ``penalty`` (the cost stays), as the thesis' GA penalises."""

    def __init__(self, objective, encoding, cost, penalty):
        self.objective, self.encoding, self.cost, self.penalty = objective, encoding, cost, penalty

    def __call__(self, layouts):
        errors = self.objective.evaluate([self.encoding.sensors(l) for l in layouts])
        out = []
        for layout, e in zip(layouts, errors):
            try:
                e = float(e)
            except (TypeError, ValueError):
                e = math.nan
            out.append((e if math.isfinite(e) else self.penalty,
                        float(sum(self.cost[self.encoding.kind[i]] for i in layout))))
        return out


def pareto(objective: Objective, structure: Structure | None = None, *, kinds: tuple[str, ...] = STRAIN_KINDS,
           sizes: tuple[int, int] = (1, 8), cost: dict[str, float] | None = None, population: int = 60,
           generations: int = 40, crossover: float = 0.8, mutation: float = 0.3, seed: int = 0, n_jobs: int = 1,
           progress: bool = False, penalty: float = PENALTY, candidates: CandidateSet | None = None,
           on_generation: Callable[[dict], None] | None = None) -> ParetoResult:
    """Pareto front of average strain error vs number of sensors (or cost).

    Parameters
    ----------
    objective : object
        A single-objective layout objective (e.g. :class:`StrainErrorObjective` built with an
        encoding of the same kinds); it is evaluated on layouts of every size in ``sizes``.
    structure : Structure, optional
        The plate (its grid of ``kinds`` are the candidates), or None with ``candidates``.
    kinds : tuple of str
        Kinds that may be placed on the plate.
    sizes : (int, int)
        The smallest and largest number of sensors.
    cost : dict, optional
        Kind -> cost per sensor (e.g. ``{"ex": 1, "ey": 1, "gxy": 1, "acc": 3}``); default one
        per sensor, i.e. the second objective is the sensor count.
    population : int
        Rounded up to a multiple of 4 (the NSGA-II tournament takes fours).
    generations : int
    crossover, mutation : float
        Probabilities.
    seed : int
        Seeds the whole run, whatever ``n_jobs``.
    n_jobs : int
        joblib workers for the fitness.
    progress : bool
        A progress bar.
    penalty : float
        The error of an infeasible layout.
    candidates : CandidateSet, optional
        Any candidate set (of any structure) instead of the plate grid; its restriction
        (forbidden regions) holds for every size, its sensor count and budget do not.
    on_generation : callable, optional
        Called with each generation's logbook row.

    Returns
    -------
    ParetoResult

    Examples
    --------
    The front of a toy objective (one over the number of gauges) on a small plate:

    >>> from core_akf.models import plate
    >>> from sensoropt import FunctionObjective
    >>> res = pareto(FunctionObjective(lambda sensors: 1.0 / len(sensors)), plate(4, 4, 0.4, 0.4, 0.002, 200e9, 0.3, 7800.0),
    ...              sizes=(1, 3), population=8, generations=2, seed=0)
    >>> res.front["n_sensors"].tolist(), [round(e, 3) for e in res.front["error"]]
    ([1, 2, 3], [1.0, 0.5, 0.333])
    """
    import pandas as pd

    population = 4 * math.ceil(population / 4)
    check_run_size(population, generations)
    lo, hi = int(sizes[0]), int(sizes[1])
    if not 1 <= lo <= hi:
        raise AKFInputError(f"sizes must satisfy 1 <= min <= max, got {sizes}")
    if candidates is None:
        if structure is None:
            raise AKFInputError("give the plate (structure) or the candidates")
        encs = {k: PlateGrid(structure, kinds=kinds, n_sensors=k) for k in range(lo, hi + 1)}
    else:
        if hi > len(candidates.allowed_indices()):
            raise AKFInputError(f"layouts of up to {hi} sensors asked, but only {len(candidates.allowed_indices())} candidates "
                                "may be placed")
        encs = {k: candidates.with_size(k) for k in range(lo, hi + 1)}
    base = encs[lo]
    cost = {k: 1.0 for k in base.kinds} if cost is None else {str(k): float(v) for k, v in cost.items()}
    missing = [k for k in base.kinds if k not in cost]
    if missing:
        raise AKFInputError(f"cost has no entry for kind(s) {missing}")

    evaluator = Evaluator(_ErrorAndCost(objective, base, cost, penalty), decode=lambda k: k, n_jobs=n_jobs, batch=BATCH,
                          n_objectives=2, infeasible_if=lambda v: v[0] >= penalty)
    algorithm = ParetoGA(encs, lo, hi, population, crossover, mutation)
    res = GeneticAlgorithm(algorithm, evaluator, generations=generations, seed=seed,
                           progress="NSGA-II" if progress else None, hall_of_fame=0, on_generation=on_generation).run()
    # the non-dominated set over everything evaluated (the cache), not only the last population
    best = {}
    for layout, (e, c) in evaluator.cache.items():
        if e >= penalty:      # infeasible (e.g. fewer static sensors than forces)
            continue
        if e < best.get(c, (math.inf,))[0]:
            best[c] = (e, layout)
    front_rows, best_so_far = [], math.inf
    for c in sorted(best):
        e, layout = best[c]
        if e < best_so_far:
            best_so_far = e
            front_rows.append({"n_sensors": len(layout), "cost": c, "error": e, "sensors": " ".join(base.sensors(layout))})
    return ParetoResult(pd.DataFrame(front_rows), res.logbook, res.evaluations, res.cache_hits)
