"""Modal filter models with static correction (core_akf.filter.model)."""
import numpy as np
import pytest

from core_akf.filter import FilterModel, estimate
from core_akf.filter.kernels import steady_outputs
from core_akf.models import s17_truss, th_plate
from core_akf.simulate import simulate
from core_akf.statespace import force_selection


@pytest.mark.parametrize("n_modes", [None, 20, 6])
def test_static_correction_gives_exact_static_strains(n_modes):
    """Under constant forces the reduced, statically corrected model's equilibrium strains equal
    the full model's K^-1 strains exactly, however few modes are kept."""
    s = th_plate()
    forces = ["121:w", "111:w"]
    fm = FilterModel(s, forces, 1 / 2000, n_modes)
    f = np.array([30.0, -12.0])
    n = fm.n_states
    A, B = fm.A_a[:n, :n], fm.A_a[:n, n:]
    x = np.linalg.solve(np.eye(n) - A, B @ f)
    strains = fm.strain_rows() @ np.r_[x, f]
    exact = s.strain_operator @ np.linalg.solve(s.K, force_selection(s, forces) @ f)
    # Both sides solve a static problem with the mass-normalised stiffness, condition number
    # kappa = (omega_max / omega_min)^2 = 2.9e8: each is accurate to eps * kappa = 6.4e-8 relative
    # to the largest strain (measured 1e-9 normwise, up to 9e-8 on small components, depending on
    # the BLAS kernel).  The tolerance is that bound on the largest strain.
    omega = s.eigen[0]
    atol = np.finfo(float).eps * (omega[-1] / omega[0]) ** 2 * np.abs(exact).max()
    np.testing.assert_allclose(strains, exact, rtol=0, atol=atol)
    G = fm.observation(["strain:2:gxy", "strain:58:ex"])
    np.testing.assert_allclose(G @ np.r_[x, f], exact[[s.strain_labels.index("strain:2:gxy"), s.strain_labels.index("strain:58:ex")]],
                               rtol=0, atol=atol)
    # and the correction is not vacuous: without it, few modes miss the static strains by far more
    if n_modes is not None:
        uncorrected = fm.strain_rows()[:, :n] @ x
        assert np.abs(uncorrected - exact).max() > 1e3 * atol


def test_steady_outputs_equal_estimate_on_the_full_model():
    s = s17_truss()
    sensors, forces, dt = ["acc:4:y", "strain:5", "strain:13"], ["4:y", "8:y"], 1 / 1024
    rng = np.random.default_rng(0)
    loads = rng.normal(size=(600, 2)) * 100
    sim = simulate(s, sensors, forces, loads, dt, relative_noise=0.02, seed=1)
    R = np.diag(sim.noise_std ** 2)
    est = estimate(s, sensors, forces, sim.measurements, dt, model_error_cov=1e-16, force_increment_cov=1e4,
                   noise_cov=R, steady=True)
    fm = FilterModel(s, forces, dt)
    out = steady_outputs(fm.A_a, fm.observation(sensors)[None], fm.Q_a(1e-16, 1e4), R[None],
                         sim.measurements[None], fm.strain_rows())
    # the same steady filter through two code paths (modal model vs estimate()); the DARE
    # solutions agree to ~1e-10 and the strains through the stiff truss (condition ~1e3) to 1e-7
    np.testing.assert_allclose(out[0], est.strains, rtol=1e-7, atol=1e-9 * np.abs(est.strains).max())


def test_residual_noise_is_the_dropped_modes_stationary_response():
    """``FilterModel.residual_noise``: the pairwise closed form equals the stationary
    covariance of the dropped modes under the model-error noise, from Smith's doubling on the
    whole dropped block (an independent route), at strain, acceleration, displacement and
    velocity sensors; it scales with q, and is zero for the full model."""
    from core_akf.covariances import state_covariance
    from core_akf.filter.riccati import stein_doubling
    from core_akf.statespace import modal_state_transform, modal_zoh, observation

    s = s17_truss()
    sensors = ["strain:5", "acc:6:y", "disp:8:y", "vel:12:y"]
    k, dt = 20, 1e-3
    fm = FilterModel(s, ["8:y"], dt, k)
    got = fm.residual_noise(sensors, 1e-12)
    n = s.n
    T, T_inv = modal_state_transform(s)
    A = modal_zoh(s, fm.forces, dt)[0]
    Qm = T_inv @ state_covariance(s, 1.0) @ T_inv.T
    drop = np.r_[np.arange(k, n), n + np.arange(k, n)]
    sigma = stein_doubling(A[np.ix_(drop, drop)], 0.5 * (Qm + Qm.T)[np.ix_(drop, drop)], tol=1e-17, max_iter=200)
    C = (observation(s, sensors, fm.forces)[0] @ T)[:, drop]
    ref = 1e-12 * C @ sigma @ C.T
    assert np.all(np.abs(got - ref) <= 1e-9 * np.sqrt(np.outer(np.diag(ref), np.diag(ref))))
    assert np.all(np.diag(got) > 0)
    assert np.allclose(fm.residual_noise(sensors, 2e-12), 2 * got, rtol=1e-12)
    assert not FilterModel(s, ["8:y"], dt).residual_noise(sensors, 1e-12).any()
