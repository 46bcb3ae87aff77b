"""Placement problems from job files and the built-in thesis problems (``akf place``)."""
from __future__ import annotations

from core_akf.defaults import default
from core_akf.exceptions import AKFInputError
from sensoropt.problem import PlacementProblem

from .examples import TH_CASE2, load_example
from .jobs import build_loads, build_structure
from .schema import parse_job


def example_problem(name, n_sensors=None):
    """The built-in placement problem ``name`` (``th-case5``, ``th-case6``, ``th-multi``: job
    files in :mod:`akf.examples`), optionally with another sensor count; the trial-and-error
    layout of TH case 2 is its reference."""
    job = load_example(name, "place")
    if n_sensors is not None:
        if "budget" in job["place"]:
            raise AKFInputError(f"{name} has a fixed budget {job['place']['budget']}; --sensors does not apply")
        job["place"]["sensors"] = int(n_sensors)
    problem, _ = problem_from_job(job)
    if name.startswith("th-"):
        problem.reference_layouts = {"TH case 2 (trial and error)": list(TH_CASE2)}
    return problem


def example_settings(name):
    """The GA settings a built-in place example sets in its ``[place]`` table (the thesis'
    defaults for the rest)."""
    return problem_from_job(load_example(name, "place"))[1]


GA_KEYS = ("population", "generations", "elite", "crossover", "mutation", "tournament", "stall_generations", "operators")


def problem_from_job(job):
    """A :class:`PlacementProblem` and GA settings from a place job (dict from TOML, see
    :mod:`akf.schema`)."""
    spec = parse_job(job, "place")
    structure = build_structure(job["structure"])
    dt = spec.dt
    sim = spec.simulation
    if sim.duration is None:
        raise AKFInputError("[simulation] needs a positive duration (s)")
    loads = build_loads(job["simulation"].get("loads", []), int(round(sim.duration / dt)), dt, len(spec.forces))
    p, f = spec.place, spec.filter
    if p.sensors is None and p.budget is None:
        raise AKFInputError("[place] needs sensors = N or budget = {strain = N, acc = M}")
    problem = PlacementProblem(spec.name or "place", structure, list(spec.forces), loads, dt,
                               kinds=tuple(p.kinds) if p.kinds else None, n_sensors=p.sensors, budget=p.budget,
                               candidates=list(p.candidates) if p.candidates else None,
                               targets=list(p.targets) if p.targets else None,
                               window=default("window", p.window),
                               stiffness_factor=default("placement_stiffness_factor", f.stiffness_factor),
                               relative_noise=default("relative_noise", sim.relative_noise),
                               model_error_cov=default("model_error_cov", f.model_error_cov),
                               force_increment_cov=default("force_increment_cov", f.force_increment_cov),
                               n_modes=None if p.n_modes == "full" else (p.n_modes or "auto"),
                               seed=sim.seed or 0)
    if f.force_increment_cov is None:
        problem.notes = force_increment_notes(loads)
    return problem, {k: getattr(p, k) for k in GA_KEYS if getattr(p, k) is not None}


def force_increment_notes(loads, band=10.0):
    """A note when the default S (``force_increment_cov``, 1 N^2 per step) is far from the
    variance of the loads' own increments per step (more than ``band`` times off): on kN loads a
    layout's error is then reported several times too large, and the GA may rank layouts by the
    filter's lag rather than by where the sensors are."""
    import numpy as np

    s_default = default("force_increment_cov")
    own = float(np.mean(np.var(np.diff(loads, axis=0), axis=0))) if loads.shape[0] > 2 else s_default
    if own > 0 and not s_default / band <= own <= s_default * band:
        return [f"[filter] force_increment_cov is not set: S = {s_default:g} N^2 per step (the default), but the "
                f"loads change by {own:.3g} N^2 per step (variance of their increments); set force_increment_cov = "
                f"{own:.3g} (or your own estimate of how fast the forces change) for errors that mean something"]
    return []
