"""One genetic-algorithm engine for every optimiser of the toolkit.

The engine owns what every GA here needs and nothing problem-specific: the generation loop, the
stop after stalled generations, the logbook, the hall of fame, checkpoints in a safe format (JSON,
no pickles) with resume, seeded random streams that never touch Python's global ``random`` state,
cached and batched (optionally parallel) fitness evaluation, and a progress bar.  An algorithm is a
configuration (pymoo style): how the first population is made and how one generation turns into
the next (:class:`Algorithm`), handed to :class:`GeneticAlgorithm`.  Sensor placement
(``sensoropt.ga``), the Pareto front (``sensoropt.pareto``) and covariance tuning
(``impactloc.tuning``) are such configurations.

Reproducibility: all randomness comes from one :class:`numpy.random.Generator` and one private
:class:`random.Random` (for operators written for Python's random module), both seeded from
``seed`` and saved in checkpoints.  Fitness batches have a fixed composition whatever the number
of workers, so a seed gives a bit-identical run on 1 or many joblib workers and on any joblib
backend (loky, threads, dask), and a resumed run continues exactly.
"""
from __future__ import annotations

import json
import math
import os
import random
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from .checks import AKFInputError, as_count, is_real
from .outputs import atomic_path

#: identifies a checkpoint of this engine; a file with another tag or version is refused
CHECKPOINT_FORMAT = ["akf-toolkit GA checkpoint", 3]
#: a generation with more individuals to evaluate than this shows its own progress (in slices)
PROGRESS_FROM = 2000


class Individual(list):
    """A genome (a list of genes) with its fitness.

    The fitness is a :class:`deap.base.Fitness`, so DEAP's selection tools (``selNSGA2``,
    ``sortNondominated``) work on populations of them.

    Parameters
    ----------
    genes : iterable
        The genes.
    fitness : tuple of float, optional
        The fitness values if known (lower is better in every objective); ``fitness.values`` once
        evaluated.
    """

    weights = (-1.0,)

    def __init__(self, genes=(), fitness=None):
        super().__init__(genes)
        self.fitness = _fitness_class(len(self.weights))()
        if fitness is not None:
            self.fitness.values = tuple(fitness)

    def key(self):
        """A hashable key of the genome (cache and hall of fame).

        Returns
        -------
        tuple
        """
        return tuple(self)

    def copy(self):
        """A copy with the same genes and fitness.

        Returns
        -------
        Individual
        """
        return type(self)(self, self.fitness.values if self.fitness.valid else None)


_FITNESS = {}


def _fitness_class(n_objectives):
    """A DEAP Fitness class minimising ``n_objectives`` objectives (made without DEAP's global
    ``creator`` registry)."""
    if n_objectives not in _FITNESS:
        from deap import base

        _FITNESS[n_objectives] = type(f"Minimise{n_objectives}", (base.Fitness,), {"weights": (-1.0,) * n_objectives})
    return _FITNESS[n_objectives]


def individual_class(n_objectives):
    """The :class:`Individual` class for a number of objectives.

    Parameters
    ----------
    n_objectives : int
        Objectives, each minimised.

    Returns
    -------
    type
        A subclass of :class:`Individual` (one per number of objectives, made once).
    """
    if n_objectives == 1:
        return Individual
    return type(f"Individual{n_objectives}", (Individual,), {"weights": (-1.0,) * n_objectives})


# ------------------------------------------------------------------------------- evaluation
class Evaluator:
    """Cached, batched, optionally parallel fitness evaluation.

    Batches have a fixed composition, whatever ``n_jobs``, so a run gives the same results on
    any number of workers.

    Parameters
    ----------
    evaluate_batch : callable
        ``evaluate_batch(items) -> list of fitness``: evaluates a list of decoded genomes (one
        joblib task per batch).
    decode : callable, optional
        ``decode(key)`` turns a genome key into what ``evaluate_batch`` takes (default: the key).
    n_jobs : int
        joblib workers (1: in this process; -1: all cores).
    batch : int
        Genomes per task.
    penalty : float
        The fitness given to a genome whose fitness is not a finite number (or tuple of them),
        counted as infeasible.
    n_objectives : int
        Objectives per fitness.
    infeasible_if : callable, optional
        ``infeasible_if(fitness) -> bool``: a fitness to replace by ``penalty`` as well.
    """

    def __init__(self, evaluate_batch, *, decode=None, n_jobs=1, batch=10, penalty=math.inf, n_objectives=1,
                 infeasible_if=None):
        self.evaluate_batch, self.decode = evaluate_batch, decode or list
        self.infeasible_if = infeasible_if
        self.n_jobs, self.batch, self.penalty = n_jobs, int(batch), penalty
        self.n_objectives = int(n_objectives)
        self.cache = {}
        self.evaluations = self.hits = self.infeasible = 0

    def _clean(self, value):
        vals = value if isinstance(value, (tuple, list)) else (value,)
        try:
            vals = tuple(float(v) for v in vals)
        except (TypeError, ValueError):
            return None
        if len(vals) != self.n_objectives or not all(math.isfinite(v) for v in vals):
            return None
        return vals

    def __call__(self, keys):
        """Fitness tuples for genome keys (cached ones are not evaluated again)."""
        from .tasks import run_tasks

        new = list(dict.fromkeys(k for k in keys if k not in self.cache))
        self.hits += len(keys) - len(new)      # cached, or repeated within this request
        if new:
            items = [self.decode(k) for k in new]
            chunks = [items[i:i + self.batch] for i in range(0, len(items), self.batch)]
            parts = run_tasks(self.evaluate_batch, chunks, self.n_jobs)
            values = [v for p in parts for v in p]
            if len(values) != len(new):
                raise AKFInputError(f"the objective returned {len(values)} values for {len(new)} candidates")
            for k, v in zip(new, values):
                clean = self._clean(v)
                if clean is None:
                    self.infeasible += 1
                    clean = (self.penalty,) * self.n_objectives
                elif self.infeasible_if is not None and self.infeasible_if(clean):
                    self.infeasible += 1
                self.cache[k] = clean
            self.evaluations += len(new)
        return [self.cache[k] for k in keys]


# ---------------------------------------------------------------------------------- algorithm
class Algorithm:
    """What makes one GA differ from another: override :meth:`initial` and :meth:`next_generation`
    (and :meth:`record` for extra logbook columns).  ``rng`` is a numpy Generator and ``pyrng`` a
    private :class:`random.Random`, both owned and checkpointed by the engine."""

    #: the individual class (number of objectives)
    individual = Individual

    def initial(self, rng, pyrng):
        """The first population.

        Parameters
        ----------
        rng : numpy.random.Generator
            The run's generator (owned and checkpointed by the engine).
        pyrng : random.Random
            A private :class:`random.Random` for DEAP-style operators.

        Returns
        -------
        list of list
            Genomes (lists of genes).
        """
        raise NotImplementedError

    def check_genome(self, genome):
        """Whether a genome read back from a checkpoint is one this algorithm makes (default: any
        list of finite numbers); a resumed run refuses a checkpoint with one that is not.

        Parameters
        ----------
        genome : list
            Genes as stored in the checkpoint.

        Returns
        -------
        bool
        """
        return isinstance(genome, list) and all(isinstance(g, (int, float)) and not isinstance(g, bool)
                                                and math.isfinite(g) for g in genome)

    def after_initial(self, population):
        """The first population once evaluated (e.g. NSGA-II ranks it).

        Parameters
        ----------
        population : list of Individual
            The evaluated first population.

        Returns
        -------
        list of Individual
            Unchanged by default.
        """
        return population

    def next_generation(self, population, generation, rng, pyrng, evaluate):
        """The next population from the evaluated one.

        Parameters
        ----------
        population : list of Individual
            The evaluated population.
        generation : int
            The number of the generation to make (1-based).
        rng : numpy.random.Generator
            The run's generator.
        pyrng : random.Random
            The run's private :class:`random.Random`.
        evaluate : callable
            ``evaluate(individuals)`` gives fitness to individuals that lack it: call it on offspring
            when survival selection needs their fitness; the engine evaluates whatever is left
            unevaluated.

        Returns
        -------
        list of Individual
        """
        raise NotImplementedError

    def record(self, population):
        """Logbook columns of a generation.

        The engine adds generation, evaluations, cache hits, infeasible and seconds.

        Parameters
        ----------
        population : list of Individual
            The evaluated population.

        Returns
        -------
        dict
            Default: ``best``, ``mean`` and ``std`` of the first objective.
        """
        f = np.array([i.fitness.values[0] for i in population])
        finite = f[np.isfinite(f)]
        return {"best": float(f.min()), "mean": float(finite.mean()) if finite.size else math.inf,
                "std": float(finite.std()) if finite.size else math.nan}


@dataclass
class GAResult:
    """Outcome of :meth:`GeneticAlgorithm.run`.

    Attributes
    ----------
    population : list of Individual
        The last population (evaluated).
    logbook : pandas.DataFrame
        One row per generation.
    hall_of_fame : list of tuple
        ``(genome key, fitness tuple)``, best first, among every genome evaluated.
    evaluations, cache_hits, infeasible : int
        Counters.
    stopped : str
        Why the run ended ("generations", "stall").
    evaluator : Evaluator
        Its ``cache`` holds every fitness computed.
    seed : int
        The run's seed.
    settings : dict
        The settings stored with the run's checkpoint.
    """

    population: list
    logbook: object
    hall_of_fame: list
    evaluations: int
    cache_hits: int
    infeasible: int
    stopped: str
    evaluator: Evaluator = None
    seed: int = 0
    settings: dict = field(default_factory=dict)


class GeneticAlgorithm:
    """The generation loop.

    Parameters
    ----------
    algorithm : Algorithm
        The configuration (initial population, one generation).
    evaluator : Evaluator
    generations : int
        Generations after the initial one.
    seed : int
        Seeds the whole run, whatever the number of workers.
    stall_generations : int
        Stop when the logbook's ``stall_column`` changed by less than ``stall_tol`` (relative)
        over this many generations (0: never).
    stall_tol : float
        See ``stall_generations``.
    stall_column : str
        The logbook column watched for a stall ("mean", "best").
    checkpoint : str, optional
        Path of a JSON checkpoint written every ``checkpoint_every`` generations (the previous
        one is kept as ``PATH.bak``).
    checkpoint_every : int
        Generations between checkpoints.
    resume : bool
        Continue from ``checkpoint``.
    settings : dict, optional
        Stored in the checkpoint; a resume with other settings is refused.
    progress : str or None
        The progress bar's label (None: no bar).
    hall_of_fame : int
        How many of the best genomes the result lists.
    on_generation : callable, optional
        Called with each generation's logbook row (a dict: ``generation``, ``best``, ...,
        ``evaluations``, ``seconds``) once it is recorded; e.g. to report the cost of generation 0.
        One that raises is reported as a :class:`RuntimeWarning` and not called again: the run goes on.
    """

    def __init__(self, algorithm, evaluator, *, generations, seed=0, stall_generations=0, stall_tol=1e-6,
                 stall_column="mean", checkpoint=None, checkpoint_every=5, resume=False, settings=None,
                 progress=None, hall_of_fame=5, on_generation=None):
        self.algorithm, self.evaluator = algorithm, evaluator
        self.generations, self.seed = as_count(generations, "generations"), as_count(seed, "seed")
        if not (is_real(stall_tol) and stall_tol >= 0):
            raise AKFInputError(f"stall_tol must be a number >= 0, got {stall_tol!r}")
        self.stall_generations, self.stall_tol, self.stall_column = (as_count(stall_generations, "stall_generations"),
                                                                     float(stall_tol), stall_column)
        if checkpoint is not None and os.path.isdir(checkpoint):
            raise AKFInputError(f"checkpoint {checkpoint} is a folder; give the checkpoint file's path")
        if on_generation is not None and not callable(on_generation):
            raise AKFInputError(f"on_generation must be a function of the generation's record, got "
                                f"{type(on_generation).__name__}")
        self.checkpoint, self.checkpoint_every, self.resume = checkpoint, as_count(checkpoint_every, "checkpoint_every",
                                                                                   1), resume
        self.settings = json.loads(json.dumps(dict(settings or {}, generations=self.generations, seed=self.seed),
                                              default=_plain))
        self.progress, self.n_hall = progress, as_count(hall_of_fame, "hall_of_fame")
        self.on_generation = on_generation

    # -- evaluation of individuals
    def _evaluate(self, individuals):
        todo = [i for i in individuals if not i.fitness.valid]
        keys = [i.key() for i in todo]
        if self.progress and len(keys) > PROGRESS_FROM:     # a large population: progress within the generation
            from tqdm.auto import tqdm

            step = max(PROGRESS_FROM // 4, -(-len(keys) // 100))
            values = []
            with tqdm(total=len(keys), desc=f"{self.progress}: evaluating", unit="individual", leave=False) as bar:
                for a in range(0, len(keys), step):
                    values += self.evaluator(keys[a:a + step])
                    bar.update(min(step, len(keys) - a))
        else:
            values = self.evaluator(keys)
        for ind, f in zip(todo, values):
            ind.fitness.values = f
            self._hof.setdefault(ind.key(), f)
        for ind in individuals:
            self._hof.setdefault(ind.key(), ind.fitness.values)
        return individuals

    def run(self):
        """Run (or resume) the GA.

        Returns
        -------
        GAResult
        """
        import pandas as pd

        alg = self.algorithm
        self._refuse_interrupted()
        rng, pyrng, pop, rows, start, t_offset = self._start()
        t0 = time.perf_counter() - t_offset
        bar = None
        if self.progress:
            from tqdm.auto import tqdm
            bar = tqdm(total=self.generations, initial=max(start - 1, 0), desc=self.progress, unit="gen", leave=False)
        stopped = "generations"
        on_generation = self.on_generation
        try:
            for gen in range(start, self.generations + 1):
                if gen == 0:
                    pop = alg.after_initial(self._evaluate(pop))
                else:
                    pop = alg.next_generation(pop, gen, rng, pyrng, self._evaluate)
                    self._evaluate(pop)
                ev = self.evaluator
                rows.append(dict(generation=gen, **alg.record(pop), evaluations=ev.evaluations, cache_hits=ev.hits,
                                 infeasible=ev.infeasible, seconds=time.perf_counter() - t0))
                if bar is not None and gen > 0:
                    bar.update(1)
                if on_generation is not None:
                    try:
                        on_generation(dict(rows[-1]))
                    except Exception as exc:  # noqa: BLE001 -- an observer must not cost the run its result
                        warnings.warn(f"on_generation failed at generation {gen} and is not called again: "
                                      f"{type(exc).__name__}: {exc}", RuntimeWarning, stacklevel=2)
                        on_generation = None
                if self.checkpoint and (gen % self.checkpoint_every == 0 or gen == self.generations):
                    self._save(pop, rows, gen, rng, pyrng)
                if self._stalled(rows, gen):
                    stopped = (f"stall: {self.stall_column} fitness changed < {self.stall_tol:g} over "
                               f"{self.stall_generations} generations")
                    break
        finally:
            if bar is not None:
                bar.close()
        if self.checkpoint and rows:
            self._save(pop, rows, rows[-1]["generation"], rng, pyrng, finished=True)
        ranked = sorted(self._hof.items(), key=lambda kv: (kv[1], kv[0]))
        ev = self.evaluator
        return GAResult(pop, pd.DataFrame(rows), ranked[:self.n_hall] if self.n_hall else ranked, ev.evaluations,
                        ev.hits, ev.infeasible, stopped, ev, self.seed, self.settings)

    def _refuse_interrupted(self):
        """Refuse to overwrite the checkpoint of an interrupted run without ``resume``."""
        if not self.checkpoint or self.resume or not os.path.exists(self.checkpoint):
            return
        try:
            earlier = load_checkpoint(self.checkpoint)
        except AKFInputError:
            earlier = {}
        if not earlier.get("finished"):      # a finished run's checkpoint is simply replaced
            done = f" (generation {earlier['generation']} of {earlier['settings'].get('generations')})" \
                if "generation" in earlier else ""
            raise AKFInputError(f"{self.checkpoint!r} holds the checkpoint of an interrupted run{done}; pass "
                                "resume=True to continue it, or remove the file to "
                                "start afresh")

    def _start(self):
        """``(rng, pyrng, population, logbook rows, first generation, seconds already spent)``: from the
        checkpoint when resuming, else a fresh seeded start."""
        Ind = self.algorithm.individual
        if not self.resume:
            rng = np.random.default_rng(self.seed)
            pyrng = random.Random(int(rng.integers(2 ** 31)))
            self._hof = {}
            return rng, pyrng, [Ind(g) for g in self.algorithm.initial(rng, pyrng)], [], 0, 0.0
        ck = load_checkpoint(self.checkpoint)
        if ck.get("settings") != self.settings:
            raise AKFInputError("the checkpoint was written by a run with other settings or candidates")
        self._check_entries(ck)
        rng = np.random.default_rng()
        rng.bit_generator.state = ck["rng"]
        pyrng = random.Random()
        pyrng.setstate(_tuples(ck["pyrng"]))
        pop = [Ind(g, f) for g, f in zip(ck["population"], ck["fitness"])]
        rows = ck["rows"]
        self._hof = {_key(k): tuple(v) for k, v in ck["hof"]}
        ev = self.evaluator
        ev.cache = {_key(k): tuple(v) for k, v in ck["cache"]}
        ev.evaluations, ev.hits, ev.infeasible = ck["evaluations"], ck["hits"], ck["infeasible"]
        return rng, pyrng, pop, rows, ck["generation"] + 1, rows[-1]["seconds"] if rows else 0.0

    def _check_entries(self, ck):
        """A checkpoint's entries, one by one, before anything is resumed from them: present, of
        their type, a generation within the run, genomes the algorithm makes, fitness of the
        objectives' number."""
        path = self.checkpoint

        def bad(what):
            return AKFInputError(f"checkpoint {path!r}: {what}; it is not resumed: start anew with resume=False and "
                                 "the file removed")

        missing = [k for k in ("generation", "rng", "pyrng", "population", "fitness", "rows", "hof", "cache",
                               "evaluations", "hits", "infeasible") if k not in ck]
        if missing:
            raise bad(f"the entries {missing} are missing")
        gen = ck["generation"]
        if not isinstance(gen, int) or isinstance(gen, bool) or not 0 <= gen <= self.generations:
            raise bad(f"generation {gen!r} is not one of this run's 0..{self.generations}")
        if not isinstance(ck["rows"], list) or len(ck["rows"]) != gen + 1 or not all(
                isinstance(r, dict) and r.get("generation") == i for i, r in enumerate(ck["rows"])):
            raise bad(f"its logbook does not hold generations 0..{gen}")
        n_obj = len(self.algorithm.individual.weights)
        for name in ("population", "hof", "cache"):
            if not isinstance(ck[name], list):
                raise bad(f"{name} is not a list")
        pairs = list(zip(ck["population"], ck["fitness"])) if isinstance(ck["fitness"], list) else []
        if not ck["population"] or len(pairs) != len(ck["population"]):
            raise bad("its population and fitness do not match one to one")
        for where, entries in (("population", pairs), ("hall of fame", ck["hof"]), ("cache", ck["cache"])):
            for i, entry in enumerate(entries):
                genome, fit = entry if isinstance(entry, (list, tuple)) and len(entry) == 2 else (None, None)
                if genome is None or not self.algorithm.check_genome(genome):
                    raise bad(f"{where} entry {i + 1} holds a genome this run cannot make: {genome!r}")
                if not isinstance(fit, list) or len(fit) != n_obj or not all(isinstance(v, (int, float)) for v in fit):
                    raise bad(f"{where} entry {i + 1} has a fitness of {fit!r}, not {n_obj} number(s)")
        for name in ("evaluations", "hits", "infeasible"):
            value = ck[name]
            if not isinstance(value, int) or isinstance(value, bool) or value < 0:
                raise bad(f"{name} = {value!r} is not a count")

    def _stalled(self, rows, gen):
        """Whether the stall column changed by less than ``stall_tol`` over ``stall_generations``."""
        if self.stall_generations <= 0 or gen < self.stall_generations:
            return False
        old, new = rows[gen - self.stall_generations][self.stall_column], rows[gen][self.stall_column]
        return abs(new - old) <= self.stall_tol * max(abs(old), 1e-300)

    def _save(self, pop, rows, gen, rng, pyrng, finished=False):
        ev = self.evaluator
        data = dict(format=CHECKPOINT_FORMAT, settings=self.settings, generation=gen, finished=finished,
                    rng=rng.bit_generator.state,
                    pyrng=pyrng.getstate(), population=[list(i) for i in pop],
                    fitness=[list(i.fitness.values) for i in pop], rows=rows,
                    hof=[[list(k), list(v)] for k, v in self._hof.items()],
                    cache=[[list(k), list(v)] for k, v in ev.cache.items()],
                    evaluations=ev.evaluations, hits=ev.hits, infeasible=ev.infeasible)
        save_checkpoint(self.checkpoint, data)


def _plain(value):
    """JSON for numpy scalars and arrays in settings and genomes (``np.int64(3)`` -> 3)."""
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def _key(genes):
    """A genome key from JSON (nested lists back to tuples)."""
    return tuple(_key(g) if isinstance(g, list) else g for g in genes)


def _tuples(x):
    """JSON lists back to the nested tuples of ``random.Random.getstate``."""
    return tuple(_tuples(v) for v in x) if isinstance(x, list) else x


# ---------------------------------------------------------------------------------- checkpoints
def save_checkpoint(path, data):
    """Write a checkpoint (JSON) atomically; the previous one is kept as ``PATH.bak``.

    Parameters
    ----------
    path : str
        The checkpoint file.
    data : dict
        JSON-serialisable contents.
    """
    body = json.dumps(data, allow_nan=True, default=_plain)
    text = body[:-1] + f', "checksum": "{_checksum(body)}"}}'        # over the rest: an edit or a cut shows
    with atomic_path(path) as tmp:          # a kill mid-write leaves the previous checkpoint
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
        if os.path.exists(path):
            os.replace(path, f"{path}.bak")


def load_checkpoint(path):
    """Read and check a checkpoint written by :class:`GeneticAlgorithm`.

    Checkpoints are JSON: loading one never runs code.

    Parameters
    ----------
    path : str
        The checkpoint file.

    Returns
    -------
    dict

    Raises
    ------
    AKFInputError
        For a missing, truncated or foreign file, naming the backup to use instead.
    """
    if not path or not os.path.exists(path):
        raise AKFInputError(f"no checkpoint to resume from at {path!r}")
    backup = f" (the previous checkpoint is kept at {path}.bak: rename it to {os.path.basename(path)} to resume from it)" \
        if os.path.exists(f"{path}.bak") else ""
    try:
        with open(path, encoding="utf-8") as fh:
            ck = json.load(fh)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise AKFInputError(f"checkpoint {path!r} is truncated or not a GA checkpoint "
                            f"({type(exc).__name__}: {exc}){backup}") from None
    if not isinstance(ck, dict) or ck.get("format") != CHECKPOINT_FORMAT:
        found = ck.get("format") if isinstance(ck, dict) else type(ck).__name__
        raise AKFInputError(f"{path!r} is not a GA checkpoint of this version (found {found!r}, "
                            f"expected {CHECKPOINT_FORMAT!r}){backup}")
    said = ck.pop("checksum", None)
    if said != _checksum(json.dumps(ck, allow_nan=True)):
        raise AKFInputError(f"checkpoint {path!r} was changed after it was written (its checksum does not match its "
                            f"contents): it is not resumed{backup}")
    return ck


def is_checkpoint(path):
    """Whether the file at ``path`` is a GA checkpoint of this toolkit (any version, intact or not).

    Parameters
    ----------
    path : str

    Returns
    -------
    bool
    """
    try:
        with open(path, encoding="utf-8") as fh:
            head = fh.read(200)
    except (OSError, UnicodeDecodeError):
        return False
    return head.startswith('{"format": ["akf-toolkit GA checkpoint"')


def _checksum(text):
    """SHA-256 of a checkpoint's JSON text."""
    import hashlib

    return hashlib.sha256(text.encode("utf-8")).hexdigest()


# ------------------------------------------------------------------------------- operators
def tournament(population, k, size, pyrng):
    """Tournament selection on the first objective (lower is better).

    The same draws as DEAP's ``selTournament``.

    Parameters
    ----------
    population : list of Individual
        Evaluated individuals.
    k : int
        Winners to select.
    size : int
        Individuals per tournament (drawn with replacement).
    pyrng : random.Random
        The random stream.

    Returns
    -------
    list of Individual
    """
    def contest():
        aspirants = [pyrng.choice(population) for _ in range(size)]
        return max(aspirants, key=lambda i: i.fitness.wvalues)     # the first best, as DEAP's max

    return [contest() for _ in range(k)]


def best(population, k):
    """The best individuals on the first objective, stable for ties (DEAP's ``selBest``).

    Parameters
    ----------
    population : list of Individual
        Evaluated individuals.
    k : int
        How many.

    Returns
    -------
    list of Individual
    """
    return sorted(population, key=lambda i: i.fitness.wvalues, reverse=True)[:k]


def blend(a, b, alpha, pyrng):
    """Blend crossover of two real genomes in place (DEAP's ``cxBlend``, with a private stream).

    Parameters
    ----------
    a, b : Individual
        The parents, changed in place into the children.
    alpha : float
        Extent of the interval beyond the parents' genes.
    pyrng : random.Random
        The random stream.

    Returns
    -------
    tuple of Individual
        ``(a, b)``.
    """
    for i, (x1, x2) in enumerate(zip(a, b)):
        gamma = (1.0 + 2.0 * alpha) * pyrng.random() - alpha
        a[i] = (1.0 - gamma) * x1 + gamma * x2
        b[i] = gamma * x1 + (1.0 - gamma) * x2
    return a, b


def gaussian(ind, sigma, indpb, pyrng, mu=0.0):
    """Gaussian mutation of a real genome in place (DEAP's ``mutGaussian``, private stream).

    Parameters
    ----------
    ind : Individual
        The genome, changed in place.
    sigma : float
        Standard deviation of the change of a gene.
    indpb : float
        Probability that a gene changes.
    pyrng : random.Random
        The random stream.
    mu : float
        Mean of the change of a gene.

    Returns
    -------
    tuple of Individual
        ``(ind,)``.
    """
    for i in range(len(ind)):
        if pyrng.random() < indpb:
            ind[i] += pyrng.gauss(mu, sigma)
    return ind


def tournament_dcd(population, k, pyrng):
    """NSGA-II binary tournament on dominance and crowding distance.

    DEAP's ``selTournamentDCD``, with a private random stream.

    Parameters
    ----------
    population : list of Individual
        Individuals carrying the crowding distances of ``deap.tools.selNSGA2``.
    k : int
        Individuals to select.
    pyrng : random.Random
        The random stream.

    Returns
    -------
    list of Individual
    """
    if len(population) % 4 != 0:
        raise AKFInputError("the NSGA-II tournament needs a population size that is a multiple of 4")

    def duel(a, b):
        if a.fitness.dominates(b.fitness):
            return a
        if b.fitness.dominates(a.fitness):
            return b
        if a.fitness.crowding_dist < b.fitness.crowding_dist:
            return b
        if a.fitness.crowding_dist > b.fitness.crowding_dist:
            return a
        return a if pyrng.random() <= 0.5 else b

    p1 = pyrng.sample(population, len(population))
    p2 = pyrng.sample(population, len(population))
    chosen = []
    for i in range(0, k, 4):
        chosen.append(duel(p1[i], p1[i + 1]))
        chosen.append(duel(p1[i + 2], p1[i + 3]))
        chosen.append(duel(p2[i], p2[i + 1]))
        chosen.append(duel(p2[i + 2], p2[i + 3]))
    return chosen
