"""Placement problems: the structure, its loads, what may be placed, and the full-record check.
(The built-in thesis problems are job files of the application layer: ``akf.examples``.)"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from core_akf.checks import AKFInputError
from core_akf.defaults import default, resolve_modes
from core_akf.filter import FilterModel
from core_akf.filter.kernels import steady_outputs
from core_akf.forcemodels import ForceModel
from core_akf.metrics import average_strain_error
from core_akf.sensors import sees_accelerations
from core_akf.simulate import simulate

from .constraints import Constrained
from .encoding import CandidateSet, make_encoding
from .objective import FatigueErrorObjective, StrainErrorObjective

if TYPE_CHECKING:
    from core_akf.structure import Structure


@dataclass
class PlacementProblem:
    """A placement problem: a structure, its loads, what to place and the filter settings.

    :meth:`objective` builds the GA fitness on the first ``window`` seconds;
    :meth:`full_record_error` checks a layout on the whole record.

    Parameters
    ----------
    name : str
    structure : Structure
        The true structure.
    forces : list of str
        Force locations ("121:w").
    loads : ndarray (N, n_p)
        Force histories of the full record (N).
    dt : float
        Time step (s).
    kinds : tuple of str, optional
        Kinds that may be placed (default: a plate's strain components, or strain gauges on
        every strain output); see :func:`~sensoropt.encoding.make_encoding`.
    n_sensors : int, optional
        Total number of sensors (or ``budget``).
    budget : dict, optional
        Sensors per type, e.g. ``{"strain": 2, "acc": 1}``.
    window : float
        Simulated response per fitness evaluation (s).
    stiffness_factor : float
        The filter model's stiffness relative to the truth (model error).
    relative_noise : float
        Sensor noise as a fraction of each channel's RMS.
    model_error_cov, force_increment_cov : float
        Q and S levels of the filter.
    n_modes : int, "auto" or None
        Filter modes with static correction.  ``"auto"``: :func:`core_akf.defaults.band_modes` for
        the fitness, :func:`core_akf.defaults.auto_modes` for :meth:`full_record_error`.
    seed : int
        The noise draw.
    reference_layouts : dict
        Name -> sensor list, layouts to compare the GA's with.
    candidates : list of str, optional
        The candidate set itself (instead of ``kinds``).
    targets : list of str, optional
        Strain output labels whose error is averaged (default all).
    objective_kind : {"strain", "fatigue"}
        What the GA minimises: the average strain error (the thesis' fitness,
        :class:`~sensoropt.objective.StrainErrorObjective`) or the mean relative error of the
        damage-equivalent stress range of the targets
        (:class:`~sensoropt.objective.FatigueErrorObjective`).
    del_slope : float
        The slope m of that damage-equivalent range.
    force_model : ForceModel, optional
        The filter's force model (default the random walk of ``force_increment_cov``); under a
        Matérn model accelerometer-only layouts are admissible.
    uncertainty : Uncertainty, optional
        True structures unlike the filter's model that the fitness scores a layout on
        (:class:`~sensoropt.robust.Uncertainty`).
    survive_failures : int
        Sensors a layout must survive losing (its fitness includes the error after each loss).
    failure_measure : str
        How the errors with and without a loss combine ("worst" by default).
    constraints : Constraints, optional
        Costs, a budget, forbidden regions, a minimum spacing
        (:class:`~sensoropt.constraints.Constraints`).
    notes : list of str
        Notes for the user (a default S far from the loads' increments).

    Examples
    --------
    Two sensors for a random load at joint 8 of the S17 truss:

    >>> from core_akf.loads import band_limited_white_noise
    >>> from core_akf.models import s17_truss
    >>> loads = band_limited_white_noise(2000, 1e-3, 100.0, 0.0, 100.0, seed=1)[:, None]
    >>> problem = PlacementProblem("truss", s17_truss(), ["8:y"], loads, 1e-3, kinds=("strain", "acc"), n_sensors=2,
    ...                            window=0.2, force_increment_cov=1e2)
    >>> errors = problem.objective().evaluate([["strain:13", "acc:8:y"], ["acc:4:y", "acc:8:y"]])
    >>> [round(e, 3) for e in errors]        # µε; accelerometers alone are undetectable
    [0.125, inf]
    """

    name: str
    structure: object
    forces: list
    loads: np.ndarray
    dt: float
    kinds: tuple = None
    n_sensors: int = None
    budget: dict = None
    window: float = default("window")
    stiffness_factor: float = default("placement_stiffness_factor")
    relative_noise: float = default("relative_noise")
    model_error_cov: float = default("model_error_cov")
    force_increment_cov: float = default("force_increment_cov")
    n_modes: object = "auto"
    seed: int = 0
    reference_layouts: dict = field(default_factory=dict)
    candidates: list = None
    targets: list = None
    objective_kind: str = "strain"
    del_slope: float = 3.0
    force_model: object = None
    uncertainty: object = None
    survive_failures: int = 0
    failure_measure: str = "worst"
    constraints: object = None
    #: what a user should know about the settings (shown with the result)
    notes: list = field(default_factory=list)

    def encoding(self) -> CandidateSet:
        """The candidate set of the problem (:func:`~sensoropt.encoding.make_encoding`).

        Returns
        -------
        CandidateSet or PlateGrid
        """
        enc = make_encoding(self.structure, kinds=self.kinds, n_sensors=self.n_sensors, budget=self.budget,
                            candidates=self.candidates)
        if self.constraints is not None:
            self.constraints.check(enc)
            enc.restrict(self.constraints.allowed(enc))
        return enc

    def target_rows(self) -> list[int] | None:
        """Rows of the target strain outputs.

        Returns
        -------
        list of int or None
            None: all.
        """
        return None if self.targets is None else self.structure.strain_label_index(self.targets)

    def objective(self, encoding: CandidateSet | None = None) -> StrainErrorObjective:
        """The GA fitness on the first ``window`` seconds: :class:`~sensoropt.objective.StrainErrorObjective`,
        or :class:`~sensoropt.objective.FatigueErrorObjective` for ``objective_kind = "fatigue"``.

        Parameters
        ----------
        encoding : CandidateSet or PlateGrid, optional
            The candidates (default :meth:`encoding`).

        Returns
        -------
        StrainErrorObjective
        """
        settings = dict(window=self.window, stiffness_factor=self.stiffness_factor, relative_noise=self.relative_noise,
                        model_error_cov=self.model_error_cov, force_increment_cov=self.force_increment_cov,
                        n_modes=self.n_modes, seed=self.seed, targets=self.targets, force_model=self.force_model,
                        uncertainty=self.uncertainty, survive_failures=self.survive_failures,
                        failure_measure=self.failure_measure)
        encoding = encoding or self.encoding()
        if self.objective_kind == "fatigue":
            objective = FatigueErrorObjective(self.structure, self.forces, self.loads, self.dt, encoding,
                                              m=self.del_slope, **settings)
        elif self.objective_kind == "strain":
            objective = StrainErrorObjective(self.structure, self.forces, self.loads, self.dt, encoding, **settings)
        else:
            raise AKFInputError(f"objective_kind must be \"strain\" or \"fatigue\", got {self.objective_kind!r}")
        if self.constraints is not None and self.constraints.active:
            return Constrained(objective, encoding, self.constraints)
        return objective

    def full_record_error(self, sensors: Sequence[str], seed: int | None = None, truth: Structure | None = None) -> float:
        """Average strain error over the whole record of a layout.

        Simulation of the true structure with this layout and ``relative_noise``, steady-state AKF
        on the model with model error (``n_modes`` modes, static correction).

        Parameters
        ----------
        sensors : sequence of str
        seed : int, optional
            The noise draw (default the problem's).
        truth : Structure, optional
            The true structure (default :attr:`structure`); the filter's model is always
            :attr:`structure` scaled by :attr:`stiffness_factor`.

        Returns
        -------
        float
            µε.
        """
        rows = self.target_rows()
        est, sim = self._full_record(sensors, seed, lambda fm: fm.strain_rows() if rows is None else fm.strain_rows()[rows],
                                     truth)
        return float(average_strain_error(est, sim.strains if rows is None else sim.strains[:, rows])) * 1e6

    def full_record_fatigue_error(self, sensors: Sequence[str], seed: int | None = None) -> float:
        """Mean relative error of the damage-equivalent stress range of the targets over the whole
        record of a layout (as :class:`~sensoropt.objective.FatigueErrorObjective` on the window).

        Parameters
        ----------
        sensors : sequence of str
        seed : int, optional
            The noise draw (default the problem's).

        Returns
        -------
        float
            %.
        """
        from core_akf.fatigue import equivalent_range, rainflow, relative_stress_operator

        rows = self.target_rows() or list(range(self.structure.n_strain))
        W = relative_stress_operator(self.structure, rows)
        est, sim = self._full_record(sensors, seed, lambda fm: W @ fm.strain_rows())
        true = equivalent_range(rainflow(sim.strains @ W.T), self.del_slope, 1.0)
        got = equivalent_range(rainflow(est), self.del_slope, 1.0)
        counted = true > 0
        return float(100.0 * np.mean(np.abs(got[counted] / true[counted] - 1.0)))

    def model_errors(self, sensors: Sequence[str]) -> list[dict]:
        """The whole-record strain error of a layout on the true structure of each model of
        :attr:`uncertainty` (the problem's noise draw).

        Parameters
        ----------
        sensors : sequence of str

        Returns
        -------
        list of dict
            Per model: its :meth:`~sensoropt.robust.Uncertainty.table` record and ``error`` (µε).
        """
        if self.uncertainty is None:
            return []
        truths = self.uncertainty.truths(self.structure, self.stiffness_factor)
        return [row | {"error": self.full_record_error(sensors, truth=t)}
                for row, t in zip(self.uncertainty.table(), truths)]

    def full_record_errors(self, layouts: Sequence[Sequence[str]], seed: int | None = None,
                           truth: Structure | None = None) -> list[float]:
        """:meth:`full_record_error` of several layouts on one simulation of every sensor they
        use: a channel has the same noise in every layout (common random numbers), so the
        layouts are compared on the same record.

        Parameters
        ----------
        layouts : sequence of sequence of str
        seed : int, optional
            The noise draw (default the problem's).
        truth : Structure, optional
            The true structure (default :attr:`structure`).

        Returns
        -------
        list of float
            µε per layout.
        """
        union = list(dict.fromkeys(str(s) for layout in layouts for s in layout))
        sim = self._simulation(union, seed, truth)
        rows = self.target_rows()
        out = []
        for layout in layouts:
            est, _ = self._full_record(list(layout), seed, lambda fm: fm.strain_rows() if rows is None else
                                       fm.strain_rows()[rows], truth, sim=(sim, [union.index(str(s)) for s in layout]))
            out.append(float(average_strain_error(est, sim.strains if rows is None else sim.strains[:, rows])) * 1e6)
        return out

    def _simulation(self, sensors, seed, truth):
        return simulate(self.structure if truth is None else truth, sensors, self.forces, self.loads, self.dt,
                        relative_noise=self.relative_noise, seed=self.seed if seed is None else seed)

    def _full_record(self, sensors, seed, rows_of, truth=None, sim=None):
        """The steady AKF's outputs ``rows_of(filter model)`` over the whole record, and the
        simulation (or ``sim = (simulation, columns)``: the layout's columns of a simulation of
        more sensors)."""
        if sim is None:
            sim, cols = self._simulation(sensors, seed, truth), slice(None)
        else:
            sim, cols = sim
        n_modes = self.n_modes if self.n_modes in (None, "auto") else min(int(self.n_modes), self.structure.n)
        n_modes = resolve_modes(n_modes, self.structure, self.dt, sees_accelerations(sensors))
        fm = self._filter_model(n_modes)
        R = np.diag(np.maximum(sim.noise_std[cols], default("noise_floor")) ** 2) \
            + fm.residual_noise(sensors, self.model_error_cov)
        est = steady_outputs(fm.A_a, fm.observation(sensors)[None], fm.Q_a(self.model_error_cov),
                             R[None], np.ascontiguousarray(sim.measurements[:, cols])[None], rows_of(fm))[0]
        return est, sim

    def _filter_model(self, n_modes):
        """The filter's model with ``n_modes`` modes (kept: the whole-record checks reuse it)."""
        cache = self.__dict__.setdefault("_filter_models", {})
        key = (n_modes, id(self.structure), tuple(self.forces), self.dt, self.stiffness_factor, self.force_model,
               self.force_increment_cov)
        if key not in cache:
            force_model = self.force_model or ForceModel("random_walk", increment_cov=self.force_increment_cov)
            cache[key] = FilterModel(self.structure.scaled(self.stiffness_factor), self.forces, self.dt, n_modes,
                                     force_model=force_model)
        return cache[key]
