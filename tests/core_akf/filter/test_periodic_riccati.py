"""The periodic covariance recursion of a cycle of observation patterns (a channel at half the
rate): a cycle that leaves a random walk unobserved is given up after CYCLE_DIVERGED cycles (it
ran 20000 steps per candidate before: a locate over an impact file with one channel at another
rate took over 10 minutes), and a cycle that converges starts from the lifted system's steady
state (the locate: 107 s -> 18 s) and gives the recursion's limit."""
import numpy as np

from core_akf.filter import kernels as K


def _system(observe_walk):
    """A damped oscillator (2 states) and a force random walk (1 state); the cycle observes the
    displacement on even steps and, if ``observe_walk``, the walk on odd ones (which then drives the
    oscillator; else nothing sees it)."""
    dt, w, z = 1e-3, 2 * np.pi * 5, 0.02
    A = np.array([[1.0, dt, 0.0], [-w * w * dt, 1 - 2 * z * w * dt, dt if observe_walk else 0.0], [0.0, 0.0, 1.0]])
    Q = np.diag([1e-12, 1e-10, 1e-2])
    G_even = np.array([[1.0, 0.0, 0.0]])
    G_odd = np.array([[0.0, 0.0, 1.0]]) if observe_walk else np.array([[1.0, 0.0, 0.0]])
    G_c = np.stack([G_even, G_odd])
    R_c = np.full((2, 1, 1), 1e-6)
    return A, Q, G_c, R_c, np.eye(3)


def _old_rule(A, Q, G_c, R_c, P):
    """The recursion with only the convergence test (as before the divergence test)."""
    p, out = len(G_c), np.empty((len(G_c),) + P.shape)
    scale = max(np.abs(P).max(), np.finfo(float).tiny)
    for _ in range(K.CYCLE_STEPS // p):
        before = P
        for j in range(p):
            out[j] = P
            GP = G_c[j] @ P
            P = A @ (P - GP.T @ np.linalg.solve(GP @ G_c[j].T + R_c[j], GP)) @ A.T + Q
            P = (P + P.T) / 2
        scale = max(scale, np.abs(P).max())
        if np.abs(P - before).max() <= K.CYCLE_TOL * scale:
            return out
    return None


def _limit(A, Q, G_c, R_c, P, cycles=100_000):
    """The prior covariances of the cycle's recursion run far past convergence."""
    out = np.empty((len(G_c),) + P.shape)
    for _ in range(cycles):
        for j in range(len(G_c)):
            out[j] = P
            GP = G_c[j] @ P
            P = A @ (P - GP.T @ np.linalg.solve(GP @ G_c[j].T + R_c[j], GP)) @ A.T + Q
            P = (P + P.T) / 2
    return out


def test_a_converging_cycle_gives_the_limit_of_its_recursion():
    """The lifted system's DARE gives the recursion's limit to rounding; the recursion's own stopping
    rule (a cycle changing P by <= 1e-12) stopped 7 % off in the displacement variance here: the
    cycle contracts by ~0.999, so a small change per cycle is no small error."""
    args = _system(observe_walk=True)
    new, old, limit = K._periodic_riccati(*args), _old_rule(*args), _limit(*args)
    scale = np.abs(limit).max()
    assert np.abs(K._lifted_cycle_start(*args[:4]) - limit[0]).max() <= 1e-12 * scale
    assert new is not None and np.abs(new - limit).max() <= 1e-12 * scale
    assert np.abs(old[:, 0, 0] - limit[:, 0, 0]).max() > 0.05 * limit[0, 0, 0]
    np.testing.assert_allclose(np.diagonal(new, axis1=1, axis2=2), np.diagonal(limit, axis1=1, axis2=2), rtol=1e-10)


def test_a_cycle_longer_than_the_lifted_limit_still_converges(monkeypatch):
    """Without the lifted start (a cycle beyond LIFTED_CYCLE steps) the recursion runs from the
    start given, as before."""
    monkeypatch.setattr(K, "LIFTED_CYCLE", 1)
    args = _system(observe_walk=True)
    assert K._lifted_cycle_start(*args[:4]) is None
    assert np.array_equal(K._periodic_riccati(*args), _old_rule(*args))


def test_a_cycle_that_leaves_a_random_walk_unobserved_is_given_up_early(monkeypatch):
    """The walk is seen by no channel: its variance grows by Q every step, without end."""
    args = _system(observe_walk=False)
    solves, real = [], np.linalg.solve
    monkeypatch.setattr(np.linalg, "solve", lambda a, b: solves.append(1) or real(a, b))
    assert K._periodic_riccati(*args) is None
    steps = len(solves)
    assert _old_rule(*args) is None
    assert steps <= 2 * (K.CYCLE_DIVERGED + 50) + 10 and len(solves) - steps == K.CYCLE_STEPS, (steps, len(solves))


def test_the_lifted_start_holds_for_longer_cycles_and_correlated_noise():
    """A 4-state system, 3 channels with correlated noise, a cycle of 5 patterns (masked as the
    filter masks them): the lifted start is the recursion's limit."""
    rng = np.random.default_rng(7)
    n, m = 4, 3
    A = 0.97 * np.linalg.qr(rng.standard_normal((n, n)))[0]
    B = rng.standard_normal((n, n))
    Q = 1e-2 * B @ B.T
    C = rng.standard_normal((m, m))
    R = C @ C.T + 0.1 * np.eye(m)
    seen = np.array([[1, 1, 1], [1, 0, 0], [0, 1, 1], [1, 0, 1], [0, 0, 0]], bool)
    G_c, R_c = K.masked(np.broadcast_to(rng.standard_normal((m, n)), (5, m, n)),
                        np.broadcast_to(R, (5, m, m)), seen)
    args = (A, Q, G_c, R_c, np.eye(n))
    start = K._lifted_cycle_start(*args[:4])
    new, limit = K._periodic_riccati(*args), _limit(*args, cycles=3000)
    assert np.abs(start - limit[0]).max() <= 1e-11 * np.abs(limit).max()
    assert np.abs(new - limit).max() <= 1e-12 * np.abs(limit).max()
