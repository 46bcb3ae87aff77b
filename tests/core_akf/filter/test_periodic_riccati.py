"""The periodic covariance recursion of a cycle of observation patterns (a channel at half the
rate): a cycle that leaves a random walk unobserved is given up after CYCLE_DIVERGED cycles (it
ran 20000 steps per candidate before: a locate over an impact file with one channel at another
rate took over 10 minutes), and a cycle that converges gives the same covariances as before."""
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


def test_a_converging_cycle_gives_the_same_covariances():
    args = _system(observe_walk=True)
    new, old = K._periodic_riccati(*args), _old_rule(*args)
    assert new is not None and np.array_equal(new, old)


def test_a_cycle_that_leaves_a_random_walk_unobserved_is_given_up_early(monkeypatch):
    """The walk is seen by no channel: its variance grows by Q every step, without end."""
    args = _system(observe_walk=False)
    solves, real = [], np.linalg.solve
    monkeypatch.setattr(np.linalg, "solve", lambda a, b: solves.append(1) or real(a, b))
    assert K._periodic_riccati(*args) is None
    steps = len(solves)
    assert _old_rule(*args) is None
    assert steps <= 2 * (K.CYCLE_DIVERGED + 50) and len(solves) - steps == K.CYCLE_STEPS, (steps, len(solves))
