"""Impacts to try the method on: a half-sine pulse at one location of a structure, read by its
sensors with noise (IMP §4: 4 ms pulses, noise of 1 microstrain and 1 mg)."""
from __future__ import annotations

from typing import TYPE_CHECKING

from core_akf.checks import ForceSpec, Layout, Seed
from core_akf.loads import half_sine_pulse, time_grid
from core_akf.simulate import MG, MICROSTRAIN, Simulation, simulate

if TYPE_CHECKING:
    from core_akf.structure import Structure


def simulate_impact(structure: Structure, sensors: Layout, location: ForceSpec, *, peak: float = 1e4,
                    duration: float = 0.004, start: float = 0.3, record: float = 0.6, dt: float = 1e-3,
                    noise: dict[str, float] | None = None, seed: Seed = 0) -> Simulation:
    """The record of a half-sine impact at one location.

    Parameters
    ----------
    structure : Structure
        The true structure.
    sensors : sequence of sensor specs
        The installed layout.
    location : str or (int, str)
        Where the impact hits (``"14:y"``).
    peak : float
        Peak force (N).
    duration : float
        Length of the pulse (s).
    start : float
        Time the pulse starts (s).
    record : float
        Length of the record (s).
    dt : float
        Time step (s).
    noise : dict, optional
        Noise standard deviation per sensor kind (SI); default 1 microstrain and 1 mg (IMP).
    seed : int or numpy.random.Generator
        The noise draw.

    Returns
    -------
    Simulation
        Its ``measurements`` (N, m) are the record; ``loads[:, 0]`` the true force (N).

    Examples
    --------
    >>> from core_akf.models import s17_truss
    >>> sim = simulate_impact(s17_truss(), ["strain:13", "acc:8:y"], "14:y")
    >>> sim.measurements.shape, float(sim.loads.max())
    ((600, 2), 10000.0)
    """
    t = time_grid(int(round(record / dt)), dt)
    force = half_sine_pulse(t, start, duration, peak)[:, None]
    levels = {"strain": MICROSTRAIN, "acc": MG} if noise is None else noise
    return simulate(structure, sensors, [location], force, dt, absolute_noise=levels, seed=seed)
