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
``x_k|N = C x_k+1|N + (I - C A) x_k|k`` run backwards (:func:`core_akf.filter.recursion.lti_response`),
and the smoothed covariance is the backward recursion from ``P_N-1|N = P_N-1|k`` until it too has
converged.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..checks import AKFInputError, ArrayLike, FloatArray, Matrix, Measurements, as_finite_array, as_measurements, check_covariance
from .kernels import fixed_gain, masked, steady_states
from .recursion import lti_response
from .riccati import steady_gain

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
        Measurements, NaN where a sample is missing (the exact filter runs through it).
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
    Y = as_measurements(Y, "Y", ndim=2)
    if A.shape != (n, n) or G.shape[1] != n or Q.shape != (n, n) or Rm.shape != (m, m) or Y.shape[1] != m:
        raise AKFInputError(f"shapes do not fit: A_a {A.shape}, G_a {G.shape}, Q_a {Q.shape}, R {Rm.shape}, Y {Y.shape}")
    if covariances not in ("full", "diagonal", None):
        raise AKFInputError(f"covariances must be 'full', 'diagonal' or None, got {covariances!r}")
    x = np.zeros(n) if x0 is None else as_finite_array(x0, "x0", ndim=1, shape=(n,))
    H = None if outputs is None else as_finite_array(outputs, "outputs", ndim=2)
    if H is not None and H.shape[1] != n:
        raise AKFInputError(f"outputs must have {n} columns (the states), got shape {H.shape}")
    seen = ~np.isnan(Y)
    if not seen.all():                                 # missing samples: the exact filter, then RTS
        P = (steady_gain(A[None], G[None], Q[None], Rm[None])[0][0] if steady
             else Q.copy() if P0 is None else check_covariance(P0, "P0"))
        forward = _GappedForward(A, G, Q, Rm, Y, seen, x, P)
    elif steady:
        res = steady_states(A[None], G[None], Q[None], Rm[None], Y[None], x[None])
        forward = _Forward.steady(A, G, Rm, x, res.states[0], res.P_prior[0], res.gain[0])
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
        X_prior = np.vstack([x, X[:-1] @ A.T])
        return cls(X, X_prior, [_posterior(P, L, G, R)], [P], 0)

    @classmethod
    def time_varying(cls, A, G, Q, R, Y, x, P):
        N, n = Y.shape[0], A.shape[0]
        X, X_prior = np.empty((N, n)), np.empty((N, n))
        posts, priors = [], []
        for k in range(N):
            X_prior[k] = x
            S = G @ P @ G.T + R
            L = np.linalg.solve(S, G @ P).T
            post = _posterior(P, L, G, R)
            x = x + L @ (Y[k] - G @ x)
            X[k] = x
            posts.append(post)
            priors.append(P)
            P_next = A @ post @ A.T + Q
            P_next = 0.5 * (P_next + P_next.T)
            if np.linalg.norm(P_next - P) <= CONVERGED * np.linalg.norm(P) and k + 1 < N:
                # converged: the steady recursion from here on, with this gain
                X[k + 1:] = fixed_gain(A[None], G[None], L[None], Y[None, k + 1:], (A @ x)[None])[0]
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


class _GappedForward(_Forward):
    """The exact forward pass through missing samples (:func:`core_akf.filter.kernels.masked`), in
    ``O(sqrt(N) n^2)`` memory: the prior covariance is kept every ``K ~ sqrt(N)`` steps, and the
    covariances of a stretch are computed again, from its first step, when the backward pass
    reaches it (twice the covariance work of the forward pass, the same numbers)."""

    def __init__(self, A, G, Q, R, Y, seen, x, P):
        N, n = Y.shape[0], A.shape[0]
        self.A, self.G, self.Q, self.R, self.seen = A, G, Q, R, seen
        self.K = max(16, int(np.sqrt(N)))
        X, X_prior, checkpoints = np.empty((N, n)), np.empty((N, n)), []
        Y0 = np.where(seen, Y, 0.0)
        for k in range(N):
            if k % self.K == 0:
                checkpoints.append(P)
            X_prior[k] = x
            L, post = self._update(P, k)
            x = x + L @ (Y0[k] - self._observation(k)[0] @ x)
            X[k] = x
            x = A @ x
            P = self._predict(post)
        super().__init__(X, X_prior, [], [], N - 1)
        self.checkpoints, self._held = checkpoints, {}

    def _observation(self, k):
        G_k, R_k = masked(self.G[None], self.R[None], self.seen[k][None])
        return G_k[0], R_k[0]

    def _update(self, P, k):
        G_k, R_k = self._observation(k)
        L = np.linalg.solve(G_k @ P @ G_k.T + R_k, G_k @ P).T
        return L, _posterior(P, L, G_k, R_k)

    def _predict(self, post):
        P = self.A @ post @ self.A.T + self.Q
        return 0.5 * (P + P.T)

    def _stretch(self, c):
        """The (posterior, prior) covariances of the steps of stretch ``c``, computed again."""
        if c not in self._held:
            if len(self._held) > 1:                     # the backward pass needs this stretch and the next
                self._held.pop(max(self._held))
            P, posts, priors = self.checkpoints[c], [], []
            for k in range(c * self.K, min((c + 1) * self.K, self.X.shape[0])):
                priors.append(P)
                post = self._update(P, k)[1]
                posts.append(post)
                P = self._predict(post)
            self._held[c] = (posts, priors)
        return self._held[c]

    def post(self, k):
        return self._stretch(k // self.K)[0][k % self.K]

    def prior(self, k):
        return self._stretch(k // self.K)[1][k % self.K]


def _posterior(P, L, G, R):
    """The filtered covariance ``(I - L G) P (I - L G)^T + L R L^T`` (Joseph form: symmetric PSD)."""
    I_LG = np.eye(P.shape[0]) - L @ G
    post = I_LG @ P @ I_LG.T + L @ R @ L.T
    return 0.5 * (post + post.T)


class FixedLagSmoother:
    """The states ``x_k|k+lag`` of a steady-state filter, chunk by chunk, in constant memory.

    With constant gains the RTS correction of step k is a finite sum over the innovations after
    it (``C`` the smoother gain, ``L`` the filter gain)::

        x_k|k+lag = x_k|k + sum_{i=1..lag} C^i L e_k+i

    :meth:`update` takes the filter's states and innovations of the next chunk and returns the
    smoothed states of the steps whose ``lag`` following steps have arrived: the output runs
    ``lag`` steps behind the input, and only those ``lag`` steps are held between chunks.  Each
    is exactly the RTS smoother's estimate on the record up to ``k + lag``, wherever the chunks
    end.  :meth:`finish` returns the last ``lag`` steps (smoothed with what follows them: the RTS
    smoother of the whole record there).  Their standard deviations come with them for the rows
    ``outputs``.

    Parameters
    ----------
    A, G : ndarray (n, n), (m, n)
        Transition and observation of the filter.
    R : ndarray (m, m)
        Measurement-noise covariance.
    P : ndarray (n, n)
        The steady prior covariance ``P_k+1|k``.
    L : ndarray (n, m)
        The steady filter gain.
    lag : int or "auto"
        Steps of the record after each step that smooth it (>= 1); "auto": :meth:`auto_lag`.
    outputs : ndarray (k, n), optional
        Rows ``H`` whose standard deviation is returned (None: none).

    Examples
    --------
    A random walk in noise, in chunks of 70 steps with a lag of 40: the steady RTS smoother of
    the record up to each step + 40.

    >>> import numpy as np
    >>> from core_akf.filter.kernels import steady_states
    >>> y = np.cumsum(np.random.default_rng(0).normal(size=300))[:, None]
    >>> A = G = Q = R = np.eye(1)
    >>> run = steady_states(A[None], G[None], Q[None], R[None], y[None], np.zeros((1, 1)))
    >>> X, L, P = run.states, run.gain, run.P_prior
    >>> E = y - np.vstack([np.zeros((1, 1)), X[0, :-1]])                    # the innovations
    >>> lagged = FixedLagSmoother(A, G, R, P[0], L[0], lag=40)
    >>> parts = [lagged.update(X[0, i:i + 70], E[i:i + 70])[0] for i in range(0, 300, 70)]
    >>> x = np.vstack(parts + [lagged.finish()[0]])
    >>> x.shape, bool(np.allclose(x[100], smooth(A, G, Q, R, y[:141], steady=True).states[100]))
    ((300, 1), True)
    """

    def __init__(self, A, G, R, P, L, lag, outputs=None):
        A, G, R, P, L = (np.asarray(a, float) for a in (A, G, R, P, L))
        post = _posterior(P, L, G, R)
        self.C = C = np.linalg.solve(P, A @ post).T                  # P_k|k A^T P_k+1|k^-1
        self.CL = C @ L
        if isinstance(lag, str) and lag == "auto":
            lag = self.auto_lag()
        if isinstance(lag, (bool, str)) or not np.isscalar(lag) or int(lag) != lag or lag < 1:
            raise AKFInputError(f"the lag must be a whole number of steps >= 1 or \"auto\", got {lag!r}")
        self.lag = int(lag)
        self.far = -np.linalg.matrix_power(C, self.lag) @ self.CL     # the term that leaves the window
        self.n, self.m = A.shape[0], G.shape[0]
        self.output_var = None
        if outputs is not None:
            H = np.asarray(outputs, float)
            var, P_l = [np.einsum("ij,jk,ik->i", H, post, H)], post
            for _ in range(self.lag):                                # P^(l) = P_post + C (P^(l-1) - P) C^T
                P_l = post + C @ (P_l - P) @ C.T
                P_l = 0.5 * (P_l + P_l.T)
                var.append(np.einsum("ij,jk,ik->i", H, P_l, H))
            self.output_var = np.maximum(np.array(var), 0.0)          # (lag + 1, k): by lag
        self.held = [np.empty((0, self.n)), np.empty((0, self.m))]   # filtered states, innovations, carried rows

    def auto_lag(self, tolerance: float | None = None, longest: int | None = None) -> int:
        """The shortest lag whose smoothing misses little: the smallest ``l`` with
        ``||C^l L|| <= tolerance ||C L||`` (the weight of the innovation ``l`` steps ahead, against
        the next one's).

        Parameters
        ----------
        tolerance : float, optional
            Default ``smooth_lag_tolerance`` (:data:`core_akf.defaults.DEFAULTS`).
        longest : int, optional
            The longest lag tried (default ``smooth_lag_longest``); reached, it is returned.

        Returns
        -------
        int
        """
        from ..defaults import default

        tolerance, longest = default("smooth_lag_tolerance", tolerance), default("smooth_lag_longest", longest)
        W, first = self.CL, np.linalg.norm(self.CL)
        lag = 1
        while lag < longest and np.linalg.norm(W) > tolerance * first:
            W = self.C @ W
            lag += 1
        return lag

    @property
    def n_held(self):
        """Steps received and not yet returned (at most ``lag``)."""
        return self.held[0].shape[0]

    def update(self, X: ArrayLike, E: ArrayLike, *carried: ArrayLike) -> tuple:
        """Take the next chunk of the filter's output; return the steps now smoothed.

        Parameters
        ----------
        X : ndarray (K, n)
            Filtered states ``x_k|k`` of the chunk.
        E : ndarray (K, m)
            Its innovations ``e_k = y_k - G x_k|k-1``.
        *carried : ndarray (K, ...)
            Rows of the same steps to return with them (measurements, ...), delayed alike.

        Returns
        -------
        tuple
            ``(states, output_std, *carried)`` of the steps returned (``max(0, held + K - lag)``
            rows, the oldest first); ``output_std`` is None without ``outputs``.
        """
        X, E = np.asarray(X, float), np.asarray(E, float)
        if X.ndim != 2 or E.ndim != 2 or X.shape[1] != self.n or E.shape != (X.shape[0], self.m) \
                or any(np.shape(c)[0] != X.shape[0] for c in carried):
            raise AKFInputError(f"a chunk must have states (K, {self.n}), innovations (K, {self.m}) and K rows of "
                                f"everything carried; got {X.shape}, {E.shape}")
        if len(self.held) == 2 and carried:
            self.held += [np.empty((0,) + np.shape(c)[1:]) for c in carried]
        rows = [np.concatenate([h, c]) for h, c in zip(self.held, (X, E) + carried)]
        K = max(0, rows[0].shape[0] - self.lag)
        self.held = [r[K:] for r in rows]
        if K == 0:
            return self._out(np.empty((0, self.n)), np.empty(0, int), [r[:0] for r in rows[2:]])
        Xb, Eb = rows[0], rows[1]
        delta = np.empty((K, self.n))
        delta[K - 1] = self._tail_sum(Eb[K:K + self.lag])
        if K > 1:                     # backwards: delta_j = C delta_j+1 + C L e_j+1 - C^(lag+1) L e_j+1+lag
            U = np.hstack([Eb[1:K], Eb[1 + self.lag:K + self.lag]])[::-1]
            U = np.vstack([np.zeros((1, 2 * self.m)), U])
            back = lti_response(self.C[None], np.hstack([self.CL, self.far])[None], U[None], delta[K - 1][None])[0]
            delta[:K - 1] = back[1:][::-1]
        return self._out(Xb[:K] + delta, np.full(K, self.lag), [r[:K] for r in rows[2:]])

    def finish(self) -> tuple:
        """The steps still held, smoothed with the steps after them (the end of the record).

        Returns
        -------
        tuple
            As :meth:`update`.
        """
        Xb, Eb = self.held[0], self.held[1]
        K = Xb.shape[0]
        delta = np.zeros((K, self.n))
        for j in range(K - 2, -1, -1):            # the RTS smoother's backward pass: delta_j = C (delta_j+1 + L e_j+1)
            delta[j] = self.C @ delta[j + 1] + self.CL @ Eb[j + 1]
        out = self._out(Xb + delta, np.arange(K - 1, -1, -1), self.held[2:])
        self.held = [h[:0] for h in self.held]
        return out

    def fresh(self) -> FixedLagSmoother:
        """A copy holding no steps (for a record that starts again).

        Returns
        -------
        FixedLagSmoother
        """
        import copy

        out = copy.copy(self)
        out.held = [h[:0] for h in self.held]
        return out

    def _tail_sum(self, E):
        """``sum_i C^i L e_i`` over the rows of ``E`` (i = 1..len(E)), by Horner's rule."""
        t = np.zeros(self.n)
        for e in E[::-1]:
            t = self.C @ t + self.CL @ e
        return t

    def _out(self, states, lags, carried):
        std = None if self.output_var is None else np.sqrt(self.output_var[lags])
        return (states, std, *carried)

    def state(self) -> dict[str, np.ndarray]:
        """The steps held (to save with a checkpoint; :meth:`restore` takes it back).

        Returns
        -------
        dict of str to ndarray
        """
        return {f"lag_held_{i}": h for i, h in enumerate(self.held)}

    def restore(self, state: dict) -> FixedLagSmoother:
        """Continue from a :meth:`state`.

        Parameters
        ----------
        state : mapping of str to ndarray
            What :meth:`state` returned.

        Returns
        -------
        FixedLagSmoother
            ``self``.
        """
        held = [np.asarray(state[f"lag_held_{i}"], float) for i in range(sum(k.startswith("lag_held_") for k in state))]
        if len(held) < 2 or held[0].shape[1:] != (self.n,) or held[1].shape[1:] != (self.m,) \
                or held[0].shape[0] > self.lag or any(h.shape[0] != held[0].shape[0] for h in held):
            raise AKFInputError("not the held steps of this fixed-lag smoother")
        self.held = held
        return self


def _backward_states(C, I_CA, X, start, N):
    """``x_k|N = C x_k+1|N + (I - C A) x_k|k`` for k = N-2 down to ``start``, from ``x_N-1|N = x_N-1|N-1``."""
    seg = X[start:N - 1][::-1]                     # x_k|k, k = N-2 .. start
    first = C @ X[-1] + I_CA @ seg[0]
    out = lti_response(C[None], I_CA[None], seg[None], first[None])[0]
    return out[::-1]
