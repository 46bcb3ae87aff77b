"""Built-in impact scenarios following IMP (Saleem & Jo 2019) §4.

* ``imp-truss-case1``: the S17 truss, 7 strain gauges + 3 vertical accelerometers; 4 gauges are
  AD in every split (35 splits).  IMP names gauges 9, 13, 14, 22 (the AD set of its Fig. 3);
  the other three gauges and the accelerometer joints are ours.
* ``imp-truss-case2``: 7 vertical accelerometers + 3 gauges; 4 accelerometers AD (35 splits).
* ``imp-plate``: the 5 x 5 cantilever plate (nodes 6, 12, ..., 36 clamped), 3 accelerometers and
  7 gauges (e_x or e_y), 4 gauges AD; IMP names gauges at nodes 3, 7, 11, 23.

The impact: a 10 kN (truss) / 1 kN (plate) half-sine pulse of 4 ms at 0.98 s on top of
low-level random excitation (band-limited noise, 50 N / 5 N RMS) at the same location,
perpendicular (truss: vertical).  Records of 1.5 s at 1 kHz.  Noise: absolute (1 µε and
1 mg) or 10 % of each channel's RMS.  The filter's model equals the simulating one (IMP
mentions no model error); ``stiffness_factor`` adds one.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core_akf.exceptions import AKFInputError
from core_akf.loads import band_limited_white_noise, half_sine_pulse, time_grid
from core_akf.models import imp_plate, s17_truss
from core_akf.simulate import MG, MICROSTRAIN, simulate

TRUSS_CASE1 = ([f"strain:{m}" for m in (5, 9, 13, 14, 22, 26, 30)]
               + [f"acc:{j}:y" for j in (6, 10, 15)])
TRUSS_CASE2 = ([f"acc:{j}:y" for j in (3, 5, 8, 10, 12, 15, 16)]
               + [f"strain:{m}" for m in (9, 14, 22)])
PLATE_SENSORS = (["strain:3:ex", "strain:7:ey", "strain:11:ex", "strain:23:ey", "strain:17:ex", "strain:29:ey",
                  "strain:34:ex"] + ["acc:1:w", "acc:19:w", "acc:33:w"])

EXAMPLES = {
    "imp-truss-case1": dict(model="truss", sensors=TRUSS_CASE1, n_ad=4, ad_kinds=("strain",), impact_node=14,
                            direction="y", peak=10e3, background=50.0),
    "imp-truss-case2": dict(model="truss", sensors=TRUSS_CASE2, n_ad=4, ad_kinds=("acc",), impact_node=14,
                            direction="y", peak=10e3, background=50.0),
    "imp-plate": dict(model="plate", sensors=PLATE_SENSORS, n_ad=4, ad_kinds=("strain",), impact_node=21,
                      direction="w", peak=1e3, background=5.0),
}
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


def example_structure(name):
    spec = EXAMPLES[_check(name)]
    return s17_truss() if spec["model"] == "truss" else imp_plate()


def _check(name):
    if name not in EXAMPLES:
        raise AKFInputError(f"unknown impact example {name!r}; available: {', '.join(EXAMPLES)}")
    return name


def example_scenario(name, impact_node=None, noise="abs", seed=0, duration=1.5, dt=1e-3, impact_time=0.98):
    """Simulate the built-in example ``name`` with the impact at ``impact_node`` (default the
    paper's node) and ``noise`` "abs" (1 µε, 1 mg) or "rel10" (10 % of each channel's RMS)."""
    spec = EXAMPLES[_check(name)]
    if noise not in NOISE:
        raise AKFInputError(f"noise must be one of {NOISE}, got {noise!r}")
    structure = example_structure(name)
    node = spec["impact_node"] if impact_node is None else int(impact_node)
    from .scan import candidate_locations

    loc = candidate_locations(structure, spec["direction"], [node])[0]
    n = int(round(duration / dt))
    if not 0 < impact_time < duration:
        raise AKFInputError(f"impact_time {impact_time} s must lie inside the {duration} s record")
    t = time_grid(n, dt)
    force = (half_sine_pulse(t, impact_time, 0.004, spec["peak"])
             + band_limited_white_noise(n, dt, spec["background"], 0.0, 100.0, seed=1000 + seed))
    kw = ({"absolute_noise": {"strain": MICROSTRAIN, "acc": MG}} if noise == "abs" else {"relative_noise": 0.10})
    sim = simulate(structure, spec["sensors"], [loc], force[:, None], dt, seed=seed, **kw)
    return ImpactScenario(name, structure, list(spec["sensors"]), dt, sim.measurements, force, loc, spec["n_ad"],
                          tuple(spec["ad_kinds"]), spec["direction"], sim)
