"""Robust standard errors (core_akf.inference) against statsmodels and analytical values, and
through calibration: near the observed-information ones when the model made the record, several
times larger, with a warning by name, when the force prior does not fit the loads."""
import numpy as np
import pytest

from core_akf import simulate
from core_akf.calibration import calibrate
from core_akf.checks import AKFInputError
from core_akf.filter.kernels import steady_logliks
from core_akf.forcemodels import ForceModel
from core_akf.inference import hac_bandwidth, information_ratio, long_run_covariance, sandwich_covariance
from core_akf.loads import band_limited_white_noise
from core_akf.models import s17_truss


def _ar1(phi, n, k=3, seed=0):
    rng = np.random.default_rng(seed)
    e = rng.normal(size=(n, k))
    x = np.zeros_like(e)
    for t in range(1, n):
        x[t] = phi * x[t - 1] + e[t]
    return x


@pytest.mark.parametrize("lags", [0, 5, 64, 65, 300])
def test_long_run_covariance_is_statsmodels_newey_west(lags):
    """Bartlett-weighted HAC: statsmodels' S_hac_simple of the centred scores, to 1e-12, by the
    lag loop (<= 64 lags) and by FFT (more)."""
    from statsmodels.stats.sandwich_covariance import S_hac_simple

    x = _ar1(0.8, 3000)
    ours = long_run_covariance(x, lags)
    theirs = S_hac_simple(x - x.mean(axis=0), nlags=lags)
    np.testing.assert_allclose(ours, theirs, rtol=1e-12, atol=1e-12 * np.abs(theirs).max())


def test_automatic_bandwidth_recovers_the_long_run_variance_of_an_ar1():
    """An AR(1) of coefficient 0.8: long-run variance 1 / (1 - 0.8)^2 = 25 per step; the Andrews
    bandwidth grows with the correlation, and white scores get (almost) none."""
    x = _ar1(0.8, 100000, k=1, seed=1)
    assert long_run_covariance(x)[0, 0] / x.shape[0] == pytest.approx(25.0, rel=0.1)
    assert hac_bandwidth(x) > 20 > 3 > hac_bandwidth(np.random.default_rng(2).normal(size=(100000, 1)))


def test_sandwich_gives_the_kurtosis_error_of_a_variance():
    """Laplace data fitted as Gaussian: the log-variance's robust error is sqrt((kurtosis - 1) / T)
    = sqrt(5 / T); the observed information gives sqrt(2 / T), 1.58x too small."""
    e = np.random.default_rng(3).laplace(size=400000)
    var = np.mean(e ** 2)
    scores = (e ** 2 / var - 1)[:, None] / 2
    robust = np.sqrt(sandwich_covariance([[e.size / 2]], scores)[0, 0])
    assert robust == pytest.approx(np.sqrt(5 / e.size), rel=0.05)
    assert information_ratio([np.sqrt(2 / e.size)], [robust])[0] == pytest.approx(np.sqrt(2.5), rel=0.05)
    assert np.isnan(information_ratio([0.0], [1.0])[0])


def test_bad_scores_are_refused():
    with pytest.raises(AKFInputError, match="not finite"):
        long_run_covariance(np.array([[1.0], [np.nan], [0.0]]))
    with pytest.raises(AKFInputError, match="at least 2 steps"):
        long_run_covariance(np.ones((1, 2)))
    with pytest.raises(AKFInputError, match="bandwidth"):
        long_run_covariance(np.ones((5, 1)), -1)


def test_per_step_logliks_sum_to_the_loglik_also_with_missing_samples():
    truss, dt = s17_truss(), 1e-3
    sensors = ["strain:13", "acc:6:y"]
    loads = band_limited_white_noise(600, dt, 300.0, 0, 100, seed=4)[:, None]
    sim = simulate(truss, sensors, ["8:y"], loads, dt, relative_noise=0.02, seed=5)
    from core_akf.filter import Filter

    f = Filter(truss, [sensors], ["8:y"], dt, model_error_cov=1e-16, force_increment_cov=1e4,
               noise_cov=np.diag(sim.noise_std ** 2))
    Y = sim.measurements.copy()
    Y[100:130, 0] = np.nan
    for record in (sim.measurements, Y):
        args = (np.repeat(f.A_a[None], 2, 0), np.repeat(f.G_a, 2, 0), np.repeat(f.Q_a[None], 2, 0),
                np.repeat(f.R, 2, 0), record)
        total, steps = steady_logliks(*args), steady_logliks(*args, per_step=True)
        assert steps.shape == (2, record.shape[0])
        np.testing.assert_allclose(steps.sum(axis=1), total, rtol=1e-12)


ACC = ["acc:2:y", "acc:3:y", "acc:4:y", "acc:5:y", "acc:6:y", "acc:7:y", "acc:8:y", "acc:10:y", "acc:12:y", "acc:6:x"]


def test_calibration_warns_by_name_when_the_noise_is_not_gaussian():
    """Gauges and an accelerometer whose noise is 5 % outliers at 5x the scale (kurtosis 20):
    the variance factors are right (within 3 robust errors of 1), the gauges' robust error is
    2.4-3.1x the observed-information one (sqrt((kurtosis - 1) / 2) = 3.1 for pure noise), and a
    warning names noise_cov:strain."""
    sensors, dt, n_steps = ["strain:5", "strain:9", "strain:13", "strain:26", "acc:6:y"], 1 / 1024, 8192
    loads = band_limited_white_noise(n_steps, dt, 500.0, 0, 100, seed=1)[:, None]
    sim = simulate(s17_truss(), sensors, ["8:y"], loads, dt, relative_noise=0.0, seed=0)
    rng = np.random.default_rng(2)
    std = 0.02 * np.sqrt(np.mean(sim.clean ** 2, axis=0))
    scale = np.where(rng.random((n_steps, len(sensors))) < 0.05, 5.0, 1.0) / np.sqrt(0.95 + 0.05 * 25)
    Y = sim.clean + rng.normal(size=(n_steps, len(sensors))) * scale * std
    fit = calibrate(s17_truss(), sensors, ["8:y"], Y, dt, parameters=["noise_cov"], model_error_cov=1e-22,
                    force_increment_cov=1e4, noise_cov=np.diag(std ** 2))
    for name in fit.multipliers:
        assert abs(np.log(fit.multipliers[name])) < 3 * fit.robust_std_errors[name]
    ratio = fit.robust_std_errors["noise_cov:strain"] / fit.std_errors["noise_cov:strain"]
    assert 2.4 < ratio < 3.1
    [warning] = [w for w in fit.warnings if "does not fit the record" in w]
    assert "(noise_cov:strain)" in warning and "non-Gaussian noise" in warning
    assert set(fit.to_dict()["robust_std_errors"]) == set(fit.std_errors)


def test_a_wrong_force_prior_biases_more_than_any_standard_error_shows():
    """Issue 34's case: ten accelerometers, two band-limited loads (0-120 Hz, 600 and 425 N) and a
    Matérn-3/2 prior learnt from 500 N and 2 ms.  ML moves to about 1400 N.  The robust error is
    larger than the observed one (its scores are correlated over >5 steps, against ~1 when the
    prior fits) but it measures the estimator's spread around what the wrong prior fits best: the
    loads' RMS stays more than 5 robust errors away.  No standard error can show a prior's bias
    (the docs say so; the Butterworth prior and OMA are the remedies)."""
    dt, n_steps, forces = 1 / 4096, 8192, ["6:y", "12:y"]
    loads = np.column_stack([band_limited_white_noise(n_steps, dt, r, 0, 120, seed=21 + j)
                             for j, r in enumerate((600.0, 425.0))])
    sim = simulate(s17_truss(), ACC, forces, loads, dt, relative_noise=0.02, seed=0)
    fit = calibrate(s17_truss(), ACC, forces, sim.measurements, dt, parameters=["force_std", "force_timescale"],
                    model_error_cov=1e-16, noise_cov=np.diag(sim.noise_std ** 2),
                    force_model=ForceModel("matern32", std=500.0, timescale=2e-3), method="time")
    ratio = information_ratio([fit.std_errors[n] for n in fit.multipliers],
                              [fit.robust_std_errors[n] for n in fit.multipliers])
    assert np.all(ratio > 1.2) and fit.hac_bandwidth > 5 and fit.method == "time"
    rms = float(np.sqrt(np.mean(loads ** 2)))
    assert fit.values["force_std"] > 1000 and np.log(fit.values["force_std"] / rms) > 5 * fit.robust_std_errors["force_std"]


def test_calibration_of_a_prior_that_fits_keeps_the_two_errors_close():
    """Loads drawn from the Matérn-3/2 prior itself: robust and observed errors within 1.5x of each
    other, scores hardly correlated, no misfit warning, and the truth within 3 robust errors."""
    dt, forces = 1 / 2048, ["6:y", "12:y"]
    loads = ForceModel("matern32", std=500.0, timescale=4e-3).sample(8192, dt, 2, seed=6)
    sim = simulate(s17_truss(), ACC[:5] + ["acc:6:x"], forces, loads, dt, relative_noise=0.02, seed=6)
    fit = calibrate(s17_truss(), ACC[:5] + ["acc:6:x"], forces, sim.measurements, dt,
                    parameters=["force_std", "force_timescale"], model_error_cov=1e-22,
                    noise_cov=np.diag(sim.noise_std ** 2), force_model=ForceModel("matern32", std=250.0, timescale=8e-3))
    ratio = information_ratio([fit.std_errors[n] for n in fit.multipliers],
                              [fit.robust_std_errors[n] for n in fit.multipliers])
    assert np.all((ratio > 1 / 1.5) & (ratio < 1.5)) and fit.hac_bandwidth < 5
    assert not [w for w in fit.warnings if "does not fit" in w]
    for name, true in (("force_std", 2.0), ("force_timescale", 0.5)):
        assert abs(np.log(fit.multipliers[name] / true)) < 3 * fit.robust_std_errors[name]
