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

from core_akf.checks import AKFInputError, ForceHistories, Forces
from core_akf.defaults import default, resolve_modes
from core_akf.filter import FilterModel
from core_akf.filter.kernels import steady_outputs
from core_akf.filter.riccati import RiccatiError
from core_akf.forcemodels import ForceModel
from core_akf.simulate import simulate
from core_akf.statespace import SubsetDetectability

if TYPE_CHECKING:
    from core_akf.structure import Structure

    from .encoding import CandidateSet


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
        modes when only strain gauges are placed, 101 when accelerometers may be: they see higher
        modes).  Measured on the thesis plate (0.1 s window): the case-2 gauges 3.077 (80 modes)
        against 3.080 µε (full); the case-3 layout with its accelerometer 4.448 (100 modes) and
        4.869 (80) against 4.506 µε (full) before the dropped modes' noise was added to R; with it,
        60 random 3-gauge layouts rank as on the full model with Spearman 0.957 at 32 modes (0.977
        at 80), the 15 best within 13 % (8 %) of their full-model fitness.
    seed : int
        The noise draw.
    targets : sequence of str, optional
        Strain output labels (``"strain:13"``, ``"strain:58:ex"``) whose error is averaged;
        default every strain output.
    force_model : ForceModel, optional
        The filter's force model (:mod:`core_akf.forcemodels`; ``force_increment_cov`` is then
        unused): under a Matérn model accelerometer-only layouts are admissible.
    """

    n_objectives = 1

    def __init__(self, structure: Structure, forces: Forces, loads: ForceHistories, dt: float, encoding: CandidateSet, *,
                 window: float = default("window"), stiffness_factor: float = default("placement_stiffness_factor"),
                 relative_noise: float = default("relative_noise"), model_error_cov: float = default("model_error_cov"),
                 force_increment_cov: float = default("force_increment_cov"), n_modes: int | str | None = "auto",
                 seed: int = 0, targets: Sequence[str] | None = None, force_model: ForceModel | None = None):
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
        sim = simulate(structure, self.labels, forces, loads[:n], dt, relative_noise=relative_noise, seed=seed)
        self.Y = sim.measurements                      # (n, n_candidates)
        self.var = np.maximum(sim.noise_std, default("noise_floor")) ** 2
        rows = None if targets is None else structure.strain_label_index(targets)
        if rows is not None and not rows:
            raise AKFInputError("targets is empty: name the strain outputs whose error to average")
        self.true_strains = sim.strains                # (n, n_strain)
        self.reference = sim.strains if rows is None else sim.strains[:, rows]    # (n, n_targets)
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

    def evaluate(self, layouts: Sequence[Sequence[str]]) -> list[float]:
        """Average strain error per layout.

        Parameters
        ----------
        layouts : sequence of sequence of str
            Layouts as sensor lists.

        Returns
        -------
        list of float
            µε; ``inf`` for an undetectable or failing layout.
        """
        idx = [self.encoding.from_sensors(l) for l in layouts]
        out = [math.inf] * len(idx)
        by_size = {}
        for k, i in enumerate(idx):
            if self.detectable(i):
                by_size.setdefault(len(i), []).append(k)
        for ks in by_size.values():
            self._batch([idx[k] for k in ks], ks, out)
        return out

    def _batch(self, idx, ks, out):
        sel = np.array([list(i) for i in idx])
        G = self.G[sel]
        R = np.stack([np.diag(self.var[s]) + self.residual_noise[np.ix_(s, s)] for s in sel])
        Y = np.ascontiguousarray(np.swapaxes(self.Y[:, sel], 0, 1))
        try:
            est = steady_outputs(self.model.A_a, G, self.Q, R, Y, self.H)
        except RiccatiError:
            if len(idx) == 1:
                return
            for j, k in enumerate(ks):   # isolate the failing layout(s)
                self._batch([idx[j]], [k], out)
            return
        for k, e in zip(ks, self._score(est)):
            out[k] = float(e) if np.isfinite(e) else math.inf

    def _score(self, est):
        """The average RMS error (µε) of each layout's estimated outputs ``est`` (B, n, targets)."""
        return np.sqrt(np.mean((est - self.reference[None]) ** 2, axis=1)).mean(axis=1) * 1e6


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
        self.reference = self.true_strains @ W.T                      # (n, k) Pa
        self.reference_del = equivalent_range(rainflow(self.reference), self.m, 1.0)
        self.counted = self.reference_del > 0
        if not self.counted.any():
            raise AKFInputError("no target output has a stress cycle in the window: lengthen the window or choose "
                                "targets the loads reach")

    def _score(self, est):
        """The mean relative DEL error (%) of each layout's estimated stresses ``est`` (B, n, k)."""
        from core_akf.fatigue import equivalent_range, rainflow

        B, n, k = est.shape
        dels = equivalent_range(rainflow(np.swapaxes(est, 0, 1).reshape(n, B * k)), self.m, 1.0).reshape(B, k)
        rel = np.abs(dels[:, self.counted] / self.reference_del[self.counted] - 1.0)
        return 100.0 * rel.mean(axis=1)
