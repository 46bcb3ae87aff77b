"""Forward simulation of the "true" structure: exact zero-order-hold response, sensor
readings and measurement noise (absolute levels or a percentage of each channel's RMS)."""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from .checks import ArrayLike, FloatArray, ForceHistories, Forces, Layout

if TYPE_CHECKING:
    from .structure import Structure
from .checks import AKFInputError, as_finite_array, as_seed, as_time_step
from .forcemodels import check_load_hold
from .sensors import MAX_READABLE, SENSOR_NAMES, UNITS, as_layout, parse_force_locations, readable_limits
from .statespace import continuous, foh, modal_blocks, modal_state_transform, observation, strain_feedthrough, zoh

#: standard gravity (m/s^2), for levels given in g or mg
G0 = 9.80665
#: one milli-g in m/s^2: ``absolute_noise={"acc": 1 * MG}``
MG = 1e-3 * G0
#: one micro-strain: ``absolute_noise={"strain": 1 * MICROSTRAIN}``
MICROSTRAIN = 1e-6
#: simulated noise above this many times a channel's RMS leaves nothing to measure: a typing slip
MAX_RELATIVE_NOISE = 10.0


@dataclass
class Simulation:
    """Simulated response of a structure to known loads.

    Attributes
    ----------
    structure : Structure
        The true structure.
    sensors : tuple of Sensor
        The layout, m channels.
    force_locations : list of (int, str)
    dt : float
        Time step (s).
    time : ndarray (N,)
        s.
    loads : ndarray (N, n_p)
        The applied forces (N).
    states : ndarray (N, 2n)
        ``[u; u']``.
    clean : ndarray (N, m)
        Noise-free sensor readings (SI).
    measurements : ndarray (N, m)
        The readings with noise (SI).
    noise_std : ndarray (m,)
        Noise standard deviation per channel.
    strains : ndarray (N, n_strain)
        The true strain at every output (m/m).
    """

    structure: object
    sensors: tuple
    force_locations: list
    dt: float
    loads: np.ndarray
    states: np.ndarray
    clean: np.ndarray
    measurements: np.ndarray
    noise_std: np.ndarray

    @property
    def time(self):
        return np.arange(self.loads.shape[0]) * self.dt

    @cached_property
    def strains(self):
        """True strains at every member/node component, shape (N, n_strain)."""
        out = self.states[:, : self.structure.n] @ self.structure.strain_operator.T
        extra = strain_feedthrough(self.structure, self.force_locations)
        return out if extra is None else out + self.loads @ extra.T

    def response(self, sensors: Layout) -> FloatArray:
        """Noise-free readings of any other sensors.

        Parameters
        ----------
        sensors : sequence of sensor specs
            k sensors on the structure.

        Returns
        -------
        ndarray (N, k)
            SI.
        """
        G, D = observation(self.structure, sensors, self.force_locations)
        return self.states @ G.T + self.loads @ D.T


def check_noise(relative, absolute, kinds, names=("relative noise", "absolute noise")):
    """Simulated noise levels checked: a relative level between 0 and :data:`MAX_RELATIVE_NOISE`,
    an absolute level for every sensor kind, each >= 0 and at most what such a sensor reads
    (:data:`~core_akf.sensors.MAX_READABLE`).

    Parameters
    ----------
    relative : float or None
        Fraction of each channel's RMS.
    absolute : dict or None
        Standard deviation per sensor kind (SI).
    kinds : set of str
        The sensor kinds of the layout.
    names : tuple of str
        What the two levels are called in messages (a job names its keys).
    """
    if relative is not None and not 0 <= relative <= MAX_RELATIVE_NOISE:
        raise AKFInputError(f"{names[0]} must be a fraction of each channel's RMS between 0 and "
                            f"{MAX_RELATIVE_NOISE:g} (0.02 = 2 %), got {relative:.4g}: noise that large leaves nothing "
                            "to measure")
    if absolute is None:
        return
    missing = sorted(set(kinds) - set(absolute))
    if missing:
        raise AKFInputError(f"{names[1]} has no level for sensor kind(s) {missing}")
    for k in sorted(kinds):
        if not 0 <= float(absolute[k]) <= MAX_READABLE[k]:
            raise AKFInputError(f"{names[1]} of {k} = {float(absolute[k]):.4g} {UNITS[k]}: a standard deviation must be "
                                f">= 0 and at most what such a sensor reads ({MAX_READABLE[k]:g} {UNITS[k]}); the "
                                "levels are in SI units")


def noise_levels(clean, sensors, relative=None, absolute=None):
    """Noise standard deviation per channel.

    Parameters
    ----------
    clean : ndarray (N, m)
        Noise-free readings (SI).
    sensors : sequence of Sensor
        The layout.
    relative : float, optional
        Fraction of each channel's RMS (0.02 = 2 %).
    absolute : dict, optional
        Standard deviations per sensor kind in SI units, e.g.
        ``{"strain": 1 * MICROSTRAIN, "acc": 1 * MG}``.  Both may be given (variances add).

    Returns
    -------
    ndarray (m,)
    """
    layout = as_layout(sensors)
    check_noise(relative, absolute, {s.kind for s in layout})
    std2 = np.zeros(len(layout))
    if relative is not None:
        std2 += (relative * np.sqrt(np.mean(clean ** 2, axis=0))) ** 2
    if absolute is not None:
        std2 += np.array([float(absolute[s.kind]) for s in layout]) ** 2
    return np.sqrt(std2)


def check_readable_response(clean, layout, loads, dt):
    """Refuse a simulated response that no sensor could read: beyond
    :data:`~core_akf.sensors.MAX_READABLE` for its kind (1 m/m of strain, 1e6 m/s^2, ...) or not
    finite -- loads typed far too large (1e300, kN for N), named with their peak.

    Parameters
    ----------
    clean : ndarray (N, m)
        Noise-free readings (SI).
    layout : list of Sensor
    loads : ndarray (N, n_p)
        The force histories (N).
    dt : float
        Step (s).
    """
    if clean.size == 0:
        return
    with np.errstate(invalid="ignore"):
        beyond = ~(np.abs(clean) <= readable_limits(layout))
    if not beyond.any():
        return
    k, j = np.unravel_index(int(np.argmax(beyond)), beyond.shape)
    s = layout[j]
    with np.errstate(invalid="ignore"):
        peak = float(np.max(np.abs(loads))) if loads.size else 0.0
    raise AKFInputError(f"the simulated response at {s.label} reaches {clean[k, j]:.4g} {UNITS[s.kind]} at step {k} "
                        f"(t = {k * dt:.6g} s), beyond what {SENSOR_NAMES[s.kind]} reads (|x| <= {MAX_READABLE[s.kind]:g} "
                        f"{UNITS[s.kind]}): the loads (peak {peak:.4g} N) are far too large for this structure ("
                        "loads are in N)")


def simulate(structure: Structure, sensors: Layout, forces: Forces, loads: ForceHistories, dt: float, *,
             relative_noise: float | None = None, absolute_noise: dict[str, float] | None = None,
             seed: int | None = None, x0: ArrayLike | None = None, load_hold: str = "zero") -> Simulation:
    """Simulate the structure under known loads and read the sensors.

    Parameters
    ----------
    structure : Structure
        The *true* structure (give the filter a different one to model error, e.g.
        ``structure.scaled(1.05)``).
    sensors : sequence of sensor specs
        The layout, m channels.
    forces : sequence of force specs
        Where the loads act (``"8:y"``), n_p locations.
    loads : ndarray (N, n_p)
        Force histories (N), the values at the steps.
    dt : float
        Step (s).
    relative_noise, absolute_noise
        See :func:`noise_levels`.
    seed : int or numpy.random.Generator, optional
        For the measurement noise.
    x0 : array_like (2n,), optional
        Initial state ``[u; u']`` (default at rest).
    load_hold : str
        How a load goes from one step to the next: ``"zero"`` (default) holds each sample
        constant over its step, as the filter assumes; ``"linear"`` goes linearly to the next
        sample (first-order hold, exact), a continuous load.  A stepped load excites the
        structure below its first mode several times more than a continuous one of the same
        samples, so a filter tested only on ``"zero"`` records looks better than it is.

    Returns
    -------
    Simulation

    Examples
    --------
    >>> import numpy as np
    >>> from core_akf.models import s17_truss
    >>> sim = simulate(s17_truss(), ["strain:13", "acc:8:y"], ["8:y"], np.ones((50, 1)), 1e-3,
    ...                relative_noise=0.02, seed=0)
    >>> sim.measurements.shape, sim.strains.shape
    ((50, 2), (50, 34))
    """
    layout = as_layout(sensors)
    dt = as_time_step(dt)
    locs = parse_force_locations(structure, forces)
    P = as_finite_array(loads, "loads", ndim=(1, 2))
    if P.ndim == 1:
        P = P[:, None]
    if P.shape[1] != len(locs):
        raise AKFInputError(f"loads have {P.shape[1]} columns for {len(locs)} force locations")
    G, D = observation(structure, layout, locs)
    nx = 2 * structure.n
    x = np.zeros(nx) if x0 is None else as_finite_array(x0, "x0", shape=(nx,))
    check_load_hold(load_hold)
    X = _march(structure, locs, P, float(dt), x, load_hold)
    with np.errstate(over="ignore", invalid="ignore"):
        clean = X @ G.T + P @ D.T
    check_readable_response(clean, layout, P, float(dt))
    std = noise_levels(clean, layout, relative_noise, absolute_noise)
    seed = as_seed(seed)
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    noisy = clean + rng.normal(size=clean.shape) * std
    return Simulation(structure, layout, locs, float(dt), P, X, clean, noisy, std)


def _march(structure, locs, P, dt, x, hold="zero"):
    """The states ``[u; u']`` (N, 2n) at the steps of the loads ``P`` (N, n_p) from ``x``.

    A classically damped structure is marched mode by mode (:func:`~core_akf.statespace.modal_blocks`:
    n decoupled 2 x 2 systems, O(N n) work, no exponential of size 2n), then taken back to
    ``[u; u']`` in one product; any other one by the ZOH of the whole state (O(N n^2)).  The two
    agree to rounding (``tests/test_simulate_loads.py``); on the 1011-DOF footbridge the modal
    march takes 0.8 s against 6.5 s.
    """
    N = P.shape[0]
    following = np.vstack([P[1:], P[-1:]])           # u_k+1 (the last step's is never used)
    parts = modal_blocks(structure, locs, dt, hold=hold)
    if parts is None:
        if hold == "linear":
            A, B0, B1 = foh(*continuous(structure, locs), dt)
            BP = P @ B0.T + following @ B1.T
        else:
            A, B = zoh(*continuous(structure, locs), dt)
            BP = P @ B.T
        X = np.empty((N, A.shape[0]))
        At = A.T
        for k in range(N):
            X[k] = x
            x = x @ At + BP[k]
        return X
    blocks, B_z = parts[:2]
    n = structure.n
    T, T_inv = modal_state_transform(structure)
    a, b, c, d = (blocks[:, i, j].copy() for i, j in ((0, 0), (0, 1), (1, 0), (1, 1)))
    Bq, Bv = P @ B_z[:n].T, P @ B_z[n:].T             # (N, n) each
    if hold == "linear":
        Bq += following @ parts[2][:n].T
        Bv += following @ parts[2][n:].T
    Zq, Zv = np.empty((N, n)), np.empty((N, n))
    z = T_inv @ x
    q, v = z[:n].copy(), z[n:].copy()
    for k in range(N):
        Zq[k], Zv[k] = q, v
        q, v = a * q + b * v + Bq[k], c * q + d * v + Bv[k]
    return np.hstack([Zq @ T[:n, :n].T, Zv @ T[n:, n:].T])     # T is block diagonal
