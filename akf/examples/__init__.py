"""The papers' cases as job files inside the package, loaded by name.

Each ``jobs/NAME.toml`` is an ordinary job file of the command in its header (``akf estimate``,
``akf place`` or ``akf locate``); ``akf COMMAND --example NAME`` runs it and
``tests/test_examples.py`` pins each to its result.  The studies vary them (other sensors,
no model error, another plate) through :func:`s17_job` and :func:`th_job`.

S17 (Khodabandeloo et al. 2017): planar truss, four vertical loads -- random at joint 4, an
impulse at joint 6, random plus a slowly varying high-amplitude load at joint 8, noise plus a ramp
at joint 12 -- 5 % model error (filter 5 % stiffer), 2 % noise.  S17 gives the load types but not
their amplitudes; the ones in the files are ours.

TH (thesis plate): excitation 1 at node 121 (ramp from 1 s to 89 N at 5 s plus band-limited white
noise), excitation 2 at node 111 (half sine to 44.5 N plus band-limited white noise), 5 % model
error, 2 % noise, dt = 1/2000 s.

IMP (Saleem & Jo 2019): impacts on the S17 truss and on a 5 x 5 cantilever plate (see
:mod:`akf.examples.impact`).

Footbridge (ours, not from the papers): the 3-D truss footbridge of
:func:`core_akf.models.footbridge` -- two forces estimated from 4 strain gauges and 2
accelerometers (``footbridge-walk``), the placement of those 6 sensors (``footbridge-place``) and
an impact on the deck (``footbridge-impact``).
"""
from __future__ import annotations

import copy
import functools
import os

from core_akf.checks import AKFInputError
from core_akf.defaults import default

from ..job import Job, load_job_file

#: the folder of the example job files
JOBS_DIR = os.path.join(os.path.dirname(__file__), "jobs")

#: example name -> the command that runs it
COMMAND_OF = {
    "s17-case1": "estimate", "s17-case2": "estimate", "s17-case3": "estimate", "s17-case4": "estimate",
    "s17-acc": "estimate",
    "th-case2": "estimate", "th-case3": "estimate",
    "th-case5": "place", "th-case6": "place", "th-multi": "place",
    "imp-truss-case1": "locate", "imp-truss-case2": "locate", "imp-plate": "locate",
    "footbridge-walk": "estimate", "footbridge-place": "place", "footbridge-impact": "locate",
}


def example_names(command=None):
    """Names of the built-in examples (of ``command``: "estimate", "place" or "locate")."""
    return sorted(n for n, c in COMMAND_OF.items() if command in (None, c))


def example_path(name):
    """The job file of example ``name``."""
    if name not in COMMAND_OF:
        raise AKFInputError(f"unknown example {name!r}; available: {', '.join(example_names())}")
    return os.path.join(JOBS_DIR, f"{name}.toml")


@functools.cache
def _load(name):
    return load_job_file(example_path(name))        # checked where it is used: Job.from_dict


def load_example(name, command=None):
    """A fresh copy of the built-in job ``name`` (a dict, as read from its TOML file); with
    ``command``, an example of another command is refused naming the right one."""
    if command is not None and COMMAND_OF.get(name, command) != command:
        raise AKFInputError(f"{name!r} is an example of akf {COMMAND_OF[name]}, not of akf {command}; examples of "
                            f"akf {command}: {', '.join(example_names(command))}")
    if command is not None and name not in COMMAND_OF:
        raise AKFInputError(f"unknown example {name!r}; available: {', '.join(example_names(command))}")
    return copy.deepcopy(_load(name))


def example_job(name):
    """A fresh copy of the built-in estimation job ``name`` (a dict, to vary before it is run)."""
    return load_example(name, "estimate")


def example(name, overrides=None):
    """The built-in job ``name`` as a :class:`akf.job.Job` of its command (checked once), with
    ``overrides`` as in :meth:`akf.job.Job.from_dict`."""
    data = load_example(name)          # an unknown name is refused here, naming the examples
    return Job.from_dict(data, COMMAND_OF[name], overrides=overrides)


# ------------------------------------------------------------------------ variations for studies
#: the papers' "no noise" cases keep a negligible noise (0.01 % of each channel's RMS) so that R
#: stays positive definite
_NEGLIGIBLE_NOISE = 1e-4
S17_FORCES = ["4:y", "6:y", "8:y", "12:y"]
S17_ACC_ONLY = [f"acc:{j}:y" for j in (2, 4, 5, 6, 7, 8, 9, 12, 14, 15)] + [f"acc:{j}:x" for j in (4, 5, 8, 9)]
S17_STRAIN_ONLY = [f"strain:{m}" for m in (4, 5, 9, 12, 13, 16, 21, 24, 26)]
S17_MULTI = ["acc:4:y", "acc:6:y", "acc:8:y", "acc:12:y", "acc:6:x", "strain:5", "strain:9", "strain:13", "strain:26"]


def s17_job(name, description, sensors, slow=True, model_error=True, noise=True):
    """An S17 truss job with other ``sensors``: the loads of ``s17-case4`` (or the zero-mean
    loads of ``s17-case1`` when not ``slow``), 5 % model error and 2 % noise unless switched off."""
    job = load_example("s17-case4" if slow else "s17-case1")
    job.update(name=name, description=description, sensors=list(sensors))
    job["filter"].update(stiffness_factor=default("placement_stiffness_factor") if model_error else 1.0, steady=True)
    job["simulation"]["relative_noise"] = default("relative_noise") if noise else _NEGLIGIBLE_NOISE
    return job


TH_FORCES = ["121:w", "111:w"]
#: the thesis' flexible plate (case 5): 60.96 cm x 182.88 cm x 1/64 in, clamped along y = 0
TH_FLEXIBLE_PLATE = {"model": "plate", "nx": 10, "ny": 10, "lx": 0.6096, "ly": 1.8288, "thickness": 3.96875e-4,
                     "E": 200e9, "nu": 0.3, "rho": 7800.0, "clamped_edge": "y0", "damping": 0.01}


def th_job(name, description, sensors, model_error=True, noise=True, structure=None, load_scale=1.0,
           model_error_cov=1e-16, force_increment_cov=1.0):
    """A thesis plate job with other ``sensors`` (the loads of ``th-case2``, all times
    ``load_scale``); 5 % model error and 2 % noise unless switched off."""
    job = load_example("th-case2")
    job.update(name=name, description=description, sensors=list(sensors))
    if structure is not None:
        job["structure"] = dict(structure)
    job["filter"].update(stiffness_factor=default("placement_stiffness_factor") if model_error else 1.0,
                         model_error_cov=model_error_cov,
                         force_increment_cov=force_increment_cov)
    job["simulation"]["relative_noise"] = default("relative_noise") if noise else _NEGLIGIBLE_NOISE
    for load in job["simulation"]["loads"]:
        for c in load["components"]:
            for k in ("peak", "rms"):
                if k in c:
                    c[k] *= load_scale
    return job


#: thesis sensor sets.  Case 2's components are shown only in a figure; we read the thesis'
#: "XY" subscripts as g_xy at nodes 2 and 100 (the gauges case 3 keeps) and take e_x at node 58.
TH_CASE1 = ["acc:12:w", "acc:58:w", "acc:100:w"]
TH_CASE2 = ["strain:2:gxy", "strain:58:ex", "strain:100:gxy"]
TH_CASE3 = ["strain:2:gxy", "strain:100:gxy", "acc:12:w"]
#: case 4 ("arbitrary"): e_x at 23, e_y at 103 and an accelerometer at node 2 -- node 2 lies on
#: the clamped edge, where an accelerometer records exactly zero, so only the two gauges inform
TH_CASE4 = ["strain:23:ex", "strain:103:ey"]
