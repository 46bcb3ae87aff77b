"""The Rauch-Tung-Striebel smoother: the states of every step given the whole record, with their
covariances (how sure the estimate is).

A filter estimates the state of step k from the record up to k; the smoother uses the record
after k as well.  After the forward filter (posterior ``x_k|k``, ``P_k|k`` and prior
``x_k+1|k``, ``P_k+1|k``) the backward pass is::

    C_k     = P_k|k A^T P_k+1|k^-1
    x_k|N   = x_k|k + C_k (x_k+1|N - x_k+1|k)
    P_k|N   = P_k|k + C_k (P_k+1|N - P_k+1|k) C_k^T

Both passes hold the covariances only while they change: once the forward covariance has
converged (the steady-state filter from the start, or the time-varying one after its transient)
the smoother gain ``C`` is constant, the states follow the lifted recursion
``x_k|N = C x_k+1|N + (I - C A) x_k|k`` run backwards (:func:`core_akf.recursion.lti_response`),
and the smoothed covariance is the backward recursion from ``P_N-1|N = P_N-1|k`` until it too has
converged.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .checks import as_finite_array, check_covariance
from .exceptions import AKFInputError
from .recursion import lti_response
from .steady import steady_states
from .types import ArrayLike, FloatArray, Matrix, Measurements

#: a covariance counts as converged when it changes by less than this, relatively, over a step
CONVERGED = 1e-14


@dataclass
class SmoothResult:
    """Outcome of :func:`smooth`.

    Attributes
    ----------
    states : ndarray (N, n)
        The smoothed states ``x_k|N``.
    covariances : ndarray (N, n, n) or (N, n) or None
        Their covariances ``P_k|N``; the diagonal (the variances) with ``covariances="diagonal"``;
        None with ``covariances=None``.
    filtered : ndarray (N, n)
        The filtered states ``x_k|k`` of the forward pass.
    gain : ndarray (n, n)
        The smoother gain ``C`` of the converged part (the last one of the backward pass).
    output_std : ndarray (N, k) or None
        The standard deviation of the outputs ``H x_k|N`` of the rows ``outputs`` given to
        :func:`smooth` (None without them).
    """

    states: FloatArray
    covariances: FloatArray | None
    filtered: FloatArray
    gain: FloatArray
    output_std: FloatArray | None = None

    @property
    def std(self):
        """The standard deviation of every smoothed state, shape (N, n) (the square root of the
        variances; needs ``covariances`` other than None)."""
        if self.covariances is None:
            raise AKFInputError("the smoother ran with covariances=None: there are no standard deviations")
        var = self.covariances if self.covariances.ndim == 2 else np.diagonal(self.covariances, axis1=1, axis2=2)
        return np.sqrt(np.maximum(var, 0.0))


def smooth(A_a: Matrix, G_a: ArrayLike, Q_a: Matrix, R: Matrix, Y: Measurements, x0: ArrayLike | None = None,
           P0: Matrix | None = None, steady: bool = False, covariances: str | None = "full",
           outputs: ArrayLike | None = None) -> SmoothResult:
    """Smoothed states of the AKF (the RTS smoother), with their covariances.

    Parameters
    ----------
    A_a : ndarray (n, n)
        Augmented transition matrix.
    G_a : ndarray (m, n)
        Augmented observation.
    Q_a : ndarray (n, n)
        Process covariance.
    R : ndarray (m, m)
        Measurement-noise covariance.
    Y : ndarray (N, m)
        Measurements.
    x0, P0 : optional
        Prior mean (default 0) and covariance (default ``Q_a``) at step 0, as in
        :func:`core_akf.filter.run`; the steady form starts from the steady prior covariance.
    steady : bool
        The steady-state filter and smoother gains from the first step.
    covariances : "full", "diagonal" or None
        The smoothed covariances to return: every matrix (N, n, n), the variances (N, n), or none.
    outputs : ndarray (k, n), optional
        Output rows ``H``: the standard deviation of ``H x_k|N`` is computed in the backward pass
        (:attr:`SmoothResult.output_std`), without holding the covariances.

    Returns
    -------
    SmoothResult

    Examples
    --------
    A random walk observed in noise: the smoother, which sees the whole record, is surer of every
    step than the filter.

    >>> import numpy as np
    >>> y = np.cumsum(np.random.default_rng(0).normal(size=200))[:, None] + np.random.default_rng(1).normal(size=(200, 1))
    >>> res = smooth(np.eye(1), np.eye(1), np.eye(1), np.eye(1), y, steady=True)
    >>> res.states.shape, bool(res.std[100, 0] < res.std[-1, 0])     # the last step has no future data
    ((200, 1), True)
    """
    A = as_finite_array(A_a, "A_a", ndim=2)
    G = as_finite_array(G_a, "G_a", ndim=2)
    n, m = A.shape[0], G.shape[0]
    Q = check_covariance(Q_a, "Q_a")
    Rm = check_covariance(R, "R", definite=True)
    Y = as_finite_array(Y, "Y", ndim=2)
    if A.shape != (n, n) or G.shape[1] != n or Q.shape != (n, n) or Rm.shape != (m, m) or Y.shape[1] != m:
        raise AKFInputError(f"shapes do not fit: A_a {A.shape}, G_a {G.shape}, Q_a {Q.shape}, R {Rm.shape}, Y {Y.shape}")
    if covariances not in ("full", "diagonal", None):
        raise AKFInputError(f"covariances must be 'full', 'diagonal' or None, got {covariances!r}")
    x = np.zeros(n) if x0 is None else as_finite_array(x0, "x0", ndim=1, shape=(n,))
    H = None if outputs is None else as_finite_array(outputs, "outputs", ndim=2)
    if H is not None and H.shape[1] != n:
        raise AKFInputError(f"outputs must have {n} columns (the states), got shape {H.shape}")
    if steady:
        X, L, P = steady_states(A[None], G[None], Q[None], Rm[None], Y[None], x[None])
        forward = _Forward.steady(A, G, Rm, x, X[0], P[0], L[0])
    else:
        P = Q.copy() if P0 is None else check_covariance(P0, "P0")
        forward = _Forward.time_varying(A, G, Q, Rm, Y, x, P)
    return forward.backward(A, covariances, H)


class _Forward:
    """The forward pass: filtered states of every step, and the covariances up to step ``ks``, after
    which they are constant (``P_post``, ``P_prior``)."""

    def __init__(self, X, X_prior, posts, priors, ks):
        self.X, self.X_prior, self.posts, self.priors, self.ks = X, X_prior, posts, priors, ks

    @classmethod
    def steady(cls, A, G, R, x, X, P, L):
        """From the steady filter's states ``X``, prior covariance ``P`` and gain ``L``."""
        I_LG = np.eye(A.shape[0]) - L @ G
        post = I_LG @ P @ I_LG.T + L @ R @ L.T                     # Joseph form: symmetric PSD
        X_prior = np.vstack([x, X[:-1] @ A.T])
        return cls(X, X_prior, [0.5 * (post + post.T)], [P], 0)

    @classmethod
    def time_varying(cls, A, G, Q, R, Y, x, P):
        N, n = Y.shape[0], A.shape[0]
        X, X_prior = np.empty((N, n)), np.empty((N, n))
        posts, priors = [], []
        for k in range(N):
            X_prior[k] = x
            S = G @ P @ G.T + R
            L = np.linalg.solve(S, G @ P).T
            I_LG = np.eye(n) - L @ G
            post = I_LG @ P @ I_LG.T + L @ R @ L.T
            post = 0.5 * (post + post.T)
            x = x + L @ (Y[k] - G @ x)
            X[k] = x
            posts.append(post)
            priors.append(P)
            P_next = A @ post @ A.T + Q
            P_next = 0.5 * (P_next + P_next.T)
            if np.linalg.norm(P_next - P) <= CONVERGED * np.linalg.norm(P) and k + 1 < N:
                # converged: the steady recursion from here on, with this gain
                rest = Y[k + 1:]
                first = L @ rest[0] + I_LG @ (A @ x)
                X[k + 1:] = lti_response((I_LG @ A)[None], L[None], rest[None], first[None])[0]
                X_prior[k + 1:] = X[k:-1] @ A.T
                return cls(X, X_prior, posts, priors, k)
            x = A @ x
            P = P_next
        return cls(X, X_prior, posts, priors, N - 1)

    def post(self, k):
        return self.posts[min(k, self.ks)]

    def prior(self, k):
        return self.priors[min(k, self.ks)]

    def backward(self, A, covariances, H=None):
        X, N, n = self.X, self.X.shape[0], self.X.shape[1]
        Xs = np.empty_like(X)
        Xs[-1] = X[-1]
        full = covariances == "full"
        Ps = None if covariances is None else (np.empty((N, n, n)) if full else np.empty((N, n)))
        out_var = None if H is None else np.empty((N, H.shape[0]))
        P_s = self.post(N - 1)

        def store(k, P):
            if Ps is not None:
                Ps[k] = P if full else np.diagonal(P)
            if out_var is not None:
                out_var[k] = np.einsum("ij,jk,ik->i", H, P, H)
        store(N - 1, P_s)

        def gain(k):                                   # P_k|k A^T P_k+1|k^-1 (both symmetric)
            return np.linalg.solve(self.prior(k + 1), A @ self.post(k)).T
        # the steady stretch: steps ks .. N-2 share one gain; the states by the lifted recursion backwards
        k = N - 2
        if self.ks < N - 1:
            C = gain(self.ks)
            start = self.ks
            Xs[start:N - 1] = _backward_states(C, np.eye(n) - C @ A, X, start, N)
            if Ps is not None or out_var is not None:
                post, prior = self.post(start), self.prior(start + 1)
                converged = False
                for k in range(N - 2, start - 1, -1):
                    if not converged:
                        nxt = post + C @ (P_s - prior) @ C.T
                        nxt = 0.5 * (nxt + nxt.T)
                        converged = np.linalg.norm(nxt - P_s) <= CONVERGED * np.linalg.norm(nxt)
                        P_s = nxt
                    store(k, P_s)
            k = start - 1
        else:
            C = np.zeros((n, n))
        while k >= 0:
            C = gain(k)
            Xs[k] = X[k] + C @ (Xs[k + 1] - self.X_prior[k + 1])
            P_s = self.post(k) + C @ (P_s - self.prior(k + 1)) @ C.T
            P_s = 0.5 * (P_s + P_s.T)
            store(k, P_s)
            k -= 1
        return SmoothResult(Xs, Ps, X, C, None if out_var is None else np.sqrt(np.maximum(out_var, 0.0)))


def _backward_states(C, I_CA, X, start, N):
    """``x_k|N = C x_k+1|N + (I - C A) x_k|k`` for k = N-2 down to ``start``, from ``x_N-1|N = x_N-1|N-1``."""
    seg = X[start:N - 1][::-1]                     # x_k|k, k = N-2 .. start
    first = C @ X[-1] + I_CA @ seg[0]
    out = lti_response(C[None], I_CA[None], seg[None], first[None])[0]
    return out[::-1]
