"""Missing samples (NaN) in every filter path, against statsmodels (an independent Kalman filter and
smoother that handles NaN natively) and against the same filter on the record without holes."""
import numpy as np
import pytest

from core_akf import estimate, simulate
from core_akf.checks import AKFInputError
from core_akf.filter import Estimator, Filter, filter_states, kernels, smooth
from core_akf.filter.riccati import steady_gain
from core_akf.filter.streaming import CheckpointError
from core_akf.models import s17_truss
from core_akf.sensors import as_layout, parse_force_locations

SENSORS = ["strain:13", "strain:26", "acc:8:y"]
FORCES = ["8:y"]
DT = 1e-3
COV = dict(model_error_cov=1e-16, force_increment_cov=1e4)


def _setup(R):
    s = s17_truss().scaled(1.05)
    return Filter(s, [as_layout(SENSORS)], parse_force_locations(s, FORCES), DT, model_error_cov=COV["model_error_cov"],
                  force_increment_cov=COV["force_increment_cov"], noise_cov=R)


def _record(n=1500, seed=0):
    rng = np.random.default_rng(seed)
    loads = 200.0 * rng.standard_normal((n, 1)).cumsum(axis=0) / np.sqrt(n)
    sim = simulate(s17_truss(), SENSORS, FORCES, loads, DT, relative_noise=0.02, seed=seed)
    return sim.measurements, np.diag(sim.noise_std ** 2), loads


def _holes(Y, fraction, seed, longest=40):
    """Random blocks of missing samples, one channel each, until ``fraction`` of the samples are gone."""
    rng, Y = np.random.default_rng(seed), Y.copy()
    while np.isnan(Y).mean() < fraction:
        j, a = rng.integers(Y.shape[1]), rng.integers(0, Y.shape[0] - longest)
        Y[a:a + rng.integers(1, longest), j] = np.nan
    return Y


def _statsmodels(f, Y, P0, smooth=False):
    from statsmodels.tsa.statespace.kalman_smoother import KalmanSmoother

    n, m = f.A_a.shape[0], Y.shape[1]
    kf = KalmanSmoother(k_endog=m, k_states=n, initialization="known", initial_state=np.zeros(n), initial_state_cov=P0)
    kf.bind(Y)
    kf["design"], kf["transition"], kf["selection"] = f.G_a[0], f.A_a, np.eye(n)
    kf["state_cov"], kf["obs_cov"] = f.Q_a, f.R[0]
    return kf.smooth() if smooth else kf.filter()


@pytest.fixture(scope="module")
def gappy():
    Y, R, loads = _record()
    Yn = _holes(Y, 0.08, 1)
    Yn[700:760, :] = np.nan                           # every channel: pure prediction
    Yn[300:500, 2] = np.nan                           # the accelerometer dead for 0.2 s
    return Y, Yn, R, loads


def test_the_time_varying_filter_through_holes_is_statsmodels(gappy):
    _, Yn, R, _ = gappy
    f = _setup(R)
    ours = filter_states(f.A_a, f.G_a, f.Q_a, f.R, Yn[None], steady=False, loglik=True)
    ref = _statsmodels(f, Yn, f.Q_a)
    assert ours.loglik[0] == pytest.approx(ref.llf, rel=1e-9)
    np.testing.assert_allclose(ours.loglik_terms[0].sum(axis=1), ref.llf_obs, rtol=1e-8,
                               atol=1e-9 * np.abs(ref.llf_obs).max())
    X = ours.states[0]
    np.testing.assert_allclose(X, ref.filtered_state.T, rtol=0, atol=1e-9 * np.abs(X).max())
    assert np.isnan(ours.innovations[0][np.isnan(Yn)]).all() and not np.isnan(ours.innovations[0][~np.isnan(Yn)]).any()


def test_the_smoother_through_holes_is_statsmodels(gappy):
    _, Yn, R, _ = gappy
    f = _setup(R)
    ours = smooth(f.A_a, f.G_a[0], f.Q_a, f.R[0], Yn, covariances="diagonal")
    ref = _statsmodels(f, Yn, f.Q_a, smooth=True)
    X = ours.states
    np.testing.assert_allclose(X, ref.smoothed_state.T, rtol=0, atol=1e-8 * np.abs(X).max())
    var = np.diagonal(ref.smoothed_state_cov, axis1=0, axis2=1)
    np.testing.assert_allclose(ours.covariances, var, rtol=1e-6, atol=1e-9 * np.abs(var).max())
    # the force's band widens where nothing is observed
    force_std = ours.std[:, -1]
    assert force_std[730] > 3 * np.median(force_std)


def test_a_record_without_holes_takes_the_paths_it_took(gappy):
    Y, _, R, _ = gappy
    f = _setup(R)
    for steady in (False, True):
        a = filter_states(f.A_a, f.G_a, f.Q_a, f.R, Y[None], steady=steady)
        b = filter_states(f.A_a, f.G_a, f.Q_a, f.R, np.where(np.isnan(Y), 0, Y)[None], steady=steady)
        np.testing.assert_array_equal(a.states, b.states)


def test_the_steady_filter_through_holes_is_close_to_the_exact_one(gappy):
    Y, Yn, R, loads = gappy
    kw = dict(noise_cov=R, **COV)
    complete = estimate(s17_truss(), SENSORS, FORCES, Y, DT, steady=True, **kw)
    exact = estimate(s17_truss(), SENSORS, FORCES, Yn, DT, steady=False, **kw)
    fast = estimate(s17_truss(), SENSORS, FORCES, Yn, DT, steady=True, **kw)
    k0 = 100

    def err(est):
        return float(np.sqrt(np.mean((est.forces[k0:] - loads[k0:]) ** 2)))
    assert np.isfinite(fast.forces).all() and np.isfinite(exact.forces).all()
    print(err(complete), err(exact), err(fast))
    assert err(complete) < err(exact) < 2.5 * err(complete)          # 8 % of the samples and 60 steps gone
    assert err(fast) < 1.25 * err(exact)


@pytest.mark.parametrize("steady", [False, True])
def test_a_streamed_record_with_holes_is_the_whole(gappy, steady):
    _, Yn, R, _ = gappy
    kw = dict(noise_cov=R, steady=steady, **COV)
    whole = estimate(s17_truss(), SENSORS, FORCES, Yn, DT, **kw)
    stream = Estimator(s17_truss(), SENSORS, FORCES, DT, **kw)
    parts = [stream.update(Yn[a:b]) for a, b in [(0, 310), (310, 333), (333, 720), (720, 1500)]]
    forces = np.vstack([p.forces for p in parts])
    np.testing.assert_allclose(forces, whole.forces, rtol=0, atol=1e-8 * np.abs(whole.forces).max())
    loglik = sum(p.loglik for p in parts)
    assert loglik == pytest.approx(whole.loglik, rel=1e-9)


def test_a_dead_channel_gets_its_own_steady_gain_and_a_stream_agrees():
    Y, R, _ = _record(2000)
    Yn = Y.copy()
    Yn[600:1500, 0] = np.nan                          # strain:13 dead for 0.9 s: long enough for its own gain
    kw = dict(noise_cov=R, steady=True, **COV)
    whole = estimate(s17_truss(), SENSORS, FORCES, Yn, DT, **kw)
    stream = Estimator(s17_truss(), SENSORS, FORCES, DT, **kw)
    state = None
    forces = []
    for a in range(0, 2000, 250):                     # a checkpoint between every chunk
        if state is not None:
            stream = Estimator(s17_truss(), SENSORS, FORCES, DT, **kw).restore(state)
        forces.append(stream.update(Yn[a:a + 250]).forces)
        state = stream.state()
    np.testing.assert_allclose(np.vstack(forces), whole.forces, rtol=0, atol=1e-8 * np.abs(whole.forces).max())


def test_a_hole_whose_cached_gain_is_unstable_runs_the_exact_recursion():
    """strain:13 dead for 0.9 s: the gain of the two channels left from the complete layout's
    covariance is not a stable filter (spectral radius 1.019); the cached gains alone reached
    1.2e8 N here.  The steady filter runs the exact recursion through the hole instead."""
    Y, R, loads = _record(2000)
    Yn = Y.copy()
    Yn[600:1500, 0] = np.nan
    f = _setup(R)
    P, _ = steady_gain(f.A_a[None], f.G_a, f.Q_a[None], f.R)
    patterns = np.array([[False, True, True], [True, True, True]])
    G_p, R_p = kernels.masked(np.repeat(f.G_a, 2, 0), np.repeat(f.R, 2, 0), patterns)
    assert kernels._unstable_patterns(f.A_a, G_p, R_p, P[0]).tolist() == [True, False]
    kw = dict(noise_cov=R, **COV)
    exact = estimate(s17_truss(), SENSORS, FORCES, Yn, DT, steady=False, **kw)
    fast = estimate(s17_truss(), SENSORS, FORCES, Yn, DT, steady=True, **kw)
    hole = slice(600, 1500)
    scale = np.abs(loads).max()
    assert np.abs(fast.forces).max() < 1.05 * scale
    np.testing.assert_allclose(fast.forces[hole], exact.forces[hole], rtol=0, atol=1e-3 * scale)


def test_a_long_hole_with_nothing_observed_holds_its_gain_and_a_stream_agrees():
    """After an unstable pattern, 5 s with nothing observed: the recursion holds its gain after 256
    steps (lifted, not a step at a time), and a stream across it carries the hole's covariance."""
    Y, R, _ = _record(8000)
    Y[600:900, 0] = np.nan
    Y[900:6000, :] = np.nan
    kw = dict(noise_cov=R, **COV)
    exact = estimate(s17_truss(), SENSORS, FORCES, Y, DT, steady=False, **kw)
    whole = estimate(s17_truss(), SENSORS, FORCES, Y, DT, steady=True, **kw)
    scale = np.abs(exact.forces).max()
    assert np.abs(whole.forces).max() < 1.05 * scale
    np.testing.assert_allclose(whole.forces, exact.forces, rtol=0, atol=0.1 * scale)
    state, forces = None, []
    for a, b in [(0, 700), (700, 3000), (3000, 6100), (6100, 8000)]:
        stream = Estimator(s17_truss(), SENSORS, FORCES, DT, steady=True, **kw)
        if state is not None:
            stream.restore(state)
        forces.append(stream.update(Y[a:b]).forces)
        state = stream.state()
    np.testing.assert_allclose(np.vstack(forces), whole.forces, rtol=0, atol=1e-8 * np.abs(whole.forces).max())


def test_a_checkpoint_with_a_bad_hole_covariance_is_refused():
    Y, R, _ = _record(400)
    Y[250:400, 0] = np.nan                             # to the end, shorter than a pattern's own gain
    stream = Estimator(s17_truss(), SENSORS, FORCES, DT, noise_cov=R, steady=True, **COV)
    stream.update(Y)
    state = stream.state()
    assert state["hole_P"].shape == (stream.filter.A_a.shape[0],) * 2      # the exact recursion carries on
    state["hole_P"] = np.full_like(state["hole_P"], np.nan)
    with pytest.raises(CheckpointError, match="hole covariance"):
        Estimator(s17_truss(), SENSORS, FORCES, DT, noise_cov=R, steady=True, **COV).restore(state)


def test_diagnostics_count_the_holes(gappy):
    _, Yn, R, _ = gappy
    est = estimate(s17_truss(), SENSORS, FORCES, Yn, DT, noise_cov=R, steady=False, **COV)
    d = est.diagnostics()
    for j, row in enumerate(d):
        assert row["missing_fraction"] == pytest.approx(np.isnan(Yn[:, j]).mean())
        assert np.isfinite(row["consistency"]) and np.isfinite(row["loglik"])
    assert d[2]["longest_missing_s"] >= 0.2 - 1e-12
    summary = est.summary()
    assert {"missing_fraction", "missing_spans", "longest_missing_s"} <= set(summary.columns)


def test_bad_records_are_still_refused():
    Y, R, _ = _record(200)
    kw = dict(noise_cov=R, **COV)
    bad = Y.copy()
    bad[5, 1] = np.inf
    with pytest.raises(AKFInputError, match="infinite"):
        estimate(s17_truss(), SENSORS, FORCES, bad, DT, **kw)
    with pytest.raises(AKFInputError, match="no observed sample"):
        estimate(s17_truss(), SENSORS, FORCES, np.full_like(Y, np.nan), DT, **kw)
    text = Y.astype(object)
    text[3, 0] = "12 ue"
    with pytest.raises(AKFInputError, match="numeric"):
        estimate(s17_truss(), SENSORS, FORCES, text, DT, **kw)


def test_calibration_learns_from_a_record_with_holes():
    from core_akf.calibration import calibrate
    from core_akf.loads import band_limited_white_noise

    loads = band_limited_white_noise(2000, 1e-3, 200.0, 0, 50, seed=1)
    sim = simulate(s17_truss(), SENSORS, FORCES, loads[:, None], DT, relative_noise=0.02, seed=0)
    Y = _holes(sim.measurements, 0.05, 0, longest=30)
    fit = calibrate(s17_truss().scaled(1.05), SENSORS, FORCES, Y, DT, parameters=["stiffness_factor"],
                    model_error_cov=1e-16, force_increment_cov=1e3, noise_cov=np.diag(sim.noise_std ** 2))
    assert 1.05 * fit.values["stiffness_factor"] == pytest.approx(1.0, abs=3e-3)      # measured 0.9998
    assert fit.loglik_after > fit.loglik_before
