"""The placement GA (TH §4): an elitist generational GA with tournament selection, set-based
crossover and per-sensor mutations (or the thesis' intermediate crossover and adaptive mutation),
configured on the one GA engine of :mod:`core_akf.evolution` (fitness cache, batched parallel
evaluation, JSON checkpoints, logbook, seeded random streams: one seed gives a bit-identical run
on 1 or many workers, and a resumed run continues exactly).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from core_akf.checks import AKFInputError, as_count, as_probability, check_memory
from core_akf.defaults import default
from core_akf.evolution import Algorithm, Evaluator, GeneticAlgorithm, Individual, best, tournament

if TYPE_CHECKING:
    import pandas as pd

    from .encoding import CandidateSet
    from .objective import Objective

#: layouts per fitness batch (fixed: the batch composition must not depend on n_jobs)
BATCH = 10
#: fitness of an infeasible layout (undetectable, failing filter, NaN from a user objective)
PENALTY = default("penalty")

THESIS = dict(population=50, generations=100, elite=2, crossover=0.8, mutation=0.16, tournament=4,
              stall_generations=50, stall_tol=1e-6)


@dataclass
class PlacementResult:
    """Outcome of :func:`place`.

    Attributes
    ----------
    best : tuple of int
        The canonical layout (candidate indices).
    best_error : float
        Its fitness (µε for the strain-error objective).
    sensors : list of str
        Its sensors.
    layout : list of dict
        Its :meth:`~sensoropt.encoding.CandidateSet.records` (1-based node ids).
    logbook : pandas.DataFrame
        Per generation: best, mean, std, diversity, evaluations, cache_hits, infeasible, seconds.
    hall_of_fame : list of (list of str, float)
        ``(sensors, fitness)``, best first.
    evaluations, cache_hits, infeasible : int
        Counters.
    stopped : str
        Why the run ended ("generations", "stall").
    seed : int
    settings : dict
        The GA settings of the run.
    """

    best: tuple
    best_error: float
    sensors: list
    layout: list
    logbook: object
    hall_of_fame: list
    evaluations: int
    cache_hits: int
    infeasible: int
    stopped: str
    seed: int
    settings: dict = field(default_factory=dict)


class PlacementGA(Algorithm):
    """The thesis' elitist generational GA on canonical layouts.

    ``elite`` best layouts kept, tournament selection, set-based (or intermediate) crossover and
    per-sensor (or adaptive) mutation.

    Parameters
    ----------
    encoding : CandidateSet or PlateGrid
    population : int
    generations : int
        Generations after the initial one (scales the adaptive mutation).
    elite : int
        Layouts kept unchanged per generation.
    crossover, mutation : float
        Probabilities.
    tournament : int
        Tournament size.
    operators : str
        "set" or "thesis" (see :func:`place`).
    initial : list of tuple, optional
        Layouts seeded into the first population.
    """

    def __init__(self, encoding, *, population, generations, elite, crossover, mutation, tournament, operators,
                 initial=None):
        self.encoding, self.size, self.generations = encoding, population, generations
        self.elite, self.cx, self.mut, self.tsize, self.operators = elite, crossover, mutation, tournament, operators
        self.seeded = initial or []

    def initial(self, rng, pyrng):
        layouts = [self.encoding.from_sensors(l) for l in self.seeded]
        for i, layout in enumerate(layouts):
            if not self.encoding.is_genome(list(layout)):
                raise AKFInputError(f"initial layout {i + 1} ({len(layout)} sensors: {list(self.seeded[i])}) is not a "
                                    f"layout of this search ({self.encoding.n_sensors} sensors"
                                    + (f", per type {self.encoding.budget}" if getattr(self.encoding, "budget", None)
                                       else "") + ", each a candidate once)")
        while len(layouts) < self.size:
            layouts.append(self.encoding.random_layout(rng))
        return layouts[:self.size]

    def check_genome(self, genome):
        return self.encoding.is_genome(genome)

    def next_generation(self, population, generation, rng, pyrng, evaluate):
        enc = self.encoding
        elites = [i.copy() for i in best(population, self.elite)]
        kids = [tuple(p) for p in tournament(population, len(population) - self.elite, self.tsize, pyrng)]
        for j in range(0, len(kids) - 1, 2):
            if rng.random() < self.cx:
                op = enc.crossover_set if self.operators == "set" else enc.crossover_intermediate
                kids[j], kids[j + 1] = op(kids[j], kids[j + 1], rng)
        scale = max(0.5, 0.5 * enc.span * (1 - generation / max(self.generations, 1)))
        for j in range(len(kids)):
            if rng.random() < self.mut:
                kids[j] = enc.mutate(kids[j], rng) if self.operators == "set" else enc.mutate_adaptive(kids[j], rng, scale)
        return elites + [Individual(k) for k in kids]

    def record(self, population):
        f = np.array([i.fitness.values[0] for i in population])
        return {"best": float(f.min()), "mean": float(f.mean()), "std": float(f.std()),
                "diversity": self.encoding.diversity([tuple(i) for i in population])}


def check_run_size(population: int, generations: int):
    """Refuse, before the first layout is drawn, a GA whose evaluated layouts (cached, with their
    fitness) would not fit in memory.

    Parameters
    ----------
    population, generations : int
    """
    check_memory(population * (generations + 1), 40, f"a GA of population {population} over {generations} generations",
                 "use a smaller population (the thesis used 50) or fewer generations", items="evaluated layouts")


def place(objective: Objective, encoding: CandidateSet, *, population: int = 50, generations: int = 100, elite: int = 2,
          crossover: float = 0.8, mutation: float = 0.16, tournament: int = 4, stall_generations: int = 50,
          stall_tol: float = 1e-6, operators: str = "set", seed: int = 0, n_jobs: int = 1,
          checkpoint: str | None = None, checkpoint_every: int = 5, resume: bool = False, progress: bool = False,
          hall_of_fame: int = 5, penalty: float = PENALTY, initial: list[list[str]] | None = None,
          on_generation: Callable[[dict], None] | None = None) -> PlacementResult:
    """Search a sensor layout minimising ``objective`` with a GA (TH defaults), on the engine of
    :mod:`core_akf.evolution`.

    Parameters
    ----------
    objective : object
        An objective with ``evaluate(list of layouts) -> list of floats`` (see
        :mod:`sensoropt.objective`; wrap a plain function with ``FunctionObjective``).
    encoding : CandidateSet or PlateGrid
        The candidates and the sensor count or budget.
    population, generations, elite, crossover, mutation, tournament : int or float
        GA settings (TH: 50, 100, 2, 0.8, 0.16, 4).
    stall_generations, stall_tol : int, float
        Stop when the mean fitness changed by less than ``stall_tol`` (relative) over
        ``stall_generations`` generations.
    operators : str
        "set" (set-based crossover, per-sensor move/jump/kind-flip mutation) or "thesis"
        (intermediate crossover, adaptive Gaussian mutation).
    seed : int
        Seeds the whole run, whatever ``n_jobs``.
    n_jobs : int
        joblib workers for the fitness (backend from ``joblib.parallel_config``).
    checkpoint : str, optional
        A JSON checkpoint saved every ``checkpoint_every`` generations.
    checkpoint_every : int
        Generations between checkpoints (a killed run loses at most this many).
    resume : bool
        Continue from ``checkpoint``.
    progress : bool
        A progress bar over the generations.
    hall_of_fame : int
        How many of the best layouts the result lists.
    penalty : float
        The fitness of an infeasible layout (undetectable, a failing filter, NaN).
    initial : list of list of str, optional
        Layouts (sensor lists) seeded into the first population.
    on_generation : callable, optional
        Called with each generation's logbook row (dict) as it is recorded.

    Returns
    -------
    PlacementResult

    Examples
    --------
    A short search with a user objective (the sum of the member numbers, least is best):

    >>> from core_akf.models import s17_truss
    >>> from sensoropt import FunctionObjective, make_encoding
    >>> member_sum = FunctionObjective(lambda sensors: float(sum(int(s.split(":")[1]) for s in sensors)))
    >>> res = place(member_sum, make_encoding(s17_truss(), kinds=("strain",), n_sensors=2), population=8,
    ...             generations=3, seed=1)
    >>> len(res.sensors), res.best_error <= 10, res.stopped
    (2, True, 'generations')
    """
    population, generations = as_count(population, "population", 2), as_count(generations, "generations")
    elite, tournament = as_count(elite, "elite"), as_count(tournament, "tournament", 1)
    crossover, mutation = as_probability(crossover, "crossover"), as_probability(mutation, "mutation")
    if not elite < population:
        raise AKFInputError(f"elite = {elite} must be below the population ({population}): some layouts must be new")
    if isinstance(penalty, bool) or not isinstance(penalty, (int, float)) or not (np.isfinite(penalty) and penalty > 0):
        raise AKFInputError(f"penalty must be a positive number (the fitness of an infeasible layout), got {penalty!r}")
    # every evaluated layout is kept (the cache, the checkpoint): about 40 float64 each
    check_run_size(population, generations)
    if operators not in ("set", "thesis"):
        raise AKFInputError(f"operators must be 'set' or 'thesis', got {operators!r}")
    if getattr(objective, "n_objectives", 1) != 1:
        raise AKFInputError("place() is single-objective; use sensoropt.pareto() for several objectives")
    settings = dict(population=population, generations=generations, elite=elite, crossover=crossover,
                    mutation=mutation, tournament=tournament, stall_generations=stall_generations,
                    stall_tol=stall_tol, operators=operators, seed=seed)
    algorithm = PlacementGA(encoding, population=population, generations=generations, elite=elite,
                            crossover=crossover, mutation=mutation, tournament=tournament, operators=operators,
                            initial=initial)
    evaluator = Evaluator(objective.evaluate, decode=encoding.sensors, n_jobs=n_jobs, batch=BATCH, penalty=penalty)
    res = GeneticAlgorithm(algorithm, evaluator, generations=generations, seed=seed,
                           stall_generations=stall_generations, stall_tol=stall_tol, checkpoint=checkpoint,
                           checkpoint_every=checkpoint_every, resume=resume,
                           progress="placement GA" if progress else None,
                           settings=_checkpoint_settings(settings, encoding, objective), hall_of_fame=hall_of_fame,
                           on_generation=on_generation).run()
    best_layout, (best_f,) = res.hall_of_fame[0]
    return PlacementResult(best_layout, best_f, encoding.sensors(best_layout), encoding.records(best_layout),
                           res.logbook, [(encoding.sensors(l), f[0]) for l, f in res.hall_of_fame], res.evaluations,
                           res.cache_hits, res.infeasible, res.stopped, seed, settings)


def _checkpoint_settings(settings, encoding, objective):
    """What a GA checkpoint must match to be resumed: the GA settings, the candidates and, for a
    robust or constrained fitness, its settings (absent otherwise, so earlier checkpoints resume)."""
    out = dict(settings, candidates=encoding.candidates)
    robustness = getattr(objective, "robustness", None)
    if robustness:
        out["robustness"] = robustness
    return out


def independent_runs(objective: Objective, encoding: CandidateSet, runs: int = 4, seed: int = 0,
                     **ga: Any) -> tuple[list[PlacementResult], pd.DataFrame]:
    """Several GA runs with seeds ``seed, seed + 1, ...``, and how much they agree.

    Parameters
    ----------
    objective : object
        An objective with ``evaluate(list of layouts) -> list of floats``.
    encoding : CandidateSet or PlateGrid
    runs : int
    seed : int
        The first run's seed.
    **ga
        Settings of :func:`place`.

    Returns
    -------
    results : list of PlacementResult
    agreement : pandas.DataFrame
        One row per run (best error, sensors) with ``shared_with_best`` (share of the run's
        sensors that are in the overall best layout) and ``mean_distance`` (layout distance to
        the other runs' best, in candidate spacings).

    Examples
    --------
    >>> from core_akf.models import s17_truss
    >>> from sensoropt import FunctionObjective, make_encoding
    >>> count = FunctionObjective(lambda sensors: float(len(sensors)))
    >>> results, agreement = independent_runs(count, make_encoding(s17_truss(), kinds=("strain",), n_sensors=2),
    ...                                       runs=2, population=4, generations=1)
    >>> len(results), "shared_with_best" in agreement.columns
    (2, True)
    """
    import pandas as pd

    results = [place(objective, encoding, seed=seed + r, **ga) for r in range(runs)]
    overall = min(results, key=lambda r: r.best_error)
    rows = []
    for r in results:
        others = [o for o in results if o is not r]
        rows.append({"seed": r.seed, "best_error": r.best_error, "sensors": " ".join(r.sensors),
                     "shared_with_best": len(set(r.best) & set(overall.best)) / len(r.best),
                     "mean_distance": float(np.mean([encoding.distance(r.best, o.best) for o in others])) if others else 0.0,
                     "generations": int(r.logbook["generation"].iloc[-1]), "evaluations": r.evaluations})
    return results, pd.DataFrame(rows)
