"""Large models (core_akf.models.sparse): the lowest modes of sparse K and M by shift-invert
Lanczos with a static correction for the others.  Checked against the dense model: frequencies,
the static response at every strain and displacement output (exact: the correction restores it),
the same through a stiffness scaling and a further reduction, and the model-error covariance
formed without a (2 n_phys)^2 matrix."""
import numpy as np
import pytest
import scipy.linalg
import scipy.sparse

from core_akf import estimate, simulate
from core_akf.checks import AKFInputError
from core_akf.covariances import state_covariance
from core_akf.models import from_matrices, plate, plate_matrices
from core_akf.models.plate import TH_PLATE
from core_akf.statespace import detectability, observation

ARGS = (12, 8, TH_PLATE["lx"], TH_PLATE["ly"], TH_PLATE["thickness"], TH_PLATE["E"], TH_PLATE["nu"], TH_PLATE["rho"])
SENSORS = ["strain:40:ex", "strain:77:ey", "strain:100:gxy", "disp:117:w", "acc:60:w", "vel:30:w"]
FORCES = ["117:w", "65:rx"]


@pytest.fixture(scope="module")
def plates():
    return plate(*ARGS), plate(*ARGS, n_modes=25)


def _static_outputs(structure, sensors, forces):
    """Outputs (m x n_p) of the static state under unit forces: G [K^-1 S_p; 0] + D."""
    G, D = observation(structure, sensors, forces)
    Sp = structure.dof_rows([(int(f.split(":")[0]), f.split(":")[1]) for f in forces]).T
    return G[:, :structure.n] @ np.linalg.solve(structure.K, Sp) + D


def test_sparse_reduction_has_the_dense_modes_and_the_exact_static_response(plates):
    dense, large = plates
    assert large.is_reduced and large.n == 25 and scipy.sparse.issparse(large.strain_matrix)
    np.testing.assert_allclose(large.frequencies(), dense.frequencies(25), rtol=1e-8)
    full = _static_outputs(dense, SENSORS, FORCES)
    red = _static_outputs(large, SENSORS, FORCES)
    scale = np.max(np.abs(full), axis=1, keepdims=True)
    assert np.all(np.abs(red - full)[:4] <= 1e-8 * scale[:4])   # strain and displacement, each to its own size
    D_acc = observation(large, SENSORS[4:5], FORCES)[1]           # the acceleration's direct feed-through
    assert np.all(np.abs(red[4:]) <= 1e-9 * np.max(np.abs(D_acc)))  # no static acceleration or velocity
    # without the correction the 25 modes miss part of the static strain
    plain = dense.reduce(25)
    assert np.max(np.abs(_static_outputs(plain, SENSORS[:3], FORCES) - full[:3]) / scale[:3]) > 1e-3
    # every strain output at once (Estimate.strains, Simulation.strains use it)
    from core_akf.statespace import strain_feedthrough
    H = strain_feedthrough(large, FORCES)
    Sp = large.dof_rows([(117, "w"), (65, "rx")]).T
    all_red = large.strain_operator @ np.linalg.solve(large.K, Sp) + H
    Spd = dense.dof_rows([(117, "w"), (65, "rx")]).T
    all_full = dense.strain_operator @ np.linalg.solve(dense.K, Spd)
    np.testing.assert_allclose(all_red, all_full, rtol=0, atol=1e-9 * np.max(np.abs(all_full)))


def test_scaling_and_further_reduction_keep_the_static_response(plates):
    dense, large = plates
    full = _static_outputs(dense.scaled(1.05, 0.9), SENSORS[:4], FORCES)
    for model in (large.scaled(1.05, 0.9), large.scaled(1.05, 0.9).reduce(10), large.reduce(10).scaled(1.05, 0.9)):
        np.testing.assert_allclose(_static_outputs(model, SENSORS[:4], FORCES), full, rtol=1e-8,
                                   atol=1e-12 * np.max(np.abs(full)))
    np.testing.assert_allclose(large.scaled(1.05, 0.9).frequencies(10), dense.scaled(1.05, 0.9).frequencies(10),
                               rtol=1e-8)


def test_frequency_factors_keep_the_mode_shapes_and_the_static_response(plates):
    """Modes 2 and 3 moved by -4 % and +3 %: the same on the dense plate and on the sparse model
    reduced with a static correction, which keeps the static response of the changed K (also
    once reduced further, the changed modes dropped into the residual)."""
    dense, large = plates
    factors = [1.0, 0.96, 1.03]
    changed = dense.with_frequency_factors(factors)
    ratio = changed.frequencies(6) / dense.frequencies(6)
    # to 1e-7: the lowest mode's eigenvalue is 1e7 times below the largest, and K' carries round-off of
    # the largest (2e-9 under OPENBLAS_CORETYPE=Haswell)
    np.testing.assert_allclose(ratio, [1.0, 0.96, 1.03, 1.0, 1.0, 1.0], rtol=1e-7)
    np.testing.assert_allclose(np.abs(changed.modes(6)), np.abs(dense.modes(6)), atol=1e-8 * np.abs(dense.modes(6)).max())
    full = _static_outputs(changed, SENSORS[:4], FORCES)
    assert np.max(np.abs(full - _static_outputs(dense, SENSORS[:4], FORCES))) > 1e-3 * np.max(np.abs(full))
    for model in (large.with_frequency_factors(factors), large.with_frequency_factors(factors).reduce(2),
                  changed.reduce(10, static_correction=True)):
        np.testing.assert_allclose(_static_outputs(model, SENSORS[:4], FORCES), full, rtol=1e-7,
                                   atol=1e-10 * np.max(np.abs(full)))
    np.testing.assert_allclose(large.with_frequency_factors(factors).frequencies(6), changed.frequencies(6), rtol=1e-7)


@pytest.mark.parametrize("factors, message", [([], "one per mode"), ([1.0, -0.9], "positive"), ([np.nan], "positive"),
                                              ([[1.0]], "one per mode"), ([1.0] * 400, "one per mode")])
def test_frequency_factors_refuse_bad_input(plates, factors, message):
    with pytest.raises(AKFInputError, match=message):
        plates[1].with_frequency_factors(factors)


def test_model_error_covariance_of_a_reduced_model_needs_no_physical_matrix(plates):
    _, large = plates
    P = large.projection
    n_phys = large.free_dofs.size
    q = np.linspace(1e-12, 3e-12, 2 * n_phys)
    for level in (2e-12, q):
        Q_phys = np.diag(np.broadcast_to(level, (2 * n_phys,)))
        B = scipy.linalg.block_diag(P, P)
        want = B @ Q_phys @ B.T
        np.testing.assert_allclose(state_covariance(large, level), want, rtol=0, atol=1e-12 * np.max(np.abs(want)))
    with pytest.raises(AKFInputError, match="variances; expected"):
        state_covariance(large, q[:-1])


def test_estimate_on_a_large_model_sees_static_forces_through_the_correction(plates):
    """Strain gauges only: the reduced model with its static correction estimates a slow force as
    the dense model does; the PBH verdicts agree."""
    dense, large = plates
    sensors, forces = ["strain:40:ey", "strain:46:ey", "strain:50:ey"], ["117:w", "113:w"]
    assert detectability(large, sensors, forces).detectable == detectability(dense, sensors, forces).detectable
    assert not detectability(large, sensors[:1], forces).detectable
    dt = 1 / 1000
    t = np.arange(2000) * dt
    loads = np.column_stack([20 * np.sin(2 * np.pi * 2 * t), 10 * np.sin(2 * np.pi * 3 * t)])
    sim = simulate(dense, sensors, forces, loads, dt, relative_noise=0.01, seed=3)
    kw = dict(model_error_cov=1e-18, force_increment_cov=1e-2, noise_cov=np.diag(sim.noise_std ** 2))
    a = estimate(dense, sensors, forces, sim.measurements, dt, **kw)
    b = estimate(large, sensors, forces, sim.measurements, dt, **kw)
    settled = slice(500, None)
    err_a = np.sqrt(np.mean((a.forces[settled] - loads[settled]) ** 2))
    err_b = np.sqrt(np.mean((b.forces[settled] - loads[settled]) ** 2))
    assert err_b < 1.2 * err_a + 0.01 * np.max(np.abs(loads))
    np.testing.assert_allclose(b.strains[settled], a.strains[settled], rtol=0, atol=0.05 * np.max(np.abs(a.strains)))


def test_imported_large_model_is_reduced_and_checked(monkeypatch):
    """from_matrices goes sparse above DENSE_LIMIT (here lowered) or with n_modes; the checks hold."""
    import core_akf.models.matrices as matrices

    parts = plate_matrices(*ARGS)
    common = dict(dofs=parts["dofs"], nodes=parts["nodes"], fixed=parts["fixed"], damping=0.01)
    monkeypatch.setattr(matrices, "DENSE_LIMIT", 100)
    m = from_matrices(parts["K"], parts["M"], strain_rows=parts["strains"], **common)
    assert m.is_reduced and m.n == matrices.DEFAULT_MODES
    np.testing.assert_allclose(m.frequencies(20), plate(*ARGS).frequencies(20), rtol=1e-8)
    with pytest.raises(AKFInputError, match="rigid-body mode"):
        from_matrices(parts["K"], parts["M"], dofs=parts["dofs"], nodes=parts["nodes"], n_modes=10)
    K = parts["K"].tolil()
    K[5, 9] += 1.0
    with pytest.raises(AKFInputError, match=r"K is not symmetric: entries \(6, 10\) and \(10, 6\)"):
        from_matrices(K.tocsr(), parts["M"], **common, n_modes=10)
    with pytest.raises(AKFInputError, match="n_modes must be between 1 and"):
        from_matrices(parts["K"], parts["M"], **common, n_modes=10 ** 6)


def test_cholesky_and_lu_give_the_same_reduced_model(plates, monkeypatch):
    """The sparse Cholesky (CHOLMOD with nested dissection, the ``large`` extra) and SuperLU's LU,
    the fallback, give the same modes and the same static correction; a K that is not positive
    definite falls back to LU, whose singular case is the clear error it always was."""
    pytest.importorskip("cholespy")
    from core_akf.models import sparse

    assert sparse.factorise(scipy.sparse.csc_matrix(np.diag([2.0, 3.0]))).method == "cholmod"
    chol = plates[1]

    def no_cholmod(K):
        raise ImportError("cholespy blocked for this test")

    monkeypatch.setattr(sparse, "CholeskyFactor", no_cholmod)
    lu = plate(*ARGS, n_modes=25)
    np.testing.assert_allclose(chol.frequencies(), lu.frequencies(), rtol=1e-10)
    a, b = _static_outputs(chol, SENSORS[:4], FORCES), _static_outputs(lu, SENSORS[:4], FORCES)
    assert np.all(np.abs(a - b) <= 1e-9 * np.max(np.abs(b), axis=1, keepdims=True))   # each output to its size
    monkeypatch.undo()
    singular = scipy.sparse.csc_matrix(np.array([[1.0, -1.0, 0.0], [-1.0, 1.0, 0.0], [0.0, 0.0, 1.0]]))
    with pytest.raises(AKFInputError, match="singular"):
        sparse.factorise(singular)
