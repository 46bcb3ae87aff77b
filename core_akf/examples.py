"""Built-in example jobs (the papers' cases) for ``akf estimate --example NAME``.

S17 (Khodabandeloo et al. 2017): planar truss, four vertical loads -- random at joint 4,
an impulse at joint 6, random plus a slowly varying high-amplitude load at joint 8, noise
plus a ramp at joint 12 -- 5 % model error (filter 5 % stiffer), 2 % noise.  S17 gives the
load types but not their amplitudes; the ones below are ours.

TH (thesis plate): excitation 1 at node 121 (ramp from 1 s to 89 N at 5 s plus
band-limited white noise), excitation 2 at node 111 (half sine to 44.5 N plus band-limited
white noise), 5 % model error, 2 % noise, dt = 1/2000 s.
"""
from __future__ import annotations

import copy

S17_FORCES = ["4:y", "6:y", "8:y", "12:y"]
S17_DT = 1.0 / 4096
S17_ACC_ONLY = [f"acc:{j}:y" for j in (2, 4, 5, 6, 7, 8, 9, 12, 14, 15)] + [f"acc:{j}:x" for j in (4, 5, 8, 9)]
S17_STRAIN_ONLY = [f"strain:{m}" for m in (4, 5, 9, 12, 13, 16, 21, 24, 26)]
S17_MULTI = ["acc:4:y", "acc:6:y", "acc:8:y", "acc:12:y", "acc:6:x", "strain:5", "strain:9", "strain:13", "strain:26"]


def _s17_loads(slow=True):
    """S17 load set (case 2-4 style when ``slow``; zero-mean case-1 loads otherwise)."""
    band = lambda rms, seed: {"type": "band_noise", "rms": rms, "f_high": 200.0, "seed": seed}
    loads = [
        {"components": [band(500.0, 11)]},                                             # joint 4: random
        {"components": [{"type": "pulse", "start": 0.5, "duration": 0.005, "peak": 5000.0}]},  # joint 6: impulse
        {"components": [band(300.0, 12)]},                                             # joint 8: random
        {"components": [band(150.0, 13)]},                                             # joint 12: noise
    ]
    if slow:
        loads[2]["components"].append({"type": "half_sine", "start": 0.2, "end": 1.8, "peak": 3000.0})
        loads[3]["components"].append({"type": "ramp", "start": 0.5, "end": 1.5, "peak": 2000.0})
    return loads


def s17_job(name, description, sensors, slow=True, model_error=True, noise=True):
    """An S17 truss job: the four vertical loads (with the slowly varying / non-zero-mean parts
    when ``slow``), 5 % model error and 2 % noise unless switched off."""
    return {
        "name": name,
        "description": description,
        "structure": {"model": "s17_truss"},
        "dt": S17_DT,
        "sensors": sensors,
        "forces": S17_FORCES,
        "filter": {"stiffness_factor": 1.05 if model_error else 1.0, "model_error_cov": 1e-16,
                   "force_increment_cov": 1e5, "noise_cov": "simulated", "steady": True},
        "simulation": {"duration": 2.0, "relative_noise": 0.02 if noise else 1e-4, "seed": 0,
                       "loads": _s17_loads(slow)},
        "output": {"strains": "all"},
    }


TH_FORCES = ["121:w", "111:w"]
#: the thesis' flexible plate (case 5): 60.96 cm x 182.88 cm x 1/64 in, clamped along y = 0
TH_FLEXIBLE_PLATE = {"model": "plate", "nx": 10, "ny": 10, "lx": 0.6096, "ly": 1.8288, "thickness": 3.96875e-4,
                     "E": 200e9, "nu": 0.3, "rho": 7800.0, "clamped_edge": "y0", "damping": 0.01}


def th_job(name, description, sensors, model_error=True, noise=True, structure=None, load_scale=1.0,
           model_error_cov=1e-16, force_increment_cov=1.0):
    """A thesis plate job: excitation 1 at node 121 (ramp 1 s -> 5 s to 89 N) and excitation 2
    at node 111 (half sine 0.5 s -> 5.5 s, 44.5 N), each plus band-limited white noise (5 N RMS,
    0-100 Hz); all loads times ``load_scale``; 5 % model error and 2 % noise unless switched off."""
    band = lambda seed: {"type": "band_noise", "rms": 5.0 * load_scale, "f_high": 100.0, "seed": seed}
    return {
        "name": name,
        "description": description,
        "structure": dict(structure or {"model": "th_plate"}),
        "dt": 1.0 / 2000,
        "sensors": sensors,
        "forces": TH_FORCES,
        "filter": {"stiffness_factor": 1.05 if model_error else 1.0, "model_error_cov": model_error_cov,
                   "force_increment_cov": force_increment_cov, "noise_cov": "simulated", "steady": True},
        "simulation": {"duration": 6.0, "relative_noise": 0.02 if noise else 1e-4, "seed": 0,
                       "loads": [{"components": [{"type": "ramp", "start": 1.0, "end": 5.0, "peak": 89.0 * load_scale},
                                                 band(21)]},
                                 {"components": [{"type": "half_sine", "start": 0.5, "end": 5.5,
                                                  "peak": 44.5 * load_scale}, band(22)]}]},
        "output": {"strains": ["ex70", "gxy1"]},
    }


#: thesis sensor sets.  Case 2's components are shown only in a figure; we read the thesis'
#: "XY" subscripts as g_xy at nodes 2 and 100 (the gauges case 3 keeps) and take e_x at node 58.
TH_CASE1 = ["acc:12:w", "acc:58:w", "acc:100:w"]
TH_CASE2 = ["strain:2:gxy", "strain:58:ex", "strain:100:gxy"]
TH_CASE3 = ["strain:2:gxy", "strain:100:gxy", "acc:12:w"]
#: case 4 ("arbitrary"): e_x at 23, e_y at 103 and an accelerometer at node 2 -- node 2 lies on
#: the clamped edge, where an accelerometer records exactly zero, so only the two gauges inform
TH_CASE4 = ["strain:23:ex", "strain:103:ey"]


EXAMPLES = {
    "s17-case1": s17_job("s17-case1", "S17 case 1: accelerations only, zero-mean loads, no model error, "
                      "negligible noise (undetectable: run with --allow-undetectable)", S17_ACC_ONLY,
                      slow=False, model_error=False, noise=False),
    "s17-case2": s17_job("s17-case2", "S17 case 2: accelerations only, slowly varying loads, 5 % model error, "
                      "2 % noise (undetectable: drifts; run with --allow-undetectable)", S17_ACC_ONLY),
    "s17-case3": s17_job("s17-case3", "S17 case 3: strains only (members 4, 5, 9, 12, 13, 16, 21, 24, 26)",
                      S17_STRAIN_ONLY),
    "s17-case4": s17_job("s17-case4", "S17 case 4: multi-metric (accelerations at 4, 6, 8, 12 vertical and 6 "
                      "horizontal; strains in members 5, 9, 13, 26)", S17_MULTI),
    "th-case2": th_job("th-case2", "TH case 2: strains at nodes 2 (g_xy), 58 (e_x), 100 (g_xy)", TH_CASE2),
    "th-case3": th_job("th-case3", "TH case 3d: g_xy at nodes 2 and 100, acceleration at node 12, "
                    "model error and noise", TH_CASE3),
}
for _name in ("s17-case1", "s17-case2"):
    EXAMPLES[_name]["filter"]["steady"] = False  # the steady-state filter does not exist for them


def example_job(name):
    """A deep copy of the built-in job ``name`` (see :data:`EXAMPLES`)."""
    from .exceptions import AKFInputError

    if name not in EXAMPLES:
        raise AKFInputError(f"unknown example {name!r}; available: {', '.join(sorted(EXAMPLES))}")
    return copy.deepcopy(EXAMPLES[name])
