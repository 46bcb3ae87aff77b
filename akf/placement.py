"""Placement problems from job files and the built-in thesis problems (``akf place``)."""
from __future__ import annotations

from core_akf.checks import AKFInputError
from core_akf.defaults import default
from sensoropt.problem import PlacementProblem

from .examples import TH_CASE2, load_example
from .job import Job, check_stiffness_factors


def example_problem(name, n_sensors=None):
    """The built-in placement problem ``name`` (``th-case5``, ``th-case6``, ``th-multi``,
    ``footbridge-place``: job files in :mod:`akf.examples`), optionally with another sensor
    count; the trial-and-error layout of TH case 2 is the reference of the thesis' problems."""
    data = load_example(name, "place")
    if n_sensors is not None and "budget" in data["place"]:
        raise AKFInputError(f"{name} has a fixed budget {data['place']['budget']}; --sensors does not apply")
    job = Job.from_dict(data, "place", overrides=None if n_sensors is None else {"place.sensors": int(n_sensors)})
    problem, _ = problem_from_job(job)
    problem.reference_layouts = reference_layouts(name)
    return problem


def reference_layouts(name):
    """The layouts a built-in place example is compared with: TH case 2's trial-and-error layout
    for the thesis' problems, none for the others."""
    return {"TH case 2 (trial and error)": list(TH_CASE2)} if name.startswith("th-") else {}


def example_settings(name):
    """The GA settings a built-in place example sets in its ``[place]`` table (the thesis'
    defaults for the rest)."""
    return ga_settings(Job.from_dict(load_example(name, "place"), "place"))


GA_KEYS = ("population", "generations", "elite", "crossover", "mutation", "tournament", "stall_generations", "operators")


def ga_settings(job: Job) -> dict:
    """The GA settings a place job sets in its ``[place]`` table."""
    p = job.spec.place
    return {k: getattr(p, k) for k in GA_KEYS if getattr(p, k) is not None}


def problem_from_job(job: Job):
    """A :class:`PlacementProblem` and the GA settings (:func:`ga_settings`) of a place
    :class:`~akf.job.Job`."""
    spec = job.spec
    sim, p, f = spec.simulation, spec.place, spec.filter
    if p.del_slope is not None and p.objective != "fatigue":
        raise AKFInputError(f"[place] del_slope = {p.del_slope:g} is a setting of objective = \"fatigue\", but the "
                            "objective is \"strain\" (the default): set objective = \"fatigue\" or remove del_slope")
    loads = job.loads()
    if p.sensors is None and p.budget is None:
        raise AKFInputError("[place] needs sensors = N or budget = {strain = N, acc = M}")
    problem = PlacementProblem(job.name, job.structure, list(spec.forces), loads, job.dt,
                               kinds=tuple(p.kinds) if p.kinds else None, n_sensors=p.sensors, budget=p.budget,
                               candidates=list(p.candidates) if p.candidates else None,
                               targets=list(p.targets) if p.targets else None,
                               window=default("window", p.window), stiffness_factor=job.stiffness_factor,
                               relative_noise=default("relative_noise", sim.relative_noise),
                               model_error_cov=job.model_error_cov, force_increment_cov=job.force_increment_cov,
                               n_modes=job.n_modes, seed=sim.seed or 0, objective_kind=p.objective or "strain",
                               del_slope=3.0 if p.del_slope is None else float(p.del_slope),
                               force_model=job.force_model, uncertainty=uncertainty_of(job),
                               survive_failures=p.survive_failures or 0, failure_measure=p.failure_measure or "worst",
                               constraints=constraints_of(job))
    if f.force_increment_cov is None and not job.force_model.stationary:
        problem.notes = force_increment_notes(loads)
    return problem, ga_settings(job)


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


def uncertainty_of(job: Job):
    """The :class:`~sensoropt.robust.Uncertainty` of a place job's ``[place.uncertainty]`` (None
    without one), drawn with the job's ``[simulation] seed``."""
    from sensoropt.robust import Uncertainty

    u = job.spec.place.uncertainty
    if u is None:
        return None
    frequency = None if u.frequency_factors is None else calibrated_frequencies(job, u.frequency_factors)
    if u.stiffness_factor is not None:
        factor = u.stiffness_factor
        check_stiffness_factors(factor, key="[place.uncertainty] stiffness_factor")
    elif frequency is not None:     # a calibration says how the truth differs from the filter's model: its
        # stiffness factor (the other modes' common factor, squared) against the job's, and the modes' factors on top
        factor = job.stiffness_factor / frequency[2]
        frequency = frequency[:2]
    else:
        factor = job.stiffness_factor
    try:
        return Uncertainty.sample(factor, frequency=frequency, samples=u.samples or 8, seeds=u.seeds or 3,
                                  measure=u.measure or "p90", seed=job.spec.simulation.seed or 0)
    except AKFInputError as exc:
        raise AKFInputError(f"[place.uncertainty] {exc}") from None


def calibrated_frequencies(job: Job, path: str):
    """The per-mode frequency factors of a calibration, the standard errors of their logarithms
    and the calibrated stiffness factor: ``[filter] frequency_factors`` and ``stiffness_factor``
    (the job's where it has none) of the ``calibrated.toml`` at ``path`` (relative to the job
    file), and the standard errors of the ``calibration.json`` that akf calibrate wrote beside it:
    the larger of the robust and the observed-information one of each mode.  A mode the
    calibration did not fit keeps factor 1 with no spread."""
    import json
    import os

    import numpy as np
    import tomllib

    where = "[place.uncertainty] frequency_factors"
    if not os.path.isabs(path) and job.source is not None:
        path = os.path.join(os.path.dirname(os.path.abspath(job.source)), path)
    try:
        with open(path, "rb") as fh:
            table = tomllib.load(fh).get("filter") or {}
        fitted, stiffness = table.get("frequency_factors"), table.get("stiffness_factor", job.stiffness_factor)
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise AKFInputError(f"{where}: cannot read {path} as a calibrated job ({type(exc).__name__}: "
                            f"{getattr(exc, 'strerror', None) or exc})") from None
    if not isinstance(fitted, list) or not fitted or not all(isinstance(v, (int, float)) and v > 0 for v in fitted):
        raise AKFInputError(f"{where}: {path} has no [filter] frequency_factors (a list of positive factors): give "
                            "the calibrated.toml of akf calibrate with calibrate = [\"frequencies\"]")
    report = os.path.join(os.path.dirname(path), "calibration.json")
    try:
        with open(report, encoding="utf-8") as fh:
            saved = json.load(fh)
        errors = {name: max(value, saved.get("robust_std_errors", {}).get(name, 0.0) or 0.0)
                  for name, value in saved["std_errors"].items()}
    except (OSError, ValueError, KeyError, TypeError):
        raise AKFInputError(f"{where}: no calibration.json with the standard errors beside {path} (akf calibrate "
                            "writes it since this version: run it again)") from None
    std = np.array([float(errors.get(f"frequencies:{k + 1}", 0.0) or 0.0) for k in range(len(fitted))])
    if not np.all(np.isfinite(std)):
        raise AKFInputError(f"{where}: the calibration left a frequency's standard error undetermined "
                            f"({report}); the record does not identify it")
    if not (isinstance(stiffness, (int, float)) and stiffness > 0):
        raise AKFInputError(f"{where}: {path} has [filter] stiffness_factor = {stiffness!r}; a positive factor is expected")
    return np.array(fitted, float), std, float(stiffness)


def constraints_of(job: Job):
    """The :class:`~sensoropt.constraints.Constraints` of a place job's ``[place.constraints]``
    (None without one)."""
    from sensoropt.constraints import Constraints

    c = job.spec.place.constraints
    if c is None:
        return None
    return Constraints(cost=c.cost, budget=c.budget, forbidden=c.forbidden, forbidden_nodes=c.forbidden_nodes,
                       min_spacing=c.min_spacing)
