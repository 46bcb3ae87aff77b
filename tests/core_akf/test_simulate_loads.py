"""Simulation, noise models, load generators and metrics against independent references.

Tolerances: two ZOH implementations (block exponential vs scipy) agree to the accuracy of the
matrix exponential (~1e-13 here), asserted at 1e-10; a 500-step simulation accumulates at most
500 times that (1e-8).  Statistical checks (noise levels from 1e3-2e4 samples) use the sampling
error of a standard deviation, ~1 / sqrt(2N): 5 % and 2 %.
"""
import numpy as np
import pytest
import scipy.signal

from core_akf import loads as L
from core_akf.metrics import average_strain_error, rms_error
from core_akf.models import s17_truss, th_plate
from core_akf.simulate import G0, noise_levels, simulate
from core_akf.statespace import continuous, observation, zoh


def test_zoh_matches_scipy_cont2discrete():
    s = s17_truss()
    A_c, B_c = continuous(s, ["4:y", "12:y"])
    A, B = zoh(A_c, B_c, 1 / 4096)
    Ad, Bd, *_ = scipy.signal.cont2discrete((A_c, B_c, np.eye(A_c.shape[0]), 0), 1 / 4096, method="zoh")
    assert np.allclose(A, Ad, rtol=1e-10, atol=1e-12)
    assert np.allclose(B, Bd, rtol=1e-10, atol=1e-14 * np.abs(Bd).max())


def test_simulation_matches_scipy_dlsim():
    s = s17_truss()
    sensors = ["strain:13", "acc:8:y", "vel:6:y", "disp:4:y"]
    forces = ["8:y", "12:y"]
    dt = 1 / 2048
    rng = np.random.default_rng(4)
    loads = rng.normal(0, 300, (500, 2))
    sim = simulate(s, sensors, forces, loads, dt)
    A_c, B_c = continuous(s, forces)
    G, D = observation(s, sensors, forces)
    _, y, _ = scipy.signal.dlsim(scipy.signal.cont2discrete((A_c, B_c, G, D), dt, method="zoh"), loads)
    assert np.allclose(sim.clean, y, rtol=1e-8, atol=1e-10 * np.abs(y).max(axis=0))
    # no noise requested -> measurements are the clean readings
    assert np.array_equal(sim.measurements, sim.clean)


def test_static_limit_of_simulation():
    """A slowly applied, then held load settles at the static solution K u = f."""
    s = s17_truss()
    dt = 1 / 512
    t = np.arange(5 * 512) * dt
    load = L.ramp(t, 0.0, 1.0, -10e3)[:, None]
    sim = simulate(s, ["strain:1", "disp:8:y"], ["8:y"], load, dt)
    f = np.zeros(s.n)
    f[s.dof_index(8, "y")] = -10e3
    u = np.linalg.solve(s.K, f)
    # 4 s after the ramp the 0.7 %-damped first mode has decayed to ~exp(-0.007 * 2 pi f1 * 4) < 5e-3
    assert sim.clean[-1, 1] == pytest.approx(u[s.dof_index(8, "y")], rel=5e-3)
    assert sim.strains[-1, 0] == pytest.approx(s.strain_operator[0] @ u, rel=5e-3)


def test_relative_and_absolute_noise_levels():
    clean = np.column_stack([np.full(1000, 2e-6), np.sin(np.linspace(0, 20, 1000))])
    sensors = ["strain:5", "acc:4:y"]
    std = noise_levels(clean, sensors, relative=0.02)
    assert std == pytest.approx([0.02 * 2e-6, 0.02 * np.sqrt(np.mean(clean[:, 1] ** 2))])
    std = noise_levels(clean, sensors, absolute={"strain": 1e-6, "acc": 1e-3 * G0})
    assert std == pytest.approx([1e-6, 9.80665e-3])
    with pytest.raises(ValueError, match="no level for sensor kind"):
        noise_levels(clean, sensors, absolute={"strain": 1e-6})


def test_noise_is_seeded_and_has_the_requested_level():
    s = s17_truss()
    loads = np.random.default_rng(0).normal(0, 500, (4000, 1))
    a = simulate(s, ["strain:13", "acc:8:y"], ["8:y"], loads, 1 / 2048, relative_noise=0.05, seed=7)
    b = simulate(s, ["strain:13", "acc:8:y"], ["8:y"], loads, 1 / 2048, relative_noise=0.05, seed=7)
    c = simulate(s, ["strain:13", "acc:8:y"], ["8:y"], loads, 1 / 2048, relative_noise=0.05, seed=8)
    assert np.array_equal(a.measurements, b.measurements)
    assert not np.array_equal(a.measurements, c.measurements)
    noise = a.measurements - a.clean
    assert np.std(noise, axis=0) == pytest.approx(a.noise_std, rel=0.05)
    assert a.noise_std == pytest.approx(0.05 * np.sqrt(np.mean(a.clean ** 2, axis=0)))


def test_band_limited_white_noise():
    dt, n = 1 / 1000, 8000
    x = L.band_limited_white_noise(n, dt, rms=3.0, f_low=20.0, f_high=80.0, seed=1)
    assert np.sqrt(np.mean(x ** 2)) == pytest.approx(3.0)
    spec = np.abs(np.fft.rfft(x)) ** 2
    f = np.fft.rfftfreq(n, dt)
    inside = (f >= 20) & (f <= 80)
    assert spec[~inside].sum() < 1e-20 * spec[inside].sum()
    assert np.array_equal(x, L.band_limited_white_noise(n, dt, 3.0, 20.0, 80.0, seed=1))
    with pytest.raises(ValueError, match="Nyquist"):
        L.band_limited_white_noise(n, dt, 1.0, 0, 600.0)


def test_deterministic_loads():
    t = np.arange(0, 2, 0.001)
    p = L.half_sine_pulse(t, 0.5, 0.01, 1e4)
    assert p.max() == pytest.approx(1e4, rel=1e-3) and p[t < 0.5].max() == 0 and p[t > 0.511].max() == 0
    # impulse of a half-sine pulse: 2 peak duration / pi (on a fine grid)
    tf = np.arange(0, 1, 1e-5)
    assert np.sum(L.half_sine_pulse(tf, 0.5, 0.01, 1e4)) * 1e-5 == pytest.approx(2 * 1e4 * 0.01 / np.pi, rel=1e-3)
    r = L.ramp(t, 0.5, 1.5, 89.0)
    assert r[t <= 0.5].max() == 0 and r[-1] == 89.0 and r[np.searchsorted(t, 1.0)] == pytest.approx(44.5)
    h = L.half_sine(t, 0.5, 1.5, 44.5)
    assert h.max() == pytest.approx(44.5) and h[0] == 0 and h[-1] == 0
    assert np.std(L.white_noise(20000, 2.0, seed=3)) == pytest.approx(2.0, rel=0.02)


def test_modal_damping_gives_the_requested_ratio_on_every_mode():
    s = s17_truss(damping=0.007)
    lam = np.linalg.eigvals(continuous(s, ["8:y"])[0])
    zeta = -lam.real / np.abs(lam)
    assert np.allclose(zeta, 0.007, rtol=1e-6)
    p = th_plate(damping=0.01).reduce(10)
    lam = np.linalg.eigvals(continuous(p, ["121:w"])[0])
    assert np.allclose(-lam.real / np.abs(lam), 0.01, rtol=1e-6)


def test_rayleigh_damping():
    s = s17_truss(damping=("rayleigh", 0.5, 1e-5))
    assert np.allclose(s.C, 0.5 * s.M + 1e-5 * s.K)
    w = 2 * np.pi * s.frequencies()
    lam = np.linalg.eigvals(continuous(s, ["8:y"])[0])
    zeta = np.sort(-lam.real / np.abs(lam))
    expected = np.sort(np.repeat(0.5 / (2 * w) + 1e-5 * w / 2, 2))
    assert np.allclose(zeta, expected, rtol=1e-6)


def test_metrics():
    ref = np.zeros((4, 2))
    est = np.array([[1.0, 2.0], [1.0, 2.0], [-1.0, 2.0], [-1.0, 2.0]])
    assert rms_error(est, ref) == pytest.approx([1.0, 2.0])
    assert average_strain_error(est, ref) == pytest.approx(1.5)
    with pytest.raises(ValueError, match="differ in shape"):
        rms_error(est, ref[:3])


def test_modal_march_is_exact_on_a_stiff_two_mode_model():
    """Two oscillators, 30 Hz and 300 kHz (the thesis plate's spread), 1 % damping, under a step:
    the simulated samples equal the closed-form step response to rounding.  (Their stiffness is
    diagonal, so the frequencies are exact numbers: with a coupled K the slow frequency itself is
    only defined to eps x the stiffness ratio, 1e-8 here.)"""
    from core_akf.models.matrices import from_matrices

    w = 2 * np.pi * np.array([30.0, 3e5])
    s = from_matrices(np.diag(w ** 2), np.eye(2), [(1, "x"), (2, "x")], {1: (0.0, 0.0), 2: (1.0, 0.0)},
                      damping=0.01)
    dt, N, F = 5e-4, 400, np.array([1e3, -2e3])
    sim = simulate(s, ["disp:1:x", "disp:2:x"], ["1:x", "2:x"], np.tile(F, (N, 1)), dt)
    t = np.arange(N)[:, None] * dt
    zeta = 0.01
    wd = w * np.sqrt(1 - zeta ** 2)
    exact = F / w ** 2 * (1 - np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta * w / wd * np.sin(wd * t)))
    assert np.max(np.abs(sim.clean - exact) / (np.abs(F) / w ** 2)) < 1e-12


def test_non_classical_damping_is_simulated_by_the_whole_state_zoh():
    """A damper between two masses (not proportional): no modal march, the same answer as scipy."""
    from core_akf.models.matrices import from_matrices

    K = np.array([[2e4, -1e4], [-1e4, 1e4]])
    C = np.array([[30.0, 0.0], [0.0, 0.0]])
    s = from_matrices(K, np.eye(2), [(1, "x"), (2, "x")], {1: (0.0, 0.0), 2: (1.0, 0.0)}, C=C)
    loads = np.random.default_rng(2).normal(0, 10, (300, 1))
    sim = simulate(s, ["disp:1:x", "acc:2:x"], ["2:x"], loads, 1e-3)
    A_c, B_c = continuous(s, ["2:x"])
    G, D = observation(s, ["disp:1:x", "acc:2:x"], ["2:x"])
    _, y, _ = scipy.signal.dlsim(scipy.signal.cont2discrete((A_c, B_c, G, D), 1e-3, method="zoh"), loads)
    assert np.allclose(sim.clean, y, rtol=1e-9, atol=1e-10 * np.abs(y).max(axis=0))
