"""The Whittle likelihood (core_akf.whittle) and calibration's choice of likelihood (``method``).

The output spectrum is checked against the whole model's transfer function and against the
steady filter's own Riccati solution (Szegő: the mean log-determinant of the spectrum is the log-
determinant of the innovation covariance); the fit against issue 34's cases: band-limited loads
(the Whittle fit, chosen by default, recovers the forces where the time-domain one does not) and
loads drawn from the prior (the time-domain fit, chosen by default, recovers sigma and ell)."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import scipy.signal

from core_akf import estimate, simulate
from core_akf.calibration import AUTO_SIGNAL_FRACTION, calibrate
from core_akf.checks import AKFInputError
from core_akf.filter.kernels import steady_gain
from core_akf.filter.model import Filter
from core_akf.forcemodels import ForceModel
from core_akf.loads import band_limited_white_noise
from core_akf.models import s17_truss
from core_akf.whittle import TAPER, output_spectrum, signal_bins, stationary, tukey, welch_density, whittle_terms

ACC = ["acc:2:y", "acc:3:y", "acc:4:y", "acc:5:y", "acc:6:y", "acc:7:y", "acc:8:y", "acc:10:y", "acc:12:y", "acc:6:x"]
FORCES = ["6:y", "12:y"]
DT, N = 1 / 4096, 8192


def _filter(force_model, sensors=ACC[:5]):
    return Filter(s17_truss(), [sensors], FORCES, DT, model_error_cov=1e-16, noise_cov=1e-2 * np.eye(len(sensors)),
                  steady=True, force_model=force_model)


MODELS = [ForceModel("matern32", std=500.0, timescale=4e-3),               # a defective (Jordan) force block
          ForceModel("matern12", std=300.0, timescale=1e-3, hold="linear"),
          ForceModel("butterworth", std=400.0, band=[20.0, 150.0], band_order=4)]


@pytest.mark.parametrize("model", MODELS, ids=["matern32", "matern12-linear", "butterworth-bandpass"])
def test_output_spectrum_is_the_whole_models_transfer_function(model):
    """``G (zI - A)^-1 Q (.)^H G^T + R`` from the structure's eigenvectors and the force blocks equals
    the same product with the whole augmented matrix inverted, at any frequency, to 1e-10."""
    f = _filter(model)
    A, G, Q, R = f.A_a, f.G_a[0], f.Q_a, f.R[0]
    assert stationary(A, f.nx)
    omega = np.array([1e-3, 0.05, 0.2, 0.9, 2.0, 3.1])
    S = output_spectrum(A, G, Q, R, f.nx, omega)
    for k, w in enumerate(omega):
        H = G @ np.linalg.inv(np.exp(1j * w) * np.eye(A.shape[0]) - A)
        direct = H @ Q @ H.conj().T + R
        np.testing.assert_allclose(S[k], direct, rtol=0, atol=1e-10 * np.abs(direct).max())


def test_output_spectrum_agrees_with_the_filters_riccati_and_lyapunov_solutions():
    """Two identities of a stationary spectrum, each through another solver: the mean of
    ``log det S`` over the unit circle is ``log det`` of the steady filter's innovation covariance
    (Szegő-Kolmogorov; the Riccati solution), and the mean of ``S`` is the output's covariance
    ``G P G^T + R`` (P from the discrete Lyapunov equation)."""
    f = _filter(MODELS[0])
    A, G, Q, R = f.A_a, f.G_a[0], f.Q_a, f.R[0]
    n_grid = 2 ** 16
    omega = 2 * np.pi * (np.arange(n_grid // 2) + 0.5) / n_grid
    S = np.concatenate([output_spectrum(A, G, Q, R, f.nx, omega[i:i + 8192]) for i in range(0, omega.size, 8192)])
    P, _ = steady_gain(A[None], G[None], Q[None], R[None])
    innovations = G @ P[0] @ G.T + R
    assert np.mean(np.linalg.slogdet(S)[1]) == pytest.approx(np.linalg.slogdet(innovations)[1], abs=1e-9)
    P_stat = scipy.linalg.solve_discrete_lyapunov(A, Q)
    np.testing.assert_allclose(np.real(S).mean(axis=0), G @ P_stat @ G.T + R, rtol=1e-6)


def test_signal_bins_are_where_the_record_stands_above_its_noise():
    """White noise alone has (almost) no signal bin at a ratio of 10 and every bin at 0; a 100 Hz
    tone in it gives the bins around 100 Hz."""
    rng = np.random.default_rng(0)
    Y = rng.normal(0.0, 1.0, (N, 2))
    assert signal_bins(Y, [1.0, 1.0]).fraction < 0.01
    everything = signal_bins(Y, [1.0, 1.0], ratio=0.0)
    assert everything.fraction == 1.0 and everything.omega.size == N // 2 - 1
    Y[:, 1] += 5.0 * np.sin(2 * np.pi * 100.0 * DT * np.arange(N))
    bins = signal_bins(Y, [1.0, 1.0])
    hz = bins.frequencies / DT
    assert bins.omega.size > 0 and np.all(np.abs(hz - 100.0) < 10.0)
    window = scipy.signal.windows.tukey(N, TAPER)
    tapered = np.fft.rfft((Y - Y.mean(axis=0)) * window[:, None], axis=0) * np.sqrt(N / np.sum(window ** 2))
    np.testing.assert_allclose(bins.coefficients, tapered[np.round(hz * N * DT).astype(int)])
    # the taper's scaling keeps |y_k|^2 / N the spectrum: 1 for unit white noise
    assert np.mean(np.abs(everything.coefficients) ** 2) / N == pytest.approx(1.0, abs=0.03)


@pytest.mark.parametrize("N", [1, 2, 5, 100, 101, 8192])
@pytest.mark.parametrize("fraction", [0.0, 0.2, 0.5, 1.0])
def test_tukey_is_scipys(N, fraction):
    np.testing.assert_allclose(tukey(N, fraction), scipy.signal.windows.tukey(N, fraction), atol=1e-14)


def _band_record(hold="zero", seed=0):
    """Issue 34's case: two band-limited loads (0-120 Hz, 600 and 425 N RMS), ten accelerometers."""
    loads = np.column_stack([band_limited_white_noise(N, DT, r, 0, 120, seed=21 + j + 10 * seed)
                             for j, r in enumerate((600.0, 425.0))])
    sim = simulate(s17_truss(), ACC, FORCES, loads, DT, relative_noise=0.02, seed=seed, load_hold=hold)
    return loads, sim, np.diag(sim.noise_std ** 2)


def _smoothed_errors(sim, R, loads, force_model):
    """The smoothed forces' RMS error over the loads' RMS, per force, and the drift (the error of the
    last quarter over that of the second)."""
    est = estimate(s17_truss(), ACC, FORCES, sim.measurements, DT, model_error_cov=1e-16, noise_cov=R,
                   force_model=force_model, smooth=True)
    e, q = est.forces - loads, N // 4
    rms = lambda x: np.sqrt(np.mean(x ** 2, axis=0))   # noqa: E731
    return rms(e) / rms(loads), rms(e[3 * q:]) / rms(e[q:2 * q])


@pytest.mark.parametrize("N, segment", [(1000, 256), (1001, 255), (8192, 4096), (100, 100), (37, 16)])
def test_welch_density_is_scipys_welch(N, segment):
    """The signal bins' Welch estimate (written here: importing scipy.signal costs 0.8 s of every
    calibration) against scipy.signal.welch, even and odd segments, one segment and several."""
    import scipy.signal

    Y = np.random.default_rng(N).normal(size=(N, 3)) * [1.0, 1e-6, 1e3]
    freq, P = scipy.signal.welch(Y, fs=1.0, nperseg=segment, axis=0, detrend=False)
    got_freq, got = welch_density(Y, segment)
    np.testing.assert_array_equal(got_freq, freq)
    np.testing.assert_allclose(got, P, rtol=1e-12, atol=0)


def test_band_limited_loads_are_fitted_by_the_whittle_likelihood_by_default():
    """Issue 34's case from 500 N and 2 ms: 7 % of the bins hold signal, so the default picks the
    Whittle likelihood and says why; its smoothed forces are within 0.35 of the loads' RMS without
    drift, where the time-domain fit moves to about 1400 N and misses force 2 by 0.64."""
    loads, sim, R = _band_record()
    kw = dict(parameters=["force_std", "force_timescale"], model_error_cov=1e-16, noise_cov=R,
              force_model=ForceModel("matern32", std=500.0, timescale=2e-3))
    fit = calibrate(s17_truss(), ACC, FORCES, sim.measurements, DT, **kw)
    assert fit.method == "whittle" and "empty bins" in fit.method_reason
    assert 0 < float(fit.method_reason.split(" %")[0]) <= 100 * AUTO_SIGNAL_FRACTION / 4
    before, after = fit.whittle_loglik
    assert after > before and fit.to_dict()["method"] == "whittle"
    error, drift = _smoothed_errors(sim, R, loads, fit.force_model)
    assert np.all(error <= 0.35) and np.all(drift < 1.5)
    timed = calibrate(s17_truss(), ACC, FORCES, sim.measurements, DT, method="time", **kw)
    assert timed.method == "time" and timed.whittle_loglik is None and timed.values["force_std"] > 1000
    assert np.max(_smoothed_errors(sim, R, loads, timed.force_model)[0]) > 0.5
    # both errors from the Whittle fit's own curvature: finite, the robust ones wider under the wrong prior
    assert all(np.isfinite(fit.std_errors[n]) and fit.robust_std_errors[n] > fit.std_errors[n] for n in fit.multipliers)


@pytest.mark.parametrize("seed", [0, 2, 3])
def test_continuous_band_limited_loads_are_fitted_as_well_as_their_true_spectrum_allows(seed):
    """Continuous loads (``load_hold = "linear"``) from 500 N and 2 ms: the default Whittle fit's
    smoothed forces are within 0.35 of the loads' RMS and within 12 % of the error of the filter
    given the loads' true spectrum (a Butterworth prior of their band and RMS: what no prior can
    beat).  Before the periodogram was tapered, the leakage of the record's ends into its lowest
    bins took seed 3 to 30x the loads' std and a 42 ms time scale, its forces 7-11x the RMS off
    (seed 2: 0.51 for force 2, seed 0: 0.38)."""
    loads, sim, R = _band_record("linear", seed)
    fit = calibrate(s17_truss(), ACC, FORCES, sim.measurements, DT, parameters=["force_std", "force_timescale"],
                    model_error_cov=1e-16, noise_cov=R, force_model=ForceModel("matern32", std=500.0, timescale=2e-3,
                                                                              hold="linear"))
    assert fit.method == "whittle" and not any("bound" in w for w in fit.warnings)
    error, _ = _smoothed_errors(sim, R, loads, fit.force_model)
    rms = np.sqrt(np.mean(loads ** 2, axis=0))
    best, _ = _smoothed_errors(sim, R, loads, ForceModel("butterworth", std=rms.tolist(), band=[0.0, 120.0],
                                                           band_order=8, hold="linear"))
    assert np.all(error <= 0.35) and np.all(error <= 1.12 * best)


def test_the_whittle_fit_holds_the_force_prior_while_the_time_domain_fits_the_rest():
    """``noise_cov`` with the force prior: the prior from the Whittle likelihood (the same values as
    without noise_cov: the bins are chosen with the starting R), then R by the time-domain
    likelihood with the prior held, which it raises."""
    loads, sim, R = _band_record()
    kw = dict(model_error_cov=1e-16, force_model=ForceModel("matern32", std=500.0, timescale=2e-3))
    alone = calibrate(s17_truss(), ACC, FORCES, sim.measurements, DT, parameters=["force_std", "force_timescale"],
                      noise_cov=R, **kw)
    both = calibrate(s17_truss(), ACC, FORCES, sim.measurements, DT,
                     parameters=["force_std", "force_timescale", "noise_cov"], noise_cov=R, **kw)
    assert both.method == "whittle"
    for name in ("force_std", "force_timescale"):
        assert both.values[name] == alone.values[name]
    assert both.multipliers["noise_cov:acc"] != 1.0 and both.loglik_after > alone.loglik_after
    assert set(both.std_errors) == set(both.robust_std_errors) == set(both.multipliers)


def test_loads_drawn_from_the_prior_are_fitted_in_the_time_domain_by_default():
    """Matérn-3/2 loads (500 N, 4 ms) fill more than half the bins: the default keeps the time-domain
    likelihood (the efficient one when the prior fits), finds sigma and ell within 10 % from a factor
    2 off, and forces within 5 % of the error with the true hyperparameters."""
    true = ForceModel("matern32", std=500.0, timescale=4e-3)
    loads = true.sample(N, DT, 2, seed=1)
    sim = simulate(s17_truss(), ACC, FORCES, loads, DT, relative_noise=0.02, seed=1)
    R = np.diag(sim.noise_std ** 2)
    fit = calibrate(s17_truss(), ACC, FORCES, sim.measurements, DT, parameters=["force_std", "force_timescale"],
                    model_error_cov=1e-16, noise_cov=R, force_model=ForceModel("matern32", std=250.0, timescale=8e-3))
    assert fit.method == "time" and "fill the band" in fit.method_reason
    assert float(fit.method_reason.split(" %")[0]) > 100 * AUTO_SIGNAL_FRACTION
    assert fit.values["force_std"] == pytest.approx(500.0, rel=0.1)
    assert fit.values["force_timescale"] == pytest.approx(4e-3, rel=0.1)
    fitted, _ = _smoothed_errors(sim, R, loads, fit.force_model)
    best, _ = _smoothed_errors(sim, R, loads, true)
    assert np.all(fitted <= 1.05 * best)


def test_method_errors_and_fallbacks():
    """An unknown method, Whittle without a force parameter or on a record with holes: named errors.
    ``"auto"`` on a record with holes or under the random walk falls back to the time domain, saying why."""
    loads, sim, R = _band_record()
    kw = dict(model_error_cov=1e-16, noise_cov=R, force_model=ForceModel("matern32", std=500.0, timescale=2e-3))
    Y = sim.measurements[:2048]
    with pytest.raises(AKFInputError, match="unknown calibration method 'spectral'.*whittle"):
        calibrate(s17_truss(), ACC, FORCES, Y, DT, parameters=["force_std"], method="spectral", **kw)
    with pytest.raises(AKFInputError, match="Whittle likelihood fits a stationary force model's parameters"):
        calibrate(s17_truss(), ACC, FORCES, Y, DT, parameters=["noise_cov"], method="whittle", **kw)
    holes = Y.copy()
    holes[100:120, 3] = np.nan
    with pytest.raises(AKFInputError, match="cannot fit this record: the record has missing samples"):
        calibrate(s17_truss(), ACC, FORCES, holes, DT, parameters=["force_std"], method="whittle", **kw)
    fit = calibrate(s17_truss(), ACC, FORCES, holes, DT, parameters=["force_std"], **kw)
    assert fit.method == "time" and "missing samples" in fit.method_reason
    walk = calibrate(s17_truss(), ["strain:13", "strain:26", "acc:6:y"], ["6:y"],
                     simulate(s17_truss(), ["strain:13", "strain:26", "acc:6:y"], ["6:y"], loads[:2048, :1], DT,
                              relative_noise=0.02, seed=0).measurements, DT, parameters=["noise_cov"],
                     model_error_cov=1e-16, force_increment_cov=1e3, noise_cov=[1e-14, 1e-14, 1e-2])
    assert walk.method == "time" and "no force-model parameter" in walk.method_reason


def test_whittle_terms_refuse_a_spectrum_that_is_not_positive_definite():
    """A bin whose spectrum is not positive definite makes the likelihood -inf, not NaN."""
    bins = signal_bins(np.random.default_rng(1).normal(size=(256, 2)), [1.0, 1.0], ratio=0.0)
    S = np.broadcast_to(np.eye(2, dtype=complex), (bins.omega.size, 2, 2)).copy()
    assert np.isfinite(whittle_terms(S, bins)).all()
    S[3] = -S[3]
    assert np.all(whittle_terms(S, bins) == -np.inf)
