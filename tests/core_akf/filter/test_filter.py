"""The AKF against independent implementations: a textbook loop, filterpy, scipy's DARE.

Tolerances: two filters that differ only in the order of their floating-point operations
agree to about ``eps * kappa * sqrt(N)`` relative, with ``kappa`` the condition number of the
innovation covariance (< 1e3 for these random systems) and ``N`` the steps (200-600):
~1e-12, asserted at 1e-10.  Riccati solutions are compared at the DARE's sensitivity
(``eps`` times its condition number, ~1e4-1e6 here): 1e-9 relative, 1e-7 for the stiff S17
model whose DARE condition number is ~1e8.
"""
import warnings

import numpy as np
import pytest
import scipy.linalg

from core_akf import filter as akf
from core_akf.filter import recursion
from core_akf.filter.riccati import dare_residual, solve_filter_dare, steady_gain
from core_akf.models import s17_truss
from core_akf.simulate import simulate
from core_akf.statespace import state_space


def _random_system(seed, n=6, m=3):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A *= 0.95 / np.max(np.abs(np.linalg.eigvals(A)))
    G = rng.normal(size=(m, n))
    L = rng.normal(size=(n, n))
    Q = L @ L.T / n + 0.01 * np.eye(n)
    Lr = rng.normal(size=(m, m))
    R = Lr @ Lr.T / m + 0.1 * np.eye(m)
    x = np.zeros(n)
    Y = []
    for _ in range(200):
        Y.append(G @ x + rng.multivariate_normal(np.zeros(m), R))
        x = A @ x + rng.multivariate_normal(np.zeros(n), Q)
    return A, G, Q, R, np.array(Y), rng.normal(size=n), np.eye(n) * 2.0


def _textbook(A, G, Q, R, Y, x0, P0):
    """Kalman filter straight from the textbook, one step at a time, with explicit inverses."""
    x, P, out = x0.copy(), P0.copy(), []
    for y in Y:
        K = P @ G.T @ np.linalg.inv(G @ P @ G.T + R)
        x = x + K @ (y - G @ x)
        I_KG = np.eye(len(x)) - K @ G
        P = I_KG @ P @ I_KG.T + K @ R @ K.T  # Joseph form
        out.append(x.copy())
        x = A @ x
        P = A @ P @ A.T + Q
    return np.array(out)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_time_varying_equals_textbook(seed):
    A, G, Q, R, Y, x0, P0 = _random_system(seed)
    ours = akf.run(A, G, Q, R, Y, x0=x0, P0=P0)
    ref = _textbook(A, G, Q, R, Y, x0, P0)
    assert np.max(np.abs(ours - ref)) <= 1e-10 * np.max(np.abs(ref))


@pytest.mark.parametrize("seed", [3, 4])
def test_time_varying_equals_filterpy(seed):
    filterpy = pytest.importorskip("filterpy.kalman")
    A, G, Q, R, Y, x0, P0 = _random_system(seed)
    kf = filterpy.KalmanFilter(dim_x=A.shape[0], dim_z=G.shape[0])
    kf.F, kf.H, kf.Q, kf.R, kf.x, kf.P = A, G, Q, R, x0.copy(), P0.copy()
    ref = []
    for y in Y:
        kf.update(y)
        ref.append(kf.x.copy())
        kf.predict()
    ref = np.array(ref)
    ours = akf.run(A, G, Q, R, Y, x0=x0, P0=P0)
    assert np.max(np.abs(ours - ref)) <= 1e-10 * np.max(np.abs(ref))


@pytest.mark.parametrize("seed", [0, 5])
def test_doubling_dare_matches_scipy_random(seed):
    A, G, Q, R, *_ = _random_system(seed, n=8, m=3)
    P = solve_filter_dare(A, G, Q, R)
    ref = scipy.linalg.solve_discrete_are(A.T, G.T, Q, R)
    assert np.allclose(P, ref, rtol=1e-9, atol=1e-12 * np.abs(ref).max())


def test_doubling_dare_matches_scipy_on_s17_case4():
    ss = state_space(s17_truss(), ["acc:4:y", "acc:6:y", "acc:8:y", "acc:12:y", "acc:6:x",
                                   "strain:5", "strain:9", "strain:13", "strain:26"],
                     ["4:y", "6:y", "8:y", "12:y"], 1 / 4096)
    Q = np.diag(np.r_[np.full(ss.n_states, 1e-16), np.full(4, 1e5)])
    R = np.diag(np.r_[np.full(5, 1e-2), np.full(4, 1e-12)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the fast path must not fall back here
        P = solve_filter_dare(ss.A_a, ss.G_a, Q, R)
    ref = scipy.linalg.solve_discrete_are(ss.A_a.T, ss.G_a.T, Q, R)
    assert np.linalg.norm(P - ref) <= 1e-7 * np.linalg.norm(ref)
    assert dare_residual(ss.A_a, ss.G_a, Q, R, P) < 1e-10


def test_steady_state_equals_time_varying_after_transient():
    A, G, Q, R, Y, x0, P0 = _random_system(7)
    Y = np.tile(Y, (3, 1))
    tv = akf.run(A, G, Q, R, Y, x0=x0, P0=P0)
    ss = akf.run(A, G, Q, R, Y, x0=x0, steady=True)
    # the time-varying gain converges geometrically (rate < 0.95 per step): after 400 steps it
    # equals the steady gain to rounding, which the last 200 steps carry at ~eps * 200 * kappa
    assert np.max(np.abs(tv[-200:] - ss[-200:])) <= 1e-9 * np.max(np.abs(tv))
    assert np.max(np.abs(tv[:5] - ss[:5])) > 1e-6  # the transient really differs


def test_steady_gain_is_limit_of_time_varying_gain():
    A, G, Q, R, Y, x0, P0 = _random_system(8)
    res = akf.filter_states(A, G, Q, R, np.tile(Y, (2, 1)), x0=x0, P0=P0)
    _, L = steady_gain(A, G, Q, R)
    assert np.allclose(res.gain, L, rtol=1e-8, atol=1e-12)   # the switch to the fixed gain happens at 1e-14 change


@pytest.mark.parametrize("steady", [False, True])
def test_batched_equals_one_by_one(steady):
    systems = [_random_system(s) for s in range(4)]
    A = systems[0][0]
    G = np.stack([s[1] for s in systems])
    Q = systems[0][2]
    R = np.stack([s[3] for s in systems])
    Y = np.stack([s[4] for s in systems])
    batch = akf.run(A, G, Q, R, Y, steady=steady)
    assert batch.shape == (4, Y.shape[1], A.shape[0])
    for b in range(4):
        one = akf.run(A, G[b], Q, R[b], Y[b], steady=steady)
        # same operations, batched BLAS calls may block differently: rounding only (~1e-14)
        assert np.allclose(batch[b], one, rtol=1e-12, atol=1e-12 * np.abs(one).max())


def test_estimate_batch_equals_estimate():
    s = s17_truss()
    forces = ["8:y"]
    layouts = [["strain:13", "acc:8:y"], ["strain:21", "acc:6:y"], ["strain:16", "acc:4:y"]]
    dt, N = 1 / 1024, 600
    rng = np.random.default_rng(0)
    loads = rng.normal(0, 500, (N, 1))
    Ys = np.stack([simulate(s, l, forces, loads, dt, relative_noise=0.02, seed=1).measurements for l in layouts])
    kw = dict(model_error_cov=1e-16, force_increment_cov=1e5, noise_cov={"strain": 1e-14, "acc": 1e-2})
    for steady in (False, True):
        batch = akf.estimate_batch(s, layouts, forces, Ys, dt, steady=steady, **kw)
        for l, y, b in zip(layouts, Ys, batch):
            one = akf.estimate(s, l, forces, y, dt, steady=steady, **kw)
            # rounding of batched vs single BLAS calls through a 66-state model: 1e-10 relative;
            # atol = 1e-10 of the forces' scale (~100 N) and of the strains' (~1e-8)
            assert np.allclose(b.forces, one.forces, rtol=1e-10, atol=1e-8)
            assert np.allclose(b.strains, one.strains, rtol=1e-10, atol=1e-18)


def test_perfect_model_no_noise_recovers_force_and_strains():
    """Sanity of the whole chain: same model, tiny noise -> force and all member strains recovered."""
    s = s17_truss()
    dt, N = 1 / 2048, 2048
    t = np.arange(N) * dt
    loads = (2000 * np.sin(2 * np.pi * 3 * t))[:, None]
    sensors = ["strain:13", "strain:21", "acc:8:y", "acc:6:y"]
    sim = simulate(s, sensors, ["8:y"], loads, dt, relative_noise=1e-4, seed=0)
    est = akf.estimate(s, sensors, ["8:y"], sim.measurements, dt, model_error_cov=1e-20,
                       force_increment_cov=1e3, noise_cov=np.diag(sim.noise_std ** 2), steady=True)
    tail = slice(N // 4, None)
    err = np.sqrt(np.mean((est.forces[tail, 0] - loads[tail, 0]) ** 2))
    assert err < 0.02 * 2000          # noise 1e-4 and a perfect model: the filter's lag dominates (~0.5 %)
    strain_err = np.sqrt(np.mean((est.strains[tail] - sim.strains[tail]) ** 2, axis=0))
    assert np.max(strain_err) < 0.02 * np.max(np.abs(sim.strains))
    # estimated response at an unused sensor follows the truth as well
    other = est.response(["acc:12:y"])[tail, 0]
    truth = sim.response(["acc:12:y"])[tail, 0]
    assert np.sqrt(np.mean((other - truth) ** 2)) < 0.05 * np.sqrt(np.mean(truth ** 2))


@pytest.mark.parametrize("n_out", [None, 2, 7])
@pytest.mark.parametrize("N", [1, 2, 40, 1000, 4099])
def test_lifted_recursion_equals_step_loop(N, n_out):
    """The lifted recursion (chunks, Markov parameters, boundary states) against the plain loop,
    for states and for a few output rows, batched, over record lengths around the chunk sizes."""
    rng = np.random.default_rng(N)
    B, n, m = 3, 6, 2
    F = rng.normal(size=(B, n, n))
    F *= 0.97 / np.max(np.abs(np.linalg.eigvals(F)), axis=1)[:, None, None]
    L = rng.normal(size=(B, n, m))
    Y = rng.normal(size=(B, N, m))
    x0 = rng.normal(size=(B, n))
    ref = np.empty((B, N, n))
    x = x0
    ref[:, 0] = x
    for k in range(1, N):
        x = np.einsum("bij,bj->bi", F, x) + np.einsum("bij,bj->bi", L, Y[:, k])
        ref[:, k] = x
    H = None if n_out is None else rng.normal(size=(n_out, n))
    want = ref if H is None else ref @ H.T
    # spectral radius 0.97: rounding grows at most like 1 / (1 - 0.97) = 33 eps per step -> ~1e-14
    assert np.allclose(recursion.lti_response(F, L, Y, x0, H), want, rtol=1e-11, atol=1e-11)
    assert np.allclose(recursion.lti_response(F[:1], L[:1], Y[:1], x0[:1], H), want[:1], rtol=1e-11, atol=1e-11)
    U = Y @ np.swapaxes(L, -1, -2)
    for path in (recursion.recursion_stepwise, recursion.recursion_chunked):
        assert np.allclose(path(F, U, x0), ref, rtol=1e-11, atol=1e-11)


def test_lifted_recursion_gives_the_same_bits_on_any_number_of_threads(monkeypatch):
    rng = np.random.default_rng(7)
    B, N, n, m = 5, 700, 9, 2
    F = rng.normal(size=(B, n, n))
    F *= 0.95 / np.max(np.abs(np.linalg.eigvals(F)), axis=1)[:, None, None]
    L, Y, x0, H = rng.normal(size=(B, n, m)), rng.normal(size=(B, N, m)), rng.normal(size=(B, n)), rng.normal(size=(3, n))
    results = []
    for threads in ("1", "2", "4"):
        monkeypatch.setenv("AKF_NUM_THREADS", threads)
        results.append((recursion.lti_response(F, L, Y, x0), recursion.lti_response(F, L, Y, x0, H)))
    alone = [recursion.lti_response(F[b:b + 1], L[b:b + 1], Y[b:b + 1], x0[b:b + 1], H)[0] for b in range(B)]
    for states, outputs in results[1:]:
        assert np.array_equal(states, results[0][0]) and np.array_equal(outputs, results[0][1])
    assert np.array_equal(np.stack(alone), results[0][1])


def test_a_stack_run_piece_by_piece_gives_the_same_bits_as_in_one_piece(monkeypatch):
    """A long record's stack runs in pieces of ``_PIECE_BYTES`` (fresh pages cost more than the
    arithmetic): the lifted outputs and the steady log-likelihoods, totals and per step, are the
    same bits in pieces of one or two systems as in one piece, on 1 or 2 threads."""
    from core_akf.filter.kernels import steady_logliks

    rng = np.random.default_rng(11)
    B, N, n, m = 7, 900, 8, 3
    F = rng.normal(size=(B, n, n))
    F *= 0.95 / np.max(np.abs(np.linalg.eigvals(F)), axis=1)[:, None, None]
    L, Y, x0, H = rng.normal(size=(B, n, m)), rng.normal(size=(B, N, m)), rng.normal(size=(B, n)), rng.normal(size=(2, n))
    G = rng.normal(size=(B, m, n))
    Q = np.repeat(np.eye(n)[None] * 0.1, B, 0)
    R = np.repeat(np.eye(m)[None], B, 0)
    runs = []
    for piece in (2 ** 40, 8 * N * 8, 1):          # one piece, about one system, one system each
        monkeypatch.setattr(recursion, "_PIECE_BYTES", piece)
        for threads in ("1", "2"):
            monkeypatch.setenv("AKF_NUM_THREADS", threads)
            runs.append((recursion.lti_response(F, L, Y, x0, H), recursion.lti_response(F, L, Y, x0),
                         steady_logliks(F, G, Q, R, Y[0]), steady_logliks(F, G, Q, R, Y[0], per_step=True)))
    assert len(recursion.stack_pieces(B, 8 * N * 8)) > 1
    for run in runs[1:]:
        for got, want in zip(run, runs[0]):
            assert np.array_equal(got, want)
    assert np.allclose(runs[0][3].sum(axis=1), runs[0][2], rtol=1e-12)


def test_time_varying_gain_switch_is_exact_on_s17():
    """The switch to the converged gain changes nothing measurable (S17 case 4, 8192 steps)."""
    ss = state_space(s17_truss().scaled(1.05), ["acc:4:y", "acc:6:y", "acc:8:y", "acc:12:y", "acc:6:x",
                                                "strain:5", "strain:9", "strain:13", "strain:26"],
                     ["4:y", "6:y", "8:y", "12:y"], 1 / 4096)
    rng = np.random.default_rng(0)
    Y = rng.normal(size=(8192, 9)) * np.r_[np.full(5, 1.0), np.full(4, 1e-6)]
    Q = np.diag(np.r_[np.full(ss.n_states, 1e-16), np.full(4, 1e5)])
    R = np.diag(np.r_[np.full(5, 1e-2), np.full(4, 1e-14)])
    full = akf.filter_states(ss.A_a, ss.G_a, Q, R, Y, switch_tol=0)
    fast = akf.filter_states(ss.A_a, ss.G_a, Q, R, Y)
    diff = np.abs(fast.states - full.states)
    # the switch happens at a relative covariance change of 1e-14; through a gain of condition
    # ~1e4 and 8192 steps that is < 1e-9 of the states
    assert diff.max() < 1e-9 * np.abs(full.states).max()
    assert np.max(diff / np.abs(full.states).max(axis=0)) < 1e-8  # every state, on its own scale
    chan = np.abs(full.innovations).max(axis=0)
    assert np.max(np.abs(fast.innovations - full.innovations) / chan) < 1e-8


def test_reduced_model_estimate_close_to_full_on_th_case3():
    """TH case-3 layout (g_xy at 2 and 100, acceleration at 12), 5 % model error, 2 % noise:
    the 80-mode reduced filter model gives the full model's average strain error within 5 %,
    with the same covariance levels (model error is specified per physical DOF)."""
    from helpers import run_estimate

    from akf.examples import example_job

    job = example_job("th-case3")
    job["simulation"]["duration"] = 0.5
    full = run_estimate(job).metrics["avg_strain_error"]
    job["filter"]["n_modes"] = 80
    reduced = run_estimate(job).metrics["avg_strain_error"]
    assert reduced == pytest.approx(full, rel=0.05)    # truncation error of 80 modes (measured 0.3 %)


def test_reduced_structure_projection_inverts_basis():
    from core_akf.models import th_plate
    r = th_plate().reduce(15)
    # Phi^T M Phi = I from eigh: orthogonality to eps * cond(M) (~1e-13)
    assert np.allclose(r.projection @ r.basis, np.eye(15), atol=1e-10)
    rr = r.reduce(5)
    assert np.allclose(rr.projection @ rr.basis, np.eye(5), atol=1e-10)


def test_riccati_falls_back_to_scipy_with_a_warning():
    from core_akf.filter.riccati import RiccatiWarning
    A, G, Q, R, *_ = _random_system(9, n=6, m=2)
    with pytest.warns(RiccatiWarning, match="falling back"):
        P = solve_filter_dare(A, G, Q, R, max_iter=1)
    assert np.allclose(P, scipy.linalg.solve_discrete_are(A.T, G.T, Q, R), rtol=1e-9)   # DARE condition ~1e4


def test_riccati_batch_of_mixed_problems():
    systems = [_random_system(s, n=5, m=2) for s in range(6)]
    A = np.stack([s[0] for s in systems])
    G = np.stack([s[1] for s in systems])
    Q = np.stack([s[2] for s in systems])
    R = np.stack([s[3] for s in systems])
    P = solve_filter_dare(A, G, Q, R)
    for b in range(6):
        assert np.allclose(P[b], scipy.linalg.solve_discrete_are(A[b].T, G[b].T, Q[b], R[b]), rtol=1e-9)


def test_riccati_stack_gives_the_same_bits_alone_batched_and_over_threads(monkeypatch):
    """Each problem of a stack iterates until it has converged and then stops, so its solution
    does not depend on what else is in the stack -- nor on how the stack is split over threads
    (the location scan and the GA rely on this for bit-identical runs on any number of workers)."""
    from core_akf.filter import riccati
    systems = [_random_system(s, n=7, m=2) for s in range(7)]
    A, G, Q, R = (np.stack([s[i] for s in systems]) for i in range(4))
    monkeypatch.setenv("AKF_NUM_THREADS", "1")
    one_call = solve_filter_dare(A, G, Q, R)
    alone = np.stack([solve_filter_dare(A[b], G[b], Q[b], R[b]) for b in range(7)])
    monkeypatch.setenv("AKF_NUM_THREADS", "3")
    threaded = solve_filter_dare(A, G, Q, R)
    assert np.array_equal(one_call, alone) and np.array_equal(threaded, alone)
    # a problem without a solution is named by its place in the whole stack, not in its thread's part
    A_bad, G_bad = A.copy(), G.copy()
    A_bad[5] *= 1.2 / np.max(np.abs(np.linalg.eigvals(A[5])))   # unstable ...
    G_bad[5] = 0.0                                              # ... and not measured: undetectable
    with pytest.warns(riccati.RiccatiWarning), pytest.raises(riccati.RiccatiError, match=r"problem\(s\) \[5\]") as err:
        solve_filter_dare(A_bad, G_bad, Q, R)
    assert err.value.problems == (5,)


def test_estimate_batch_with_noise_per_layout():
    s = s17_truss()
    layouts = [["strain:13", "acc:8:y"], ["strain:21", "acc:6:y"]]
    dt = 1 / 1024
    loads = np.random.default_rng(1).normal(0, 500, (400, 1))
    sims = [simulate(s, l, ["8:y"], loads, dt, relative_noise=0.02, seed=2) for l in layouts]
    Ys = np.stack([x.measurements for x in sims])
    R = np.stack([np.diag(x.noise_std ** 2) for x in sims])
    kw = dict(model_error_cov=1e-16, force_increment_cov=1e5, steady=True)
    batch = akf.estimate_batch(s, layouts, ["8:y"], Ys, dt, noise_cov=R, **kw)
    for l, y, r, b in zip(layouts, Ys, R, batch):
        assert np.allclose(b.forces, akf.estimate(s, l, ["8:y"], y, dt, noise_cov=r, **kw).forces, rtol=1e-10, atol=1e-8)
    with pytest.raises(ValueError, match="noise_cov has 3 entries for 2 layouts"):
        akf.estimate_batch(s, layouts, ["8:y"], Ys, dt, noise_cov=np.stack([R[0]] * 3), **kw)


def test_structured_time_varying_update_equals_dense():
    """ModalBlockTransition's A P A^T (used by estimate for classically damped structures)
    gives the same time-varying filter as the dense product."""
    from core_akf.filter.recursion import ModalBlockTransition
    from core_akf.models import th_plate
    from core_akf.statespace import augment, modal_state_transform, modal_zoh, observation
    s = th_plate().reduce(30)
    forces = ["121:w", "111:w"]
    sensors = ["strain:2:gxy", "strain:100:gxy", "acc:12:w"]
    A_z, B_z = modal_zoh(s, forces, 1 / 2000)
    A_a, _ = augment(A_z, B_z, np.zeros((0, 60)), np.zeros((0, 2)))
    G, D = observation(s, sensors, forces)
    T, _ = modal_state_transform(s)
    G_a = np.hstack([G @ T, D])
    tr = ModalBlockTransition.detect(A_a, s.n)
    assert tr is not None and tr.error == 0.0
    rng = np.random.default_rng(0)
    P = rng.normal(size=(62, 62))
    P = P @ P.T
    # two orderings of the same 62 x 62 products: rounding ~ 62 eps
    assert np.allclose(tr.propagate(P, np.eye(62)), A_a @ P @ A_a.T + np.eye(62), rtol=1e-12, atol=1e-12)
    Y = rng.normal(size=(300, 3)) * np.array([1e-6, 1e-6, 1.0])
    Q = np.diag(np.r_[np.full(60, 1e-10), 1e-2, 1e-2])
    R = np.diag([1e-14, 1e-14, 1e-3])
    dense = akf.filter_states(A_a, G_a, Q, R, Y, switch_tol=0)
    fast = akf.filter_states(A_a, G_a, Q, R, Y, switch_tol=0, transition=tr)
    # 300 steps of rounding differences through gains of condition ~1e6 (strain vs acceleration)
    assert np.allclose(fast.states, dense.states, rtol=1e-9, atol=1e-9 * np.abs(dense.states).max())


def test_estimate_with_non_classical_damping_uses_the_dense_path():
    """A discrete dashpot makes the damping non-proportional: no modal shortcut, same answers
    from the steady-state and the time-varying filter after the transient."""
    from core_akf import Structure
    s = s17_truss(damping=0.007)
    C = s.C.copy()
    i = s.dof_index(8, "y")
    C[i, i] += 2e3
    s2 = Structure(M=s.M, K=s.K, C=C, nodes=s.nodes, dof_names=s.dof_names, free_dofs=s.free_dofs,
                   strain_matrix=s.strain_matrix, members=s.members, name="truss + dashpot")
    sensors = ["strain:13", "strain:21", "acc:8:y"]
    loads = np.random.default_rng(3).normal(0, 500, (3000, 1))
    sim = simulate(s2, sensors, ["8:y"], loads, 1 / 2048, relative_noise=0.02, seed=1)
    kw = dict(model_error_cov=1e-16, force_increment_cov=1e5, noise_cov=np.diag(sim.noise_std ** 2))
    ss = akf.estimate(s2, sensors, ["8:y"], sim.measurements, 1 / 2048, steady=True, **kw)
    tv = akf.estimate(s2, sensors, ["8:y"], sim.measurements, 1 / 2048, steady=False, **kw)
    # after 2000 steps the time-varying gain has converged to ~1e-7 (slowest pole of the error
    # dynamics ~0.99); the last 1000 steps then agree to that
    assert np.allclose(ss.forces[-1000:], tv.forces[-1000:], rtol=1e-6, atol=1e-6 * np.abs(tv.forces).max())
    assert np.sqrt(np.mean((ss.forces[500:, 0] - loads[500:, 0]) ** 2)) < 0.5 * 500


def test_estimate_to_frame():
    s = s17_truss()
    loads = np.random.default_rng(5).normal(0, 100, (64, 1))
    sim = simulate(s, ["strain:13", "acc:8:y"], ["8:y"], loads, 1 / 1024, relative_noise=0.02, seed=0)
    est = akf.estimate(s, ["strain:13", "acc:8:y"], ["8:y"], sim.measurements, 1 / 1024, model_error_cov=1e-16,
                       force_increment_cov=1e4, noise_cov=np.diag(sim.noise_std ** 2), steady=True)
    wide = est.to_frame(wide=True)
    assert list(wide.columns[:2]) == ["time", "force:8:y"] and wide.shape == (64, 2 + 34)
    assert np.allclose(wide["strain:13"], est.strains[:, 12])
    tidy = est.to_frame(reference=sim)        # one row per time step and channel, with the truth
    assert list(tidy.columns) == ["time", "quantity", "channel", "unit", "estimated", "reference", "std"]
    assert len(tidy) == 64 * 35
    m13 = tidy[tidy["channel"] == "strain:13"]
    assert np.allclose(m13["estimated"], est.strains[:, 12]) and np.allclose(m13["time"], est.time)
    assert np.allclose(m13["reference"], sim.strains[:, 12]) and m13["std"].isna().all()      # filtered: no std
    assert set(tidy[tidy["quantity"] == "force"]["unit"]) == {"N"}
    forces = tidy[tidy["quantity"] == "force"]
    assert np.allclose(forces["estimated"], est.forces[:, 0]) and np.allclose(forces["reference"], loads[:, 0])
    few = est.to_frame(strains=[12, 0])       # the strain outputs asked for, after the forces
    assert list(few["channel"].cat.categories) == ["8:y", "strain:13", "strain:1"] and len(few) == 64 * 3
    assert np.allclose(few[few["channel"] == "strain:1"]["estimated"], est.strains[:, 0])
    assert est.detectability.detectable


def test_estimate_summary_and_diagnostics():
    """The estimate's own summary: a row per force and per sensor, the record's figures in attrs."""
    s = s17_truss()
    loads = np.random.default_rng(5).normal(0, 100, (2048, 1)).cumsum(axis=0)
    sensors = ["strain:13", "acc:8:y"]
    sim = simulate(s, sensors, ["8:y"], loads, 1 / 1024, relative_noise=0.02, seed=0)
    kw = dict(model_error_cov=1e-16, force_increment_cov=1e4, noise_cov=np.diag(sim.noise_std ** 2))
    est = akf.estimate(s, sensors, ["8:y"], sim.measurements, 1 / 1024, **kw)
    table = est.summary()
    assert list(table["channel"]) == ["8:y", "strain:13", "acc:8:y"]
    assert list(table["quantity"]) == ["force", "sensor", "sensor"]
    force = table.iloc[0]
    assert force["unit"] == "N" and np.isclose(force["rms"], np.sqrt(np.mean(est.forces[102:, 0] ** 2)))
    assert np.isclose(abs(force["peak"]), np.abs(est.forces[102:, 0]).max())
    assert np.allclose(table["loglik"].iloc[1:], est.loglik_channels)
    assert np.isclose(table.attrs["loglik"], est.loglik) and table.attrs["n_steps"] == 2048
    assert 0 < table.attrs["transient_time"] < 2048 / 1024 and not table.attrs["smoothed"]
    assert [d["channel"] for d in est.diagnostics()] == sensors
    assert all(0.5 < d["consistency"] < 2 for d in est.diagnostics())        # the model that made the record
    smoothed = akf.estimate(s, sensors, ["8:y"], sim.measurements, 1 / 1024, smooth=True, **kw).summary()
    assert smoothed.attrs["smoothed"] and 0 < smoothed["mean_std"].iloc[0] < force["rms"]


def test_stein_doubling_matches_scipy_lyapunov():
    from core_akf.filter.riccati import stein_doubling
    rng = np.random.default_rng(11)
    F = rng.normal(size=(7, 7))
    F *= 0.98 / np.max(np.abs(np.linalg.eigvals(F)))
    E = rng.normal(size=(7, 7))
    E = E @ E.T
    # spectral radius 0.98: Stein condition ~1 / (1 - 0.98^2) = 25, both solvers to ~1e-14
    assert np.allclose(stein_doubling(F, E), scipy.linalg.solve_discrete_lyapunov(F, E), rtol=1e-9)


def test_newton_step_polishes_a_perturbed_solution():
    from core_akf.filter.riccati import newton_step
    A, G, Q, R, *_ = _random_system(12, n=8, m=3)
    ref = scipy.linalg.solve_discrete_are(A.T, G.T, Q, R)
    P = ref * (1 + 1e-3 * np.random.default_rng(0).normal(size=ref.shape))
    P = 0.5 * (P + P.T)
    before = np.linalg.norm(P - ref)
    once = newton_step(A, G, Q, R, P)
    twice = newton_step(A, G, Q, R, once)
    assert np.linalg.norm(once - ref) < 1e-2 * before           # quadratic convergence
    assert np.linalg.norm(twice - ref) < 1e-11 * np.linalg.norm(ref)
