"""The placement GA on DEAP (TH §4): elitist generational GA with tournament selection,
set-based crossover and per-sensor mutations (or the thesis' intermediate crossover and adaptive
mutation), a fitness cache, parallel batched evaluation, checkpoints and a logbook.

Reproducibility: all randomness comes from one ``numpy.random.Generator`` seeded by ``seed`` (and
DEAP's tournament from the ``random`` module, seeded from it and restored afterwards); fitness
batches have a fixed composition whatever the number of workers, so one seed gives a
bit-identical run on 1 or many workers, and a resumed run continues exactly.
"""
from __future__ import annotations

import copy
import math
import os
import pickle
import random
import time
from dataclasses import dataclass, field

import numpy as np

from core_akf.exceptions import AKFInputError
from core_akf.outputs import atomic_path

#: layouts per fitness batch (fixed: the batch composition must not depend on n_jobs)
BATCH = 10
#: fitness of an infeasible layout (undetectable, failing filter, NaN from a user objective)
PENALTY = 100.0

THESIS = dict(population=50, generations=100, elite=2, crossover=0.8, mutation=0.16, tournament=4,
              stall_generations=50, stall_tol=1e-6)


def _creator():
    """DEAP creator classes, made once per process; individuals never leave this process
    (workers get plain lists of sensor strings)."""
    from deap import base, creator

    if not hasattr(creator, "PlacementFitness"):
        creator.create("PlacementFitness", base.Fitness, weights=(-1.0,))
        creator.create("PlacementIndividual", list, fitness=creator.PlacementFitness)
    return creator


def _evaluate_chunk(objective, layouts):
    return objective.evaluate(layouts)


class Evaluator:
    """Cached, batched, optionally parallel evaluation of layouts (canonical tuples)."""

    def __init__(self, objective, encoding, n_jobs=1, penalty=PENALTY, batch=BATCH):
        self.objective, self.encoding = objective, encoding
        self.n_jobs, self.penalty, self.batch = n_jobs, float(penalty), int(batch)
        self.cache = {}
        self.evaluations = self.hits = self.infeasible = 0

    def _clean(self, v):
        try:
            v = float(v)
        except (TypeError, ValueError):
            return None
        return v if math.isfinite(v) else None

    def __call__(self, layouts):
        from joblib import Parallel, delayed

        new = list(dict.fromkeys(l for l in layouts if l not in self.cache))
        self.hits += len(layouts) - len(new)      # cached, or repeated within this request
        if new:
            sensors = [self.encoding.sensors(l) for l in new]
            chunks = [sensors[i:i + self.batch] for i in range(0, len(sensors), self.batch)]
            if self.n_jobs == 1 or len(chunks) == 1:
                parts = [self.objective.evaluate(c) for c in chunks]
            else:
                parts = Parallel(n_jobs=self.n_jobs)(delayed(_evaluate_chunk)(self.objective, c) for c in chunks)
            values = [v for p in parts for v in p]
            if len(values) != len(new):
                raise AKFInputError(f"the objective returned {len(values)} values for {len(new)} layouts")
            for l, v in zip(new, values):
                clean = self._clean(v)
                if clean is None:
                    self.infeasible += 1
                    clean = self.penalty
                self.cache[l] = clean
            self.evaluations += len(new)
        return [self.cache[l] for l in layouts]


@dataclass
class PlacementResult:
    """Outcome of :func:`place`.

    best : canonical layout;  best_error : its fitness
    sensors : sensor strings;  layout : ``[{"node", "kind"}]`` (1-based node ids)
    logbook : DataFrame per generation: best, mean, std, diversity, evaluations, cache_hits,
        infeasible, seconds
    hall_of_fame : list of (sensors, fitness), best first
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


def place(objective, encoding, *, population=50, generations=100, elite=2, crossover=0.8, mutation=0.16,
          tournament=4, stall_generations=50, stall_tol=1e-6, operators="set", seed=0, n_jobs=1,
          checkpoint=None, checkpoint_every=5, resume=False, progress=False, hall_of_fame=5, penalty=PENALTY,
          initial=None):
    """Search a sensor layout minimising ``objective`` with a GA (TH defaults).

    Parameters
    ----------
    objective : an objective with ``evaluate(list of layouts) -> list of floats`` (see
        :mod:`sensoropt.objective`; wrap a plain function with ``FunctionObjective``)
    encoding : :class:`~sensoropt.encoding.Encoding` -- candidates, sensor count / budget
    population, generations, elite, crossover, mutation, tournament : GA settings
    stall_generations, stall_tol : stop when the mean fitness changed by less than
        ``stall_tol`` (relative) over that many generations
    operators : "set" (set-based crossover, per-sensor move/jump/kind-flip mutation) or
        "thesis" (intermediate crossover, adaptive Gaussian mutation)
    seed : int -- the whole run, whatever ``n_jobs``
    n_jobs : joblib workers for the fitness (backend from ``joblib.parallel_config``)
    checkpoint : path -- saved every ``checkpoint_every`` generations; ``resume=True`` continues
        from it (a killed run loses at most ``checkpoint_every`` generations)
    initial : optional layouts (sensor lists) seeded into the first population

    Returns
    -------
    :class:`PlacementResult`
    """
    import pandas as pd
    from deap import tools

    if population < 2 or generations < 0 or not 0 <= elite < population:
        raise AKFInputError("need population >= 2, generations >= 0 and 0 <= elite < population")
    if operators not in ("set", "thesis"):
        raise AKFInputError(f"operators must be 'set' or 'thesis', got {operators!r}")
    if getattr(objective, "n_objectives", 1) != 1:
        raise AKFInputError("place() is single-objective; use sensoropt.pareto() for several objectives")
    creator = _creator()
    settings = dict(population=population, generations=generations, elite=elite, crossover=crossover,
                    mutation=mutation, tournament=tournament, stall_generations=stall_generations,
                    stall_tol=stall_tol, operators=operators, seed=seed)
    evaluate = Evaluator(objective, encoding, n_jobs=n_jobs, penalty=penalty)
    if checkpoint and not resume and os.path.exists(checkpoint):
        raise AKFInputError(f"a checkpoint of an earlier run exists at {checkpoint!r}; pass resume=True (CLI: --resume) "
                            "to continue it, or remove it / choose another output folder to start afresh")
    state = random.getstate()
    try:
        if resume:
            ck = load_checkpoint(checkpoint)
            if ck["settings"] != settings or ck["candidates"] != encoding.candidates:
                raise AKFInputError("the checkpoint was written by a run with other settings or candidates")
            rng = ck["rng"]
            random.setstate(ck["random"])
            pop = [creator.PlacementIndividual(l) for l in ck["population"]]
            for ind, f in zip(pop, ck["fitness"]):
                ind.fitness.values = (f,)
            rows, hof_store, start = ck["rows"], ck["hof"], ck["generation"] + 1
            evaluate.cache, evaluate.evaluations = ck["cache"], ck["evaluations"]
            evaluate.hits, evaluate.infeasible = ck["hits"], ck["infeasible"]
            t_offset = rows[-1]["seconds"] if rows else 0.0
        else:
            rng = np.random.default_rng(seed)
            random.seed(int(rng.integers(2 ** 31)))
            layouts = [encoding.from_sensors(l) for l in (initial or [])]
            while len(layouts) < population:
                layouts.append(encoding.random_layout(rng))
            pop = [creator.PlacementIndividual(l) for l in layouts[:population]]
            rows, hof_store, start, t_offset = [], {}, 0, 0.0
        t0 = time.perf_counter() - t_offset
        bar = None
        if progress:
            from tqdm.auto import tqdm
            bar = tqdm(total=generations, initial=max(start - 1, 0), desc="placement GA", unit="gen", leave=False)
        stopped = "generations"
        for gen in range(start, generations + 1):
            if gen > 0:
                elites = [copy.deepcopy(i) for i in tools.selBest(pop, elite)]
                parents = tools.selTournament(pop, len(pop) - elite, tournsize=tournament)
                kids = [tuple(p) for p in parents]
                for j in range(0, len(kids) - 1, 2):
                    if rng.random() < crossover:
                        op = encoding.crossover_set if operators == "set" else encoding.crossover_intermediate
                        kids[j], kids[j + 1] = op(kids[j], kids[j + 1], rng)
                scale = max(0.5, 0.5 * max(encoding.nx, encoding.ny) * (1 - gen / max(generations, 1)))
                for j in range(len(kids)):
                    if rng.random() < mutation:
                        kids[j] = (encoding.mutate(kids[j], rng) if operators == "set"
                                   else encoding.mutate_adaptive(kids[j], rng, scale))
                pop = elites + [creator.PlacementIndividual(k) for k in kids]
            todo = [ind for ind in pop if not ind.fitness.valid]
            for ind, f in zip(todo, evaluate([tuple(i) for i in todo])):
                ind.fitness.values = (f,)
            fits = np.array([i.fitness.values[0] for i in pop])
            for ind in pop:
                hof_store.setdefault(tuple(ind), ind.fitness.values[0])
            rows.append({"generation": gen, "best": float(fits.min()), "mean": float(fits.mean()),
                         "std": float(fits.std()), "diversity": encoding.diversity([tuple(i) for i in pop]),
                         "evaluations": evaluate.evaluations, "cache_hits": evaluate.hits,
                         "infeasible": evaluate.infeasible, "seconds": time.perf_counter() - t0})
            if bar is not None and gen > 0:
                bar.update(1)
            if checkpoint and (gen % checkpoint_every == 0 or gen == generations):
                _save(checkpoint, dict(settings=settings, candidates=encoding.candidates, rng=rng,
                                       random=random.getstate(), population=[list(i) for i in pop],
                                       fitness=[i.fitness.values[0] for i in pop], rows=rows, hof=hof_store,
                                       generation=gen, cache=evaluate.cache, evaluations=evaluate.evaluations,
                                       hits=evaluate.hits, infeasible=evaluate.infeasible))
            if gen >= stall_generations > 0:
                old = rows[gen - stall_generations]["mean"]
                if abs(rows[gen]["mean"] - old) <= stall_tol * max(abs(old), 1e-300):
                    stopped = f"stall: mean fitness changed < {stall_tol:g} over {stall_generations} generations"
                    break
        if bar is not None:
            bar.close()
    finally:
        random.setstate(state)
    ranked = sorted(hof_store.items(), key=lambda kv: (kv[1], kv[0]))
    best, best_f = ranked[0]
    return PlacementResult(best, best_f, encoding.sensors(best), encoding.records(best), pd.DataFrame(rows),
                           [(encoding.sensors(l), f) for l, f in ranked[:hall_of_fame]], evaluate.evaluations,
                           evaluate.hits, evaluate.infeasible, stopped, seed, settings)


#: identifies a placement checkpoint and its layout; a file with another tag or version is refused
CHECKPOINT_FORMAT = ("akf-toolkit placement checkpoint", 1)


def _save(path, data):
    """Write a checkpoint atomically; the previous one is kept as ``PATH.bak``."""
    with atomic_path(path) as tmp:          # a kill mid-write leaves the previous checkpoint
        with open(tmp, "wb") as fh:
            pickle.dump(dict(data, format=CHECKPOINT_FORMAT), fh, protocol=pickle.HIGHEST_PROTOCOL)
        if os.path.exists(path):
            os.replace(path, f"{path}.bak")


def load_checkpoint(path):
    """Read and check a checkpoint written by :func:`place`; a missing, truncated or foreign file
    is an :class:`AKFInputError` that names the backup to use instead.

    Checkpoints are pickles: load only files your own runs wrote."""
    if not path or not os.path.exists(path):
        raise AKFInputError(f"no checkpoint to resume from at {path!r}")
    backup = f" (the previous checkpoint is kept at {path}.bak: rename it to {os.path.basename(path)} to resume from it)" \
        if os.path.exists(f"{path}.bak") else ""
    try:
        with open(path, "rb") as fh:
            ck = pickle.load(fh)
    except (pickle.UnpicklingError, EOFError, AttributeError, ImportError, IndexError, TypeError, ValueError) as exc:
        raise AKFInputError(f"checkpoint {path!r} is truncated or not a placement checkpoint "
                            f"({type(exc).__name__}: {exc}){backup}") from None
    if not isinstance(ck, dict) or ck.get("format") != CHECKPOINT_FORMAT:
        found = ck.get("format") if isinstance(ck, dict) else type(ck).__name__
        raise AKFInputError(f"{path!r} is not a placement checkpoint of this version (found {found!r}, "
                            f"expected {CHECKPOINT_FORMAT!r}){backup}")
    return ck


def independent_runs(objective, encoding, runs=4, seed=0, **ga):
    """``runs`` GA runs with seeds ``seed, seed + 1, ...``; returns ``(results, agreement)``
    where ``agreement`` is a DataFrame with one row per run (best error, sensors) and columns
    ``shared_with_best`` (share of the run's sensors that are in the overall best layout) and
    ``mean_distance`` (layout distance to the other runs' best, grid units)."""
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
