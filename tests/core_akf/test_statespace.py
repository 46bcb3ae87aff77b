"""Discretisation, observation matrices and the PBH detectability check.

Tolerances: a matrix exponential is accurate to ~eps * ||A_c dt|| * cond (scipy's Pade scaling
and squaring), so results derived from it agree to 1e-10 relative for the truss (||A_c dt|| ~ 1)
and 1e-7 for the stiff plate (||A_c dt|| ~ 1e3 with shear modes in the MHz); products of a few
well-conditioned matrices to ~1e-13.
"""
import numpy as np
import pytest

from core_akf import UndetectableError
from core_akf.forcemodels import van_loan
from core_akf.models import s17_truss, th_plate
from core_akf.statespace import continuous, detectability, observation, state_space, zoh

FORCES4 = ["4:y", "6:y", "8:y", "12:y"]
ACC_ONLY = [f"acc:{j}:y" for j in (2, 4, 5, 6, 7, 8, 9, 12, 14, 15)] + [f"acc:{j}:x" for j in (4, 5, 8, 9)]


def _rk4(A_c, B_c, u, x0, dt, substeps):
    """Fine-step RK4 with the input held constant over each coarse step."""
    h = dt / substeps
    x = x0.copy()
    f = lambda x: A_c @ x + B_c @ u
    for _ in range(substeps):
        k1 = f(x)
        k2 = f(x + h / 2 * k1)
        k3 = f(x + h / 2 * k2)
        k4 = f(x + h * k3)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


def test_zoh_matches_fine_rk4():
    s = s17_truss()
    A_c, B_c = continuous(s, ["8:y", "12:y"])
    dt = 1 / 512
    A, B = zoh(A_c, B_c, dt)
    rng = np.random.default_rng(0)
    x = np.zeros(A.shape[0])
    x_rk = x.copy()
    for _ in range(40):
        u = rng.normal(0, 1e3, 2)
        x = A @ x + B @ u
        x_rk = _rk4(A_c, B_c, u, x_rk, dt, 1000)
    # RK4 with h = dt / 1000: local error ~ (omega_max h)^5 / 120 ~ 1e-12 per step, 4e4 steps
    assert np.max(np.abs(x - x_rk)) <= 1e-7 * np.max(np.abs(x_rk))


def test_zoh_singular_Ac_has_integrator_B():
    """Block exponential works when A_c is singular: a free mass gives B = [dt^2/2, dt] / m."""
    A_c = np.array([[0.0, 1.0], [0.0, 0.0]])
    B_c = np.array([[0.0], [0.5]])
    A, B = zoh(A_c, B_c, 0.1)
    assert np.allclose(A, [[1, 0.1], [0, 1]])
    assert np.allclose(B[:, 0], [0.5 * 0.01 / 2, 0.05])


def test_van_loan_matches_quadrature():
    """Q = int_0^dt e^{A t} Q_c e^{A^T t} dt for a damped oscillator, by adaptive quadrature."""
    from scipy.integrate import quad_vec
    from scipy.linalg import expm
    A_c = np.array([[0.0, 1.0], [-(2 * np.pi * 5) ** 2, -2 * 0.02 * 2 * np.pi * 5]])
    Qc = np.array([[0.1, 0.0], [0.0, 2.0]])
    dt = 0.01
    ref, _ = quad_vec(lambda t: expm(A_c * t) @ Qc @ expm(A_c * t).T, 0, dt, epsabs=1e-14)
    assert np.allclose(van_loan(A_c, Qc, dt), ref, rtol=1e-9, atol=1e-14)   # quadrature to epsabs 1e-14


def test_acceleration_rows_equal_equation_of_motion():
    """y_acc = G x + D f must equal M^-1 (S_p f - C v - K u) picked at the sensor DOFs."""
    s = s17_truss()
    sensors = ["acc:8:y", "acc:6:x", "strain:5", "disp:4:y", "vel:12:y"]
    G, D = observation(s, sensors, ["8:y", "12:y"])
    rng = np.random.default_rng(1)
    u, v, f = rng.normal(size=s.n), rng.normal(size=s.n), rng.normal(size=2)
    Sp = np.zeros((s.n, 2))
    Sp[s.dof_index(8, "y"), 0] = 1
    Sp[s.dof_index(12, "y"), 1] = 1
    acc = np.linalg.solve(s.M, Sp @ f - s.C @ v - s.K @ u)
    y = G @ np.r_[u, v] + D @ f
    # two routes through M^-1 (Cholesky vs LU) with cond(M) ~ 1e2 and ||M^-1 K|| ~ 1e8: ~1e-13
    assert y[0] == pytest.approx(acc[s.dof_index(8, "y")], rel=1e-10)
    assert y[1] == pytest.approx(acc[s.dof_index(6, "x")], rel=1e-10)
    assert y[2] == pytest.approx(s.strain_operator[4] @ u, rel=1e-12)
    assert y[3] == pytest.approx(u[s.dof_index(4, "y")])
    assert y[4] == pytest.approx(v[s.dof_index(12, "y")])
    assert np.allclose(D[2:], 0)


def test_augmentation_blocks():
    ss = state_space(s17_truss(), ["strain:5", "acc:8:y"], ["8:y"], 1 / 1024)
    assert ss.A_a.shape == (ss.n_states + 1, ss.n_states + 1)
    assert np.allclose(ss.A_a[-1], np.r_[np.zeros(ss.n_states), 1.0])
    assert np.allclose(ss.G_a[:, -1], ss.D[:, 0])


def test_pbh_acceleration_only_is_undetectable_and_names_s0():
    s = s17_truss()
    rep = detectability(s, ["acc:4:y", "acc:6:y", "acc:8:y"], ["8:y"])
    assert not rep.detectable
    assert rep.failures[0]["s"] == 0.0
    assert "s = 0" in str(rep) and "forces" in str(rep)
    # one strain gauge restores detectability for one unknown force
    assert detectability(s, ["acc:4:y", "acc:6:y", "acc:8:y", "strain:13"], ["8:y"]).detectable


def test_pbh_needs_as_many_static_sensors_as_forces():
    """With four unknown forces, one strain is not enough: three static load patterns stay unseen."""
    s = s17_truss()
    assert not detectability(s, ACC_ONLY + ["strain:5"], FORCES4).detectable
    case4 = ["acc:4:y", "acc:6:y", "acc:8:y", "acc:12:y", "acc:6:x", "strain:5", "strain:9", "strain:13", "strain:26"]
    assert detectability(s, case4, FORCES4).detectable
    assert detectability(s, [f"strain:{m}" for m in (4, 5, 9, 12, 13, 16, 21, 24, 26)], FORCES4).detectable


def test_pbh_plate_and_reduced_plate():
    p = th_plate()
    forces = ["121:w", "111:w"]
    assert not detectability(p, ["acc:12:w", "acc:58:w", "acc:100:w"], forces).detectable
    case3 = ["strain:2:gxy", "strain:100:gxy", "acc:12:w"]
    assert detectability(p, case3, forces).detectable
    assert detectability(p.reduce(20), case3, forces).detectable


def test_undetectable_error_carries_report():
    from core_akf.statespace import check_detectable
    with pytest.raises(UndetectableError) as err:
        check_detectable(s17_truss(), ACC_ONLY, FORCES4)
    assert "allow_undetectable" in str(err.value)
    assert not err.value.report.detectable
    assert not check_detectable(s17_truss(), ACC_ONLY, FORCES4, allow_undetectable=True).detectable


@pytest.mark.parametrize("sensors,forces", [
    (["acc:4:y", "acc:6:y", "acc:8:y"], ["8:y"]),
    (["acc:4:y", "acc:6:y", "acc:8:y", "strain:13"], ["8:y"]),
    (["acc:4:y", "strain:9"], ["8:y"]),  # member 9 carries no static force from a load at 8
    (ACC_ONLY + ["strain:5"], FORCES4),
    (["acc:4:y", "acc:6:y", "acc:8:y", "acc:12:y", "acc:6:x", "strain:5", "strain:9", "strain:13", "strain:26"], FORCES4),
    (["disp:8:y", "disp:4:y", "disp:12:y", "disp:6:y"], FORCES4),
    (["acc:2:y", "acc:10:y", "acc:14:y", "acc:16:y", "acc:10:x", "strain:5", "strain:19", "strain:26", "strain:30"],
     FORCES4),  # zero-force member 30: undetectable
])
def test_static_shortcut_agrees_with_full_pbh_at_s0(sensors, forces):
    """The damped structure uses the static-gain shortcut; the undamped one (every mode on the
    imaginary axis) goes through the full PBH matrix.  Their verdicts at s = 0 must agree."""
    damped = detectability(s17_truss(), sensors, forces)
    undamped = detectability(s17_truss(damping=None), sensors, forces)
    assert len(undamped.checked) == 1 + 33
    s0_fails = any(f["s"] == 0.0 for f in undamped.failures)
    assert damped.detectable == (not s0_fails)


@pytest.mark.parametrize("make,forces,dt,tol", [
    (lambda: s17_truss(), ["8:y", "12:y"], 1 / 4096, 1e-11),
    (lambda: s17_truss(damping=("rayleigh", 0.5, 1e-5)), ["8:y"], 1 / 1024, 1e-11),
    (lambda: th_plate(), ["121:w", "111:w"], 1 / 2000, 1e-7),   # dense expm of a stiff 660x660 matrix
    (lambda: th_plate().reduce(25), ["121:w"], 1 / 2000, 1e-11),
])
def test_modal_zoh_equals_dense_zoh_in_modal_coordinates(make, forces, dt, tol):
    from core_akf.statespace import modal_state_transform, modal_zoh
    s = make()
    A, B = zoh(*continuous(s, forces), dt)
    T, T_inv = modal_state_transform(s)
    A_z, B_z = modal_zoh(s, forces, dt)
    assert np.max(np.abs(A_z - T_inv @ A @ T)) <= tol * np.max(np.abs(A_z))
    assert np.max(np.abs(B_z - T_inv @ B)) <= tol * np.max(np.abs(B_z))


def test_modal_zoh_refuses_non_classical_damping():
    from core_akf.statespace import modal_zoh
    s = s17_truss(damping=None)
    C = np.zeros_like(s.K)
    i = s.dof_index(8, "y")
    C[i, i] = 1e4  # one discrete dashpot: not proportional
    from core_akf import Structure
    s2 = Structure(M=s.M, K=s.K, C=C, nodes=s.nodes, dof_names=s.dof_names, free_dofs=s.free_dofs,
                   strain_matrix=s.strain_matrix, members=s.members)
    assert modal_zoh(s2, ["8:y"], 1e-3) is None


def test_pbh_zero_force_member_is_not_information():
    """A zero-force member reads rounding noise (~1e-24) in the static gain; unit row scaling
    once turned that into a full row.  Gauges 5, 19, 26, 30 with accelerometers away from the
    loads cannot see the self-equilibrated group f4 - 2 f6 + f8 -- the DARE then has no
    stabilising solution -- and the report must say so."""
    s = s17_truss(200e9, 7800)
    sensors = ["acc:2:y", "acc:10:y", "acc:14:y", "acc:16:y", "acc:10:x",
               "strain:5", "strain:19", "strain:26", "strain:30"]
    rep = detectability(s, sensors, FORCES4)
    assert not rep.detectable
    assert "-0.41 x 4:y +0.82 x 6:y -0.41 x 8:y" in str(rep) or "+0.41 x 4:y -0.82 x 6:y +0.41 x 8:y" in str(rep)
    sensors[-1] = "strain:14"  # a chord between loaded joints 6 and 8 sees it
    assert detectability(s, sensors, FORCES4).detectable


def test_pbh_thin_cantilever_plate_counts_as_supported():
    """f1 / f_max ~ 1e-8 on the thesis' flexible plate (in-plane and shear modes in the MHz):
    still a supported structure, so the static test applies and two gauges are detectable."""
    from akf.examples import TH_FLEXIBLE_PLATE
    from akf.job import build_structure
    from core_akf.statespace import is_supported

    s = build_structure(TH_FLEXIBLE_PLATE)
    f = s.frequencies()
    assert f[0] / f[-1] < 1e-7
    assert is_supported(s)
    assert detectability(s, ["strain:2:gxy", "strain:100:gxy"], ["121:w", "111:w"]).detectable
    import types

    free_truss = types.SimpleNamespace(K=s17_truss(200e9, 7800).meta["K_full"],  # no supports: 3 rigid modes
                                       memo=lambda key, compute: compute())
    assert not is_supported(free_truss)
