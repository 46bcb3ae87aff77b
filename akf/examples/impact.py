"""The built-in impact cases (IMP, Saleem & Jo 2019, section 4) as simulated scenarios.

The cases are the job files ``imp-truss-case1``, ``imp-truss-case2`` and ``imp-plate`` of
:mod:`akf.examples`: a 10 kN (truss) / 1 kN (plate) half-sine pulse of 4 ms at 0.98 s on top of
low-level background excitation (band-limited noise, 50 N / 5 N RMS) at the same location,
perpendicular (truss: vertical); records of 1.5 s at 1 kHz; noise of 1 microstrain and 1 mg
(``noise="abs"``) or 10 % of each channel's RMS (``"rel10"``).  :func:`example_scenario` moves the
impact and changes noise and seed, and simulates.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core_akf.checks import AKFInputError

from . import example_names, load_example

#: noise options of the examples: absolute (1 microstrain, 1 mg) or 10 % of each channel's RMS
NOISE = ("abs", "rel10")


@dataclass
class ImpactScenario:
    """A simulated impact: the true structure, installed sensors, the measurements and the truth."""

    name: str
    structure: object
    sensors: list
    dt: float
    measurements: np.ndarray
    true_force: np.ndarray
    impact: tuple
    n_ad: int
    ad_kinds: tuple
    direction: str
    simulation: object = None
    #: the job's further ``[locate]`` settings for :func:`impactloc.locate` (candidates, n_modes, ...)
    options: dict = None
    #: the locate :class:`~akf.job.Job` the scenario was simulated from (:func:`impact_job`): what
    #: ``akf locate --example`` runs, every ``[locate]`` key honoured (:func:`akf.locating.run_locate_job`)
    job: object = None


def impact_job(name, impact_node=None, noise="abs", seed=0):
    """The locate job of example ``name`` with the impact at ``impact_node`` (default the file's),
    ``noise`` "abs" or "rel10", and the noise and background-load seeds shifted by ``seed``."""
    if noise not in NOISE:
        raise AKFInputError(f"noise must be one of {NOISE}, got {noise!r}")
    job = load_example(name, "locate")
    if impact_node is not None:
        job["forces"] = [f"{int(impact_node)}:{job['locate']['direction']}"]
    sim = job["simulation"]
    sim["seed"] = int(seed)
    if noise == "rel10":
        sim.pop("absolute_noise", None)
        sim["relative_noise"] = 0.10
    for load in sim["loads"]:
        for c in load["components"]:
            if "seed" in c:
                c["seed"] += int(seed)
    return job


def example_scenario(name, impact_node=None, noise="abs", seed=0):
    """Simulate the built-in impact example ``name`` (see :func:`impact_job`)."""
    from ..job import Job

    job = Job.from_dict(impact_job(name, impact_node, noise, seed), "locate")
    sim = job.simulate()
    loc = job.spec.locate
    options = {k: getattr(loc, k) for k in ("candidates", "skip", "max_splits") if getattr(loc, k) is not None}
    if loc.n_modes is not None:
        options["n_modes"] = job.n_modes
    return ImpactScenario(name, job.structure, list(job.spec.sensors), job.dt, sim.measurements,
                          sim.loads[:, 0], job.forces[0], int(loc.n_ad), tuple(loc.ad_kinds or ["strain"]),
                          loc.direction, sim, options, job)


#: the impact examples
EXAMPLES = example_names("locate")
