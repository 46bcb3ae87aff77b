"""Placement objectives: the thesis' strain-estimation fitness and user functions.

An objective maps a batch of layouts (each a list of sensor strings such as ``"strain:58:ex"``)
to one score per layout (a float, or a tuple for several objectives); lower is better.  The GA
only sees :meth:`evaluate`; any callable ``layout -> float`` becomes an objective through
:class:`FunctionObjective`.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Protocol

import numpy as np

from core_akf.checks import AKFInputError, ForceHistories, Forces, check_memory
from core_akf.defaults import default, resolve_modes
from core_akf.filter import FilterModel
from core_akf.filter.kernels import fixed_gain_records, steady_outputs
from core_akf.filter.riccati import RiccatiError, steady_gain
from core_akf.forcemodels import ForceModel
from core_akf.simulate import simulate
from core_akf.statespace import SubsetDetectability

from .robust import MEASURES, Uncertainty, combine

if TYPE_CHECKING:
    from core_akf.structure import Structure

    from .encoding import CandidateSet


def check_failures(survive_failures: int, failure_measure: str, n_sensors: int) -> int:
    """``survive_failures`` checked: a whole number of sensors that leaves at least one.

    Parameters
    ----------
    survive_failures : int
        Sensors a layout must survive losing.
    failure_measure : str
        How the errors with and without the losses combine (:data:`~sensoropt.robust.MEASURES`).
    n_sensors : int
        Sensors of a layout.

    Returns
    -------
    int
    """
    if isinstance(survive_failures, bool) or int(survive_failures) != survive_failures or survive_failures < 0:
        raise AKFInputError(f"survive_failures must be a whole number >= 0 (sensors a layout must survive losing), "
                            f"got {survive_failures!r}")
    if survive_failures and survive_failures >= n_sensors:
        raise AKFInputError(f"survive_failures = {survive_failures} would lose every one of the {n_sensors} sensors: "
                            f"it must be below the number of sensors")
    if failure_measure not in MEASURES:
        raise AKFInputError(f"the failure measure must be one of {', '.join(MEASURES)}, got {failure_measure!r}")
    return int(survive_failures)



def check_scenarios(structure, uncertainty, n_steps, n_candidates):
    """Refuse, before anything is simulated, model and noise draws that would not fit in memory:
    per model a true structure and its simulation over the window, per record (model x draw) the
    candidates' readings and the estimated strains of a layout.

    Parameters
    ----------
    structure : Structure
    uncertainty : Uncertainty or None
    n_steps : int
        Steps of the fitness window.
    n_candidates : int
        Candidate channels.
    """
    if uncertainty is None:
        return
    models, seeds = uncertainty.n_models, int(uncertainty.seeds)
    # a model: its matrices and modes (about 6 n^2), the simulation's states, strains and readings
    # with their intermediates (measured on the thesis plate: 8.6 MB per model against 10.8 estimated)
    per_model = 6.0 * structure.n ** 2 + n_steps * (4 * structure.n + 2 * structure.n_strain + 4 * n_candidates)
    per_record = n_steps * (n_candidates + structure.n_strain)
    check_memory(models * seeds, per_record + per_model / seeds,
                 f"[place.uncertainty]: {models} models x {seeds} noise draws of a {n_steps}-step window",
                 "draw fewer samples or seeds (8 x 3 holds the p90 well)", items="records")

class Objective(Protocol):
    """What the placement GAs minimise (:func:`~sensoropt.ga.place`, :func:`~sensoropt.pareto.pareto`):
    :class:`StrainErrorObjective`, :class:`FunctionObjective`, or any object of this shape.

    Attributes
    ----------
    n_objectives : int
        Values per layout (1 for the GA of :func:`~sensoropt.ga.place`).
    """

    n_objectives: int

    def evaluate(self, layouts: Sequence[Sequence[str]]) -> list:
        """The objective of each layout (lower is better).

        Parameters
        ----------
        layouts : sequence of sequence of str
            Layouts as sensor lists.

        Returns
        -------
        list
            One float (or tuple of ``n_objectives`` floats) per layout; ``inf`` or NaN for an
            infeasible one.
        """


class FunctionObjective:
    """A user function of a layout's sensors as an objective.

    Parameters
    ----------
    fn : callable
        ``fn(sensors) -> float`` (or a tuple of floats, one per objective; lower is better), with
        ``sensors`` a list of sensor strings.  It must be picklable for ``n_jobs > 1`` (a
        module-level function, not a lambda).
    n_objectives : int
        Values ``fn`` returns.

    Examples
    --------
    >>> count_gauges = FunctionObjective(lambda sensors: float(sum(s.startswith("strain") for s in sensors)))
    >>> count_gauges.evaluate([["strain:5", "acc:4:y"], ["strain:5", "strain:9"]])
    [1.0, 2.0]
    """

    def __init__(self, fn: Callable[[list[str]], float | tuple[float, ...]], n_objectives: int = 1):
        if not callable(fn):
            raise AKFInputError("the objective must be callable: layout (list of sensor strings) -> float")
        self.fn = fn
        self.n_objectives = int(n_objectives)

    def evaluate(self, layouts: Sequence[Sequence[str]]) -> list:
        """The objective of each layout.

        Parameters
        ----------
        layouts : sequence of sequence of str
            Layouts as sensor lists (or a result's ``layout`` records).

        Returns
        -------
        list
            ``fn`` of each layout.
        """
        from .encoding import sensor_label

        return [self.fn([sensor_label(s) for s in l]) for l in layouts]


class StrainErrorObjective:
    """TH fitness: the average RMS strain error of a steady-state AKF fed by the layout.

    Over *all* strain outputs (or ``targets``), in µε, on a short window of simulated response
    with model error and noise.  The true (full) structure is simulated once for the window with
    every admissible sensor channel (each channel with its own fixed noise draw,
    ``relative_noise`` of its RMS), so the fitness of a layout is deterministic.  The filter uses
    the structure scaled by ``stiffness_factor`` (model error), reduced to ``n_modes`` modes with
    a static correction (:class:`core_akf.filter.model.FilterModel`), the true noise variances
    plus what the dropped modes' response to the model-error noise adds at the sensors
    (:meth:`~core_akf.filter.model.FilterModel.residual_noise`, so that a reduced fitness ranks
    layouts like the full model), and runs the layouts of a batch in one call (one batched
    Riccati solve).

    Parameters
    ----------
    structure : Structure
        The true structure.
    forces : sequence of force specs
        Where the loads act.
    loads : ndarray (N, n_p)
        Force histories (N).
    dt : float
        Time step (s).
    encoding : CandidateSet or PlateGrid
        The candidates to prepare.
    window : float
        The record used (s), from the start of ``loads``.
    stiffness_factor : float
        The filter model's stiffness relative to the truth (model error).
    relative_noise : float
        Sensor noise as a fraction of each channel's RMS.
    model_error_cov, force_increment_cov : float
        Q and S levels of the filter.
    n_modes : int, "auto" or None
        Filter modes with static correction (None: the full model).  ``"auto"``:
        :func:`core_akf.defaults.band_modes`, the inner-loop rule (thesis plate at 2 kHz: 32
        modes, also when accelerometers may be placed).  Measured on the thesis plate (0.1 s
        window): the case-2 gauges 3.077 (80 modes) against 3.080 µε (full); 60 random 3-gauge
        layouts rank as on the full model with Spearman 0.957 at 32 modes (0.977 at 80), the 15
        best within 13 % (8 %) of their full-model fitness; 30 layouts of 2 gauges and an
        accelerometer (0.5 s window) with Spearman 0.999 at 32 modes.
    seed : int
        The noise draw.
    targets : sequence of str, optional
        Strain output labels (``"strain:13"``, ``"strain:58:ex"``) whose error is averaged;
        default every strain output.
    force_model : ForceModel, optional
        The filter's force model (:mod:`core_akf.forcemodels`; ``force_increment_cov`` is then
        unused): under a Matérn model accelerometer-only layouts are admissible.
    uncertainty : Uncertainty, optional
        The true structures (and noise draws) a layout is scored on, and the measure of its
        errors over them (:class:`~sensoropt.robust.Uncertainty`).  The filter stays the model
        scaled by ``stiffness_factor``; model i's truth is ``structure`` scaled by
        ``stiffness_factor / uncertainty.stiffness_factors[i]``.  A layout costs one Riccati
        solve, then every record runs through its gain (:func:`~core_akf.filter.kernels.fixed_gain_records`).
    survive_failures : int
        Score a layout also with each ``survive_failures`` of its sensors lost; a layout whose
        remaining sensors are undetectable after a loss is infeasible.
    failure_measure : {"worst", "mean", "p90", "cvar90"}
        How the error without losses and the errors after each loss combine (the worst by default).
    """

    n_objectives = 1

    def __init__(self, structure: Structure, forces: Forces, loads: ForceHistories, dt: float, encoding: CandidateSet, *,
                 window: float = default("window"), stiffness_factor: float = default("placement_stiffness_factor"),
                 relative_noise: float = default("relative_noise"), model_error_cov: float = default("model_error_cov"),
                 force_increment_cov: float = default("force_increment_cov"), n_modes: int | str | None = "auto",
                 seed: int = 0, targets: Sequence[str] | None = None, force_model: ForceModel | None = None,
                 uncertainty: Uncertainty | None = None, survive_failures: int = 0, failure_measure: str = "worst"):
        loads = np.asarray(loads, float)
        if loads.ndim != 2:
            raise AKFInputError("loads must be (N, n_forces)")
        n = int(round(window / dt))
        if not 2 <= n <= loads.shape[0]:
            raise AKFInputError(f"window {window} s must hold at least 2 steps of the {loads.shape[0] * dt:.3g} s loads")
        n_modes = n_modes if n_modes in (None, "auto") else min(int(n_modes), structure.n)
        n_modes = resolve_modes(n_modes, structure, dt, "acc" in set(encoding.type), rule="band")
        self.encoding = encoding
        self.labels = encoding.sensors(range(len(encoding.candidates)))
        self.uncertainty = uncertainty
        self.failure_measure = failure_measure
        self.survive_failures = check_failures(survive_failures, failure_measure, encoding.n_sensors)
        check_scenarios(structure, uncertainty, n, len(self.labels))
        truths = [structure] if uncertainty is None else uncertainty.truths(structure, stiffness_factor)
        sims = [simulate(t, self.labels, forces, loads[:n], dt, relative_noise=relative_noise, seed=seed) for t in truths]
        # the records: per model its own noise draw ``seed`` (as simulate's), then draws seed + 1, ...
        seeds = 1 if uncertainty is None else uncertainty.seeds
        self.Ys = np.stack([sim.measurements if j == 0 else
                            sim.clean + np.random.default_rng(seed + j).normal(size=sim.clean.shape) * sim.noise_std
                            for sim in sims for j in range(seeds)])      # (S, n, n_candidates)
        self.scenario_model = np.repeat(np.arange(len(sims)), seeds)       # (S,) the model of each record
        self.Y = self.Ys[0]                            # (n, n_candidates)
        self.var = np.mean([np.maximum(sim.noise_std, default("noise_floor")) ** 2 for sim in sims], axis=0)
        rows = None if targets is None else structure.strain_label_index(targets)
        if rows is not None and not rows:
            raise AKFInputError("targets is empty: name the strain outputs whose error to average")
        self.true_strains_of = [sim.strains for sim in sims]        # per model (n, n_strain)
        self.true_strains = sims[0].strains            # (n, n_strain)
        self.references = [t if rows is None else t[:, rows] for t in self.true_strains_of]   # per model (n, n_targets)
        self.reference = self.references[0]
        if force_model is None:
            force_model = ForceModel("random_walk", increment_cov=force_increment_cov)
        self.model = FilterModel(structure.scaled(stiffness_factor), forces, dt, n_modes, force_model=force_model)
        self.G = self.model.observation(self.labels)   # (n_candidates, n_a)
        self.H = self.model.strain_rows() if rows is None else self.model.strain_rows()[rows]
        self.Q = self.model.Q_a(model_error_cov)
        # what the dropped modes' model-error response adds to each channel (FilterModel.residual_noise):
        # with it the reduced fitness ranks layouts like the full model
        self.residual_noise = self.model.residual_noise(self.labels, model_error_cov)
        self._detectability = SubsetDetectability(structure, self.labels, self.model.forces, force_model)
        self.n_forces = len(self.model.forces)

    def detectable(self, idx: Sequence[int]) -> bool:
        """PBH test of a layout (:class:`core_akf.statespace.SubsetDetectability`).

        Parameters
        ----------
        idx : sequence of int
            Candidate indices.

        Returns
        -------
        bool
        """
        return self._detectability.detectable(idx)

    @property
    def robustness(self) -> dict | None:
        """The uncertainty and failure settings of the fitness (None without them): kept with a GA
        checkpoint, so that a resume under other settings is refused."""
        out = {}
        if self.uncertainty is not None:
            u = self.uncertainty
            out |= {"stiffness_factors": list(u.stiffness_factors), "seeds": int(u.seeds), "measure": u.measure,
                    "frequency_factors": None if u.frequency_factors is None else np.asarray(u.frequency_factors).tolist()}
        if self.survive_failures:
            out |= {"survive_failures": self.survive_failures, "failure_measure": self.failure_measure}
        return out or None

    @property
    def n_scenarios(self) -> int:
        """The records a layout is scored on: models times noise draws (1 without uncertainty)."""
        return self.Ys.shape[0]

    def evaluate(self, layouts: Sequence[Sequence[str]]) -> list[float]:
        """Average strain error per layout (with an :class:`~sensoropt.robust.Uncertainty`, its
        measure over the models and seeds; with ``survive_failures``, combined with the error
        after each loss of that many sensors).

        Parameters
        ----------
        layouts : sequence of sequence of str
            Layouts as sensor lists.

        Returns
        -------
        list of float
            µε; ``inf`` for an undetectable or failing layout (or one that becomes undetectable
            when ``survive_failures`` sensors are lost).
        """
        idx = [self.encoding.from_sensors(l) for l in layouts]
        fit = self._measure(self.errors(idx))
        if self.survive_failures:
            fit = self._with_failures(idx, fit)
        return [float(f) if np.isfinite(f) else math.inf for f in fit]

    def scenario_errors(self, sensors: Sequence[str]) -> np.ndarray:
        """The error of one layout on each record (model and noise draw) of the fitness.

        Parameters
        ----------
        sensors : sequence of str

        Returns
        -------
        ndarray (n_scenarios,)
            µε (or the objective's unit); ``inf`` where the layout fails.
        """
        return self.errors([self.encoding.from_sensors(sensors)])[0]

    def failure_errors(self, sensors: Sequence[str], lost: int = 1) -> list[tuple[list[str], float]]:
        """The fitness of a layout after each loss of ``lost`` of its sensors.

        Parameters
        ----------
        sensors : sequence of str
        lost : int
            Sensors lost at once.

        Returns
        -------
        list of (list of str, float)
            The sensors lost and the fitness of what remains (its measure over the records;
            ``inf`` where what remains is undetectable).
        """
        from itertools import combinations

        layout = self.encoding.from_sensors(sensors)
        if not 1 <= int(lost) < len(layout):
            raise AKFInputError(f"lost must be between 1 and {len(layout) - 1} for a layout of {len(layout)} sensors")
        gone = list(combinations(range(len(layout)), int(lost)))
        subs = [tuple(g for j, g in enumerate(layout) if j not in out) for out in gone]
        fit = self._measure(self.errors(subs))
        return [([self.labels[layout[j]] for j in out], float(f)) for out, f in zip(gone, fit)]

    def errors(self, idx: Sequence[Sequence[int]]) -> np.ndarray:
        """The error of each layout (candidate indices) on each record of the fitness.

        Parameters
        ----------
        idx : sequence of sequence of int
            Layouts as candidate indices.

        Returns
        -------
        ndarray (len(idx), n_scenarios)
            ``inf`` for an undetectable or failing layout.
        """
        out = np.full((len(idx), self.n_scenarios), np.inf)
        by_size = {}
        for k, i in enumerate(idx):
            if self.detectable(i):
                by_size.setdefault(len(i), []).append(k)
        for ks in by_size.values():
            self._batch([idx[k] for k in ks], ks, out)
        return out

    def _measure(self, errors):
        """One fitness per layout from its errors over the records (L, S)."""
        return errors[:, 0].copy() if self.uncertainty is None else combine(errors, self.uncertainty.measure)

    def _with_failures(self, idx, fit):
        """The fitness combined with the fitness after every loss of ``survive_failures`` sensors;
        ``inf`` when a loss leaves an undetectable set."""
        from itertools import combinations

        subs, owner = [], []
        for k, layout in enumerate(idx):
            if np.isfinite(fit[k]):
                for gone in combinations(range(len(layout)), self.survive_failures):
                    subs.append(tuple(g for j, g in enumerate(layout) if j not in gone))
                    owner.append(k)
        if not subs:
            return fit
        lost = self._measure(self.errors(subs))
        owner = np.array(owner)
        out = fit.copy()
        for k in np.unique(owner):
            out[k] = combine(np.concatenate([[fit[k]], lost[owner == k]]), self.failure_measure)
        return out

    def _batch(self, idx, ks, out):
        sel = np.array([list(i) for i in idx])
        G = self.G[sel]
        R = np.stack([np.diag(self.var[s]) + self.residual_noise[np.ix_(s, s)] for s in sel])
        try:
            if self.n_scenarios == 1:          # the thesis' fitness, as it always ran
                Y = np.ascontiguousarray(np.swapaxes(self.Y[:, sel], 0, 1))
                errors = self._score(steady_outputs(self.model.A_a, G, self.Q, R, Y, self.H), 0)[:, None]
            else:                              # one gain per layout, then every record through it
                B, n = len(sel), self.model.n_a
                A = np.broadcast_to(self.model.A_a, (B, n, n))
                _, L = steady_gain(A, G, np.broadcast_to(self.Q, (B, n, n)), R)
                X = fixed_gain_records(A, G, L, np.moveaxis(self.Ys[:, :, sel], 2, 0))    # (B, S, N, n)
                errors = np.stack([self._score(X[:, s] @ self.H.T, m) for s, m in enumerate(self.scenario_model)],
                                  axis=1)
        except RiccatiError:
            if len(idx) == 1:
                return
            for j, k in enumerate(ks):   # isolate the failing layout(s)
                self._batch([idx[j]], [k], out)
            return
        out[ks] = np.where(np.isfinite(errors), errors, np.inf)

    def _score(self, est, model=0):
        """The average RMS error (µε) of each layout's estimated outputs ``est`` (B, n, targets)
        against the truth of model ``model``."""
        err = est - self.references[model][None]
        err *= err
        return np.sqrt(err.mean(axis=1)).mean(axis=1) * 1e6


class FatigueErrorObjective(StrainErrorObjective):
    """The error of the estimated fatigue: the mean relative error (%) of the damage-equivalent
    stress range (DEL) over the target outputs, on the same window, filter and noise as
    :class:`StrainErrorObjective`.

    The filter estimates the stresses of the targets directly (``σ = W ε`` on the state,
    :func:`core_akf.fatigue.stress_operator`); the stress histories of all layouts of a batch are
    rainflow-counted together (:func:`core_akf.fatigue.rainflow`) and their DEL
    ``(Σ n_i Δσ_i^m / N)^(1/m)`` compared with the truth's.  A target with no cycle in the window is
    left out of the mean.  The DEL rather than Miner's sum: it has no cut-off, so it is defined for
    the short windows a GA can afford, and its error is the damage's error to the power 1/m.

    Parameters
    ----------
    structure, forces, loads, dt, encoding
        As :class:`StrainErrorObjective`.
    m : float
        The slope of the DEL (3 for steel details).
    youngs_modulus : float, optional
        E (Pa) for the stresses (default the model's own; a model without one needs none: a
        uniform E does not change the relative error).
    **settings
        The other settings of :class:`StrainErrorObjective` (window, stiffness_factor,
        relative_noise, model_error_cov, force_increment_cov, n_modes, seed, targets).

    Examples
    --------
    >>> from core_akf.loads import band_limited_white_noise
    >>> from core_akf.models import s17_truss
    >>> from sensoropt.encoding import CandidateSet
    >>> loads = band_limited_white_noise(2000, 1e-3, 2e3, 0.0, 50.0, seed=1)[:, None]
    >>> enc = CandidateSet(s17_truss(), candidates=["strain:13", "strain:26", "acc:8:y", "acc:4:y"], n_sensors=2)
    >>> fat = FatigueErrorObjective(s17_truss(), ["8:y"], loads, 1e-3, enc, window=1.0, force_increment_cov=1e4)
    >>> errors = fat.evaluate([["strain:13", "acc:8:y"], ["acc:4:y", "acc:8:y"]])
    >>> bool(errors[0] < 10), errors[1]       # % of the DEL; accelerometers alone are undetectable
    (True, inf)
    """

    def __init__(self, structure: Structure, forces: Forces, loads: ForceHistories, dt: float, encoding: CandidateSet, *,
                 m: float = 3.0, youngs_modulus: float | None = None, **settings: object):
        from core_akf.fatigue import equivalent_range, rainflow, relative_stress_operator

        if not (np.isfinite(m) and m > 0):
            raise AKFInputError(f"the DEL slope m must be a positive number, got {m!r}")
        super().__init__(structure, forces, loads, dt, encoding, **settings)
        targets = settings.get("targets")
        rows = list(range(structure.n_strain)) if targets is None else structure.strain_label_index(targets)
        W = relative_stress_operator(structure, rows, youngs_modulus)          # (k, n_strain)
        self.m = float(m)
        self.H = W @ self.model.strain_rows()                         # the targets' stresses on the filter state
        self.references = [t @ W.T for t in self.true_strains_of]      # per model (n, k) Pa
        self.reference = self.references[0]
        self.reference_dels = [equivalent_range(rainflow(r), self.m, 1.0) for r in self.references]
        self.reference_del = self.reference_dels[0]
        self.counted = self.reference_del > 0
        if not self.counted.any():
            raise AKFInputError("no target output has a stress cycle in the window: lengthen the window or choose "
                                "targets the loads reach")

    def _score(self, est, model=0):
        """The mean relative DEL error (%) of each layout's estimated stresses ``est`` (B, n, k)
        against the truth of model ``model`` (over the targets with a cycle in its window)."""
        from core_akf.fatigue import equivalent_range, rainflow

        B, n, k = est.shape
        dels = equivalent_range(rainflow(np.swapaxes(est, 0, 1).reshape(n, B * k)), self.m, 1.0).reshape(B, k)
        counted = self.reference_dels[model] > 0
        rel = np.abs(dels[:, counted] / self.reference_dels[model][counted] - 1.0)
        return 100.0 * rel.mean(axis=1)
