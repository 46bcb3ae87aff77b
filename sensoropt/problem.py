"""Placement problems: the plate, its loads, what may be placed, and the full-record check.

Built-in examples (the thesis plate, TH §4; loads of :func:`core_akf.examples.th_job`):

* ``th-case5``: 3 strain gauges (any of e_x, e_y, g_xy at any node), TH case 5;
* ``th-case6``: the same with ``--sensors`` 3, 4, 5 or 8 (TH case 6);
* ``th-multi``: 2 strain gauges + 1 accelerometer (the multi-metric placement TH names as
  future work).
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np

from core_akf.examples import TH_CASE2, th_job
from core_akf.exceptions import AKFInputError
from core_akf import jobs as J
from core_akf.jobs import build_loads, build_structure, check_sections
from core_akf.metrics import average_strain_error
from core_akf.reduced import ModalFilterModel, steady_outputs
from core_akf.simulate import simulate

from .encoding import STRAIN_KINDS, Encoding
from .objective import StrainErrorObjective


@dataclass
class PlacementProblem:
    """A plate, its force locations and load histories (full record), what to place, and the
    filter settings.  ``objective()`` builds the GA fitness on the first ``window`` seconds;
    ``full_record_error(sensors)`` checks a layout on the whole record."""

    name: str
    structure: object
    forces: list
    loads: np.ndarray
    dt: float
    kinds: tuple = STRAIN_KINDS
    n_sensors: int = None
    budget: dict = None
    window: float = 0.1
    stiffness_factor: float = 1.05
    relative_noise: float = 0.02
    model_error_cov: float = 1e-16
    force_increment_cov: float = 1.0
    n_modes: object = "auto"
    seed: int = 0
    reference_layouts: dict = field(default_factory=dict)

    def encoding(self):
        return Encoding(self.structure, kinds=self.kinds, n_sensors=self.n_sensors, budget=self.budget)

    def objective(self, encoding=None):
        return StrainErrorObjective(self.structure, self.forces, self.loads, self.dt, encoding or self.encoding(),
                                    window=self.window, stiffness_factor=self.stiffness_factor,
                                    relative_noise=self.relative_noise, model_error_cov=self.model_error_cov,
                                    force_increment_cov=self.force_increment_cov, n_modes=self.n_modes,
                                    seed=self.seed)

    def full_record_error(self, sensors, seed=None):
        """Average strain error (µε) over the whole record: simulation of the true plate with
        this layout and ``relative_noise``, steady-state AKF on the model with model error
        (``n_modes`` modes, static correction)."""
        sim = simulate(self.structure, sensors, self.forces, self.loads, self.dt, relative_noise=self.relative_noise,
                       seed=self.seed if seed is None else seed)
        n_modes = self.n_modes
        if n_modes == "auto":
            n_modes = 100 if any(str(s).startswith("acc") for s in sensors) else 80
        fm = ModalFilterModel(self.structure.scaled(self.stiffness_factor), self.forces, self.dt,
                              None if n_modes is None else min(int(n_modes), self.structure.n))
        R = np.diag(np.maximum(sim.noise_std, 1e-30) ** 2)
        est = steady_outputs(fm.A_a, fm.observation(sensors)[None], fm.Q_a(self.model_error_cov, self.force_increment_cov),
                             R[None], sim.measurements[None], fm.strain_rows())[0]
        return float(average_strain_error(est, sim.strains)) * 1e6


EXAMPLES = {
    "th-case5": dict(kinds=STRAIN_KINDS, n_sensors=3, description="TH case 5: 3 strain gauges on the thesis plate"),
    "th-case6": dict(kinds=STRAIN_KINDS, n_sensors=3, description="TH case 6: N strain gauges (use --sensors N)"),
    "th-multi": dict(kinds=STRAIN_KINDS + ("acc",), budget={"strain": 2, "acc": 1},
                     description="multi-metric: 2 strain gauges + 1 accelerometer on the thesis plate"),
}


def example_problem(name, n_sensors=None):
    """The built-in problem ``name`` (see :data:`EXAMPLES`), optionally with another sensor count."""
    if name not in EXAMPLES:
        raise AKFInputError(f"unknown placement example {name!r}; available: {', '.join(EXAMPLES)}")
    spec = EXAMPLES[name]
    job = th_job(name, spec["description"], TH_CASE2)
    structure = build_structure(job["structure"])
    dt = float(job["dt"])
    loads = build_loads(job["simulation"]["loads"], int(round(job["simulation"]["duration"] / dt)), dt, 2)
    budget = copy.deepcopy(spec.get("budget"))
    n = spec.get("n_sensors")
    if n_sensors is not None:
        if budget:
            raise AKFInputError(f"{name} has a fixed budget {budget}; --sensors does not apply")
        n = int(n_sensors)
    return PlacementProblem(name, structure, list(job["forces"]), loads, dt, kinds=spec["kinds"], n_sensors=n,
                            budget=budget, model_error_cov=job["filter"]["model_error_cov"],
                            force_increment_cov=job["filter"]["force_increment_cov"],
                            reference_layouts={"TH case 2 (trial and error)": list(TH_CASE2)})


PLACE_KEYS = {
    None: {"name": J.TEXT, "description": J.ANY, "dt": J.POSITIVE, "forces": J.TEXTS, "structure": J.TABLE,
           "place": J.TABLE, "filter": J.TABLE, "simulation": J.TABLE},
    "place": {"sensors": J.COUNT, "budget": J.TABLE, "kinds": J.TEXTS, "window": J.POSITIVE, "population": J.COUNT,
              "generations": J.COUNT0, "elite": J.COUNT0, "crossover": J.FRACTION, "mutation": J.FRACTION,
              "tournament": J.COUNT, "stall_generations": J.COUNT0, "operators": J.TEXT, "n_modes": J.MODES},
    "filter": {"stiffness_factor": J.POSITIVE, "model_error_cov": J.NON_NEGATIVE, "force_increment_cov": J.POSITIVE},
    "simulation": {"duration": J.POSITIVE, "relative_noise": J.NON_NEGATIVE, "seed": J.SEED, "loads": J.TABLES},
}
GA_KEYS = ("population", "generations", "elite", "crossover", "mutation", "tournament", "stall_generations", "operators")


def problem_from_job(job):
    """A :class:`PlacementProblem` and GA settings from a place job (dict from TOML)."""
    check_sections(job, PLACE_KEYS, "place job")
    for key in ("dt", "forces", "structure", "place", "simulation"):
        if key not in job:
            raise AKFInputError(f"the place job has no {key!r}")
    structure = build_structure(job["structure"])
    dt = float(job["dt"])
    sim = job["simulation"]
    if "duration" not in sim or not float(sim["duration"]) > 0:
        raise AKFInputError("[simulation] needs a positive duration (s)")
    loads = build_loads(sim.get("loads", []), int(round(float(sim["duration"]) / dt)), dt, len(job["forces"]))
    p, f = job["place"], job.get("filter", {})
    if "sensors" not in p and "budget" not in p:
        raise AKFInputError("[place] needs sensors = N or budget = {strain = N, acc = M}")
    problem = PlacementProblem(job.get("name", "place"), structure, list(job["forces"]), loads, dt,
                               kinds=tuple(p.get("kinds", STRAIN_KINDS)), n_sensors=p.get("sensors"),
                               budget=p.get("budget"), window=float(p.get("window", 0.1)),
                               stiffness_factor=float(f.get("stiffness_factor", 1.05)),
                               relative_noise=float(sim.get("relative_noise", 0.02)),
                               model_error_cov=float(f.get("model_error_cov", 1e-16)),
                               force_increment_cov=float(f.get("force_increment_cov", 1.0)),
                               n_modes=None if p.get("n_modes") == "full" else p.get("n_modes", "auto"),
                               seed=int(sim.get("seed", 0)))
    return problem, {k: p[k] for k in GA_KEYS if k in p}
