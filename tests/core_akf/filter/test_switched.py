"""The switched fixed-gain filter (a record with missing samples or mixed rates): its lifted and
chunked paths against the plain step-by-step recursion, and the periodic steady gains of a record
whose slow channels sample every p-th step against the exact (time-varying) filter."""
import numpy as np
import pytest

from core_akf import estimate, simulate
from core_akf.filter import Estimator, Filter, kernels
from core_akf.filter.kernels import sampling_period
from core_akf.filter.switched import LIFT_FROM, switched_filter
from core_akf.models import s17_truss
from core_akf.sensors import as_layout, parse_force_locations

SENSORS = ["strain:13", "strain:26", "acc:8:y", "acc:6:y"]
FORCES = ["8:y"]
DT = 1e-3
COV = dict(model_error_cov=1e-16, force_increment_cov=1e4)


def _loop(A, G, L, which, Y0, x):
    """The recursion one step at a time: x_k = (I - L_i G_i) A x_k-1 + L_i y_k."""
    F = (np.eye(A.shape[0]) - L @ G) @ A
    X = np.empty((len(which), A.shape[0]))
    X[0] = x - L[which[0]] @ (G[which[0]] @ x) + L[which[0]] @ Y0[0]
    for k in range(1, len(which)):
        X[k] = F[which[k]] @ X[k - 1] + L[which[k]] @ Y0[k]
    return X


def _system(seed, n=10, m=3, gains=5):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A *= 0.9 / np.abs(np.linalg.eigvals(A)).max()
    G, L = rng.normal(size=(gains, m, n)), 0.02 * rng.normal(size=(gains, n, m))
    return A, G, L, rng


def _sequences(rng, N=3000, gains=5):
    stretches = np.repeat(rng.integers(0, gains, 300), rng.integers(1, 40, 300))[:N]
    cycle = np.tile([0, 1, 1, 1, 2, 1, 1, 1], N // 8)
    mixed = cycle.copy()
    mixed[700:1300] = 3                                        # a long stretch of one gain (lifted)
    mixed[2000:2005] = 4                                       # breaks the cycle for a moment
    return {"random": (rng.integers(0, gains, N), 1), "stretches": (stretches, 1),
            "cycle of 8": (cycle, 8), "cycle, a long stretch, a break": (mixed, 8),
            "one step": (np.array([2]), 1), "two steps": (np.array([2, 0]), 1),
            "one gain": (np.full(N, 3), 1)}


@pytest.mark.parametrize("name", list(_sequences(np.random.default_rng(0))))
def test_the_switched_filter_is_the_step_by_step_recursion(name):
    A, G, L, rng = _system(1)
    which, period = _sequences(rng)[name]
    Y0, x = rng.normal(size=(len(which), G.shape[1])), rng.normal(size=A.shape[0])
    expected = _loop(A, G, L, which, Y0, x)
    got = switched_filter(A, G, L, which, Y0, x, period)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("name", ["random", "stretches", "cycle, a long stretch, a break", "one step"])
def test_steps_with_gains_used_once_run_one_at_a_time_and_are_the_recursion(name):
    """Gains from ``fixed`` on (the exact recursion through a hole) run without their ``F``."""
    A, G, L, rng = _system(2)
    which, period = _sequences(rng)[name]
    which = which.copy()
    which[(np.arange(len(which)) % 7 == 0) | (which == 4)] = 4       # gain 4: steps one at a time
    Y0, x = rng.normal(size=(len(which), G.shape[1])), rng.normal(size=A.shape[0])
    expected = _loop(A, G, L, which, Y0, x)
    got = switched_filter(A, G, L, which, Y0, x, period, fixed=4)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12 * np.abs(expected).max())


def test_sampling_period():
    seen = np.ones((960, 3), bool)
    assert sampling_period(seen) == 1
    seen[np.arange(960) % 4 != 0, 1] = False
    seen[np.arange(960) % 6 != 0, 2] = False
    assert sampling_period(seen) == 12
    seen[480, 1] = False                                       # a hole in a slow channel keeps its rate
    assert sampling_period(seen) == 12
    holes = np.ones((960, 2), bool)
    holes[np.random.default_rng(0).random((960, 2)) < 0.05] = False
    assert sampling_period(holes) == 1
    slow = np.ones((960, 1), bool)
    slow[np.arange(960) % 300 != 0] = False
    assert sampling_period(slow) == 300
    assert sampling_period(slow, longest=256) == 1             # a cycle longer than asked for


def _mixed(n=3000, every=8, seed=0, sensors=SENSORS):
    """Strain gauges every ``every``-th step, accelerometers every step."""
    rng = np.random.default_rng(seed)
    loads = 200.0 * rng.standard_normal((n, 1)).cumsum(axis=0) / np.sqrt(n)
    sim = simulate(s17_truss(), sensors, FORCES, loads, DT, relative_noise=0.02, seed=seed)
    Y = sim.measurements.copy()
    slow = [i for i, s in enumerate(sensors) if s.startswith("strain")]
    Y[np.ix_(np.arange(n) % every != 0, slow)] = np.nan
    return Y, np.diag(sim.noise_std ** 2)


def test_a_mixed_rate_record_gets_the_periodic_steady_gains_of_the_exact_filter():
    Y, R = _mixed()
    kw = dict(noise_cov=R, **COV)
    exact = estimate(s17_truss(), SENSORS, FORCES, Y, DT, steady=False, **kw)
    fast = estimate(s17_truss(), SENSORS, FORCES, Y, DT, steady=True, **kw)
    late = slice(2500, None)                                   # the exact filter's covariance has converged
    scale = np.abs(exact.forces[late]).max()
    np.testing.assert_allclose(fast.forces[late], exact.forces[late], rtol=0, atol=1e-6 * scale)
    np.testing.assert_allclose(fast.strains[late], exact.strains[late], rtol=0,
                               atol=1e-6 * np.abs(exact.strains[late]).max())


def test_a_mixed_rate_record_runs_the_exact_recursion_only_until_its_cycle_is_known(monkeypatch):
    """The record starts with a hole, so its first steps run the exact covariance recursion; once
    the cycle has come round twice its periodic gains take over.  Without them the recursion runs
    through the whole record: as exact, at the time-varying filter's cost."""
    Y, R = _mixed()
    kw = dict(noise_cov=R, **COV)
    steps, hole_gains = [], kernels._hole_gains

    def counting(*args):
        steps.append(int(args[6].sum()))                       # the steps marked for the recursion
        return hole_gains(*args)

    monkeypatch.setattr(kernels, "_hole_gains", counting)
    exact = estimate(s17_truss(), SENSORS, FORCES, Y, DT, steady=False, **kw)
    estimate(s17_truss(), SENSORS, FORCES, Y, DT, steady=True, **kw)
    assert 0 < steps[-1] <= 2 * 8
    monkeypatch.setattr(kernels, "sampling_period", lambda seen, longest=0: 1)
    per_pattern = estimate(s17_truss(), SENSORS, FORCES, Y, DT, steady=True, **kw)
    assert steps[-1] > len(Y) - 10
    late = slice(2500, None)
    np.testing.assert_allclose(per_pattern.forces[late], exact.forces[late], rtol=0,
                               atol=1e-6 * np.abs(exact.forces[late]).max())


@pytest.mark.parametrize("every, n", [(16, 3000), (256, 6000)])
def test_slow_gauges_alone_stay_stable(every, n):
    """Two gauges sampled every 16th (or 256th) step, nothing in between: the complete layout's gain
    applied once per cycle overshoots -- the filter diverged at 16, and was 2x off at 256; the
    periodic gain is the exact one."""
    sensors = SENSORS[:2]
    Y, R = _mixed(n=n, every=every, sensors=sensors)
    kw = dict(noise_cov=R, **COV)
    exact = estimate(s17_truss(), sensors, FORCES, Y, DT, steady=False, **kw)
    fast = estimate(s17_truss(), sensors, FORCES, Y, DT, steady=True, **kw)
    assert np.abs(fast.forces).max() < 1.1 * np.abs(exact.forces).max()
    late = slice(n - 500, None)
    np.testing.assert_allclose(fast.forces[late], exact.forces[late], rtol=0, atol=1e-6 * np.abs(exact.forces).max())


def _broken(n=6000, every=16):
    """Gauges every ``every``-th step with 40 holes of up to 60 steps in the accelerometers (the
    cycle broken) and a gauge dead for 0.4 s."""
    Y, R = _mixed(n=n, every=every)
    rng = np.random.default_rng(3)
    for _ in range(40):
        j, a = rng.integers(2, 4), rng.integers(0, n - 100)
        Y[a:a + rng.integers(1, 60), j] = np.nan
    Y[n // 2:n // 2 + 400, 0] = np.nan
    return Y, R


def test_a_mixed_rate_record_with_holes_stays_with_the_exact_filter():
    """Holes in the accelerometers break the gauges' cycle; the cached gains alone grew to 1e81 N
    here.  Through a broken cycle the filter runs the exact covariance recursion."""
    Y, R = _broken()
    kw = dict(noise_cov=R, **COV)
    exact = estimate(s17_truss(), SENSORS, FORCES, Y, DT, steady=False, **kw)
    fast = estimate(s17_truss(), SENSORS, FORCES, Y, DT, steady=True, **kw)
    scale = np.abs(exact.forces).max()
    assert np.abs(fast.forces).max() < 1.01 * scale
    late = slice(500, None)                                    # after the exact filter's start
    np.testing.assert_allclose(fast.forces[late], exact.forces[late], rtol=0, atol=0.05 * scale)
    assert np.sqrt(np.mean((fast.forces[late] - exact.forces[late]) ** 2)) < 0.005 * scale


def test_a_mixed_rate_record_with_holes_streamed_and_resumed_is_the_whole():
    Y, R = _broken()
    kw = dict(noise_cov=R, steady=True, **COV)
    whole = estimate(s17_truss(), SENSORS, FORCES, Y, DT, **kw)
    state, forces, bounds = None, [], [0, 333, 700, 1543, 3100, 3200, 4711, 6000]
    for a, b in zip(bounds[:-1], bounds[1:]):
        stream = Estimator(s17_truss(), SENSORS, FORCES, DT, **kw)
        if state is not None:
            stream.restore(state)
        forces.append(stream.update(Y[a:b]).forces)
        state = stream.state()
    np.testing.assert_allclose(np.vstack(forces), whole.forces, rtol=0, atol=1e-8 * np.abs(whole.forces).max())


@pytest.mark.parametrize("every, n, cuts", [(8, 3000, [200, 613, 1999]), (256, 4000, [100, 700, 1000, 2900])])
def test_a_streamed_mixed_rate_record_is_the_whole(every, n, cuts):
    Y, R = _mixed(n=n, every=every)
    kw = dict(noise_cov=R, steady=True, **COV)
    whole = estimate(s17_truss(), SENSORS, FORCES, Y, DT, **kw)
    stream = Estimator(s17_truss(), SENSORS, FORCES, DT, **kw)
    state, forces, bounds = None, [], [0] + cuts + [n]
    for a, b in zip(bounds[:-1], bounds[1:]):
        if state is not None:
            stream = Estimator(s17_truss(), SENSORS, FORCES, DT, **kw).restore(state)
        forces.append(stream.update(Y[a:b]).forces)
        state = stream.state()
    np.testing.assert_allclose(np.vstack(forces), whole.forces, rtol=0, atol=1e-8 * np.abs(whole.forces).max())


def test_a_long_stretch_is_lifted_and_still_the_recursion():
    """One S17 filter, its steady gain and the per-pattern gains of a record with holes: the lifted
    stretches and chunks give the step-by-step recursion."""
    s = s17_truss().scaled(1.05)
    Y, R = _mixed(n=2 * LIFT_FROM + 500)
    f = Filter(s, [as_layout(SENSORS)], parse_force_locations(s, FORCES), DT, noise_cov=R, **COV)
    P, L = kernels.steady_gain(f.A_a[None], f.G_a, f.Q_a[None], f.R)
    seen = ~np.isnan(Y)
    seen[:LIFT_FROM + 100] = True                              # a long complete stretch first
    Y0 = np.where(seen, np.nan_to_num(Y, nan=1e-6), 0.0)
    assert np.isfinite(Y0).all()
    patterns, which = kernels._patterns(seen)
    G_p, R_p = kernels.masked(np.broadcast_to(f.G_a[0], (len(patterns),) + f.G_a.shape[1:]),
                              np.broadcast_to(f.R[0], (len(patterns),) + f.R.shape[1:]), patterns)
    S = kernels.innovation_covariance(G_p, P[0], R_p)
    gains = np.swapaxes(np.linalg.solve(S, G_p @ P[0]), -1, -2)
    x = np.zeros(f.A_a.shape[0])
    expected = _loop(f.A_a, G_p, gains, which, Y0, x)
    got = switched_filter(f.A_a, G_p, gains, which, Y0, x, sampling_period(seen))
    assert np.isfinite(expected).all() and np.abs(expected).max() > 0
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-10 * np.abs(expected).max())
