"""The log-likelihood of a run (issue 21, item 1): the exact Gaussian log-likelihood of the
innovations, ``-1/2 sum_k (m log 2 pi + log det S_k + e_k^T S_k^-1 e_k)``, for the time-varying
and the steady filter, batched and streamed, checked against statsmodels' KalmanFilter (an
independent implementation) on the same matrices."""
import numpy as np
import pytest

from core_akf import estimate, simulate
from core_akf.filter import Estimator, Filter, estimate_batch, filter_states
from core_akf.models import s17_truss
from core_akf.sensors import as_layout, parse_force_locations

SENSORS = ["strain:13", "strain:26", "acc:8:y"]
FORCES = ["8:y"]
DT = 1e-3
COV = dict(model_error_cov=1e-16, force_increment_cov=1e4)


def _record(n=400, seed=0):
    rng = np.random.default_rng(seed)
    loads = 200.0 * rng.standard_normal((n, 1)).cumsum(axis=0) / np.sqrt(n)
    sim = simulate(s17_truss(), SENSORS, FORCES, loads, DT, relative_noise=0.02, seed=seed)
    return sim.measurements, np.diag(sim.noise_std ** 2)


def _statsmodels_loglik(A, G, Q, R, Y, P0):
    """statsmodels' Kalman filter (a test extra) on the same matrices, initial state 0 with covariance P0."""
    from statsmodels.tsa.statespace.kalman_filter import KalmanFilter

    n, m = A.shape[0], G.shape[0]
    kf = KalmanFilter(k_endog=m, k_states=n, initialization="known", initial_state=np.zeros(n),
                      initial_state_cov=P0)
    kf.bind(np.asarray(Y))
    kf["design"], kf["transition"], kf["selection"] = G, A, np.eye(n)
    kf["state_cov"], kf["obs_cov"] = Q, R
    res = kf.filter()
    return res.llf, res.llf_obs


def _setup(R):
    s = s17_truss().scaled(1.05)
    layout = as_layout(SENSORS)
    return Filter(s, [layout], parse_force_locations(s, FORCES), DT, model_error_cov=COV["model_error_cov"],
                  force_increment_cov=COV["force_increment_cov"], noise_cov=R)


@pytest.mark.parametrize("steady", [False, True])
def test_loglik_equals_an_independent_kalman_filter(steady):
    Y, R = _record()
    setup = _setup(R)
    res = filter_states(setup.A_a, setup.G_a, setup.Q_a, setup.R, Y[None], steady=steady, loglik=True)
    P0 = setup.Q_a if not steady else res.P_prior[0]
    ref, ref_steps = _statsmodels_loglik(setup.A_a, setup.G_a[0], setup.Q_a, setup.R[0], Y, P0)
    ours = res.loglik_terms[0]
    assert ours.sum() == pytest.approx(ref, rel=1e-9)
    np.testing.assert_allclose(ours.sum(axis=1), ref_steps, rtol=1e-8, atol=1e-9 * np.abs(ref_steps).max())


def test_the_estimate_carries_its_loglik_and_the_channels_sum_to_it():
    Y, R = _record()
    est = estimate(s17_truss().scaled(1.05), SENSORS, FORCES, Y, DT, noise_cov=R, steady=False, **COV)
    assert est.loglik_channels.shape == (3,)
    assert est.loglik_channels.sum() == pytest.approx(est.loglik, rel=1e-12)
    setup = _setup(R)
    ref, _ = _statsmodels_loglik(setup.A_a, setup.G_a[0], setup.Q_a, setup.R[0], Y, setup.Q_a)
    assert est.loglik == pytest.approx(ref, rel=1e-9)


def test_batched_logliks_are_those_of_single_runs():
    Y, R = _record()
    Y2, _ = _record(seed=1)
    layouts = [SENSORS, ["strain:9", "strain:26", "acc:8:y"]]
    batch = estimate_batch(s17_truss(), layouts, FORCES, np.stack([Y, Y2]), DT, noise_cov=R, **COV)
    for layout, y, est in zip(layouts, (Y, Y2), batch):
        one = estimate(s17_truss(), layout, FORCES, y, DT, noise_cov=R, **COV)
        assert est.loglik == pytest.approx(one.loglik, rel=1e-10)


@pytest.mark.parametrize("steady", [False, True])
def test_a_streamed_record_has_the_loglik_of_the_whole(steady):
    Y, R = _record(600)
    model = s17_truss().scaled(1.05)
    whole = estimate(model, SENSORS, FORCES, Y, DT, noise_cov=R, steady=steady, **COV)
    est = Estimator(model, SENSORS, FORCES, DT, noise_cov=R, steady=steady, **COV)
    total = sum(est.update(Y[a:a + 170]).loglik for a in range(0, 600, 170))
    assert total == pytest.approx(whole.loglik, rel=1e-10)


def test_the_likelihood_points_at_the_true_stiffness():
    """S17: the record of the true truss is likelier under the true model than under one 5 %
    off either way (the premise of calibration by maximum likelihood)."""
    Y, R = _record(1500)
    ll = {f: estimate(s17_truss().scaled(f), SENSORS, FORCES, Y, DT, noise_cov=R, **COV).loglik
          for f in (0.95, 1.0, 1.05)}
    assert ll[1.0] > ll[0.95] and ll[1.0] > ll[1.05]


def test_a_channel_that_disagrees_has_the_lowest_loglik():
    """A gauge whose data are scaled by 3 (a wrong unit) loses the most likelihood."""
    Y, R = _record()
    bad = Y.copy()
    bad[:, 1] *= 3.0
    good = estimate(s17_truss(), SENSORS, FORCES, Y, DT, noise_cov=R, **COV).loglik_channels
    worse = estimate(s17_truss(), SENSORS, FORCES, bad, DT, noise_cov=R, **COV).loglik_channels
    assert np.argmax(good - worse) == 1
