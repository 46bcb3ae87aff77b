"""The fixed-gain filter whose gain switches from step to step (a record with missing samples).

``X_k = F_i X_k-1 + L_i y_k`` with ``F_i = (I - L_i G_i) A`` and ``i = which[k]``, the gain of step
``k`` (:func:`core_akf.filter.kernels.steady_gapped` picks it from the pattern of observed
channels).  A step-by-step loop costs a Python round trip per step; this module runs the same
recursion in three ways, each exact up to rounding (``tests/core_akf/filter/test_switched.py`` pins them
against the plain loop):

- a stretch of one gain of :data:`LIFT_FROM` steps or more runs lifted
  (:func:`~.recursion.lti_response`);
- a stretch of one repeating cycle of gains (a slow channel sampled every ``p``-th step, as with
  mixed sampling rates) of :data:`LIFT_FROM` steps or more runs lifted over the cycle: the map
  over one period ``x -> Phi x + v_c``, then the phases filled in, each phase for all periods
  at once;
- the rest -- stretches of one gain between holes -- is cut into chunks of ``2^q`` steps
  (largest first).  Each chunk's zero-state end ``v = sum_j F^(K-1-j) L y_j`` comes from a
  recursion over the chunks' phases, all chunks of one gain at once; then one loop over the
  chunks in time order, ``x <- F^K x + v``; then the chunks' inner steps, again a phase at a time.
  A stretch of 29 steps is four round trips (16 + 8 + 4 + 1) instead of 29;
- a step whose gain is one of many used once each (the exact covariance recursion through a
  hole, from :func:`~core_akf.filter.kernels.steady_gapped`) runs as it is,
  ``x <- A x - L (G A x - y)``, without forming its ``F``.
"""
from __future__ import annotations

import numpy as np

from .recursion import lti_response

#: a stretch of one gain (or of one cycle of gains) this long runs lifted
LIFT_FROM = 256
#: the largest chunk of a stretch of one gain between holes, in steps (a power of two)
LARGEST_CHUNK = 128


def switched_filter(A, G, L, which, Y0, x, period=1, out=None, fixed=None):
    """The fixed-gain filter of one record whose gain switches from step to step.

    Parameters
    ----------
    A : ndarray (n, n)
    G : ndarray (E, m, n)
        The (masked) observation of each gain.
    L : ndarray (E, n, m)
        The gains.
    which : ndarray (N,) of int
        The gain of each step.
    Y0 : ndarray (N, m)
        Measurements, zero where missing.
    x : ndarray (n,)
        Prior mean of the first step.
    period : int
        The cycle of gains to look for (1: stretches of one gain only).
    out : ndarray (N, n), optional
        Where to write the states (C-contiguous).
    fixed : int, optional
        Gains ``0 .. fixed-1`` run through their ``F`` (lifted or chunked); the steps of the others
        run one at a time (default: all through ``F``).

    Returns
    -------
    ndarray (N, n)
        The filtered states.
    """
    which = np.asarray(which, np.int64)
    N, n = len(which), A.shape[-1]
    E = len(L) if fixed is None else int(fixed)
    I_LG = np.eye(n) - L[:E] @ G[:E]              # kernels.closed_loop, which imports this module
    F = I_LG @ A
    Ft = np.ascontiguousarray(np.swapaxes(F, -1, -2))
    Lt = np.ascontiguousarray(np.swapaxes(L, -1, -2))
    X = np.empty((N, n)) if out is None else out
    one = which >= E                                            # the steps run one at a time
    if one[0]:
        _one_at_a_time(X, A, G, L, which, Y0, 0, 1, x)
    else:
        X[0] = I_LG[which[0]] @ x + L[which[0]] @ Y0[0]
    if N == 1:
        return X
    blocks = _lifted_runs(np.where(one, -1 - np.arange(N), which), period)     # no lifting across them
    free = ~one
    free[0] = False
    for a, b, _ in blocks:
        free[a:b] = False
    edges = np.flatnonzero(np.diff(np.r_[False, one[1:], False].astype(np.int8)))
    blocks = sorted(blocks + [(int(a) + 1, int(b) + 1, 0) for a, b in zip(edges[::2], edges[1::2])])
    chunks = _Chunks(which, free, F, Ft, Lt, Y0)
    ends = [X[e] for e in chunks.end.tolist()]                 # views of the rows the loop writes
    powers = [chunks.power_t[i] for i in chunks.power.tolist()]
    inputs, dot, add = list(chunks.v), np.dot, np.add
    k = 0                                        # chunks before this one are done
    for a, b, p in blocks + [(N, N, -1)]:
        k1 = chunks.first_after(a)
        x_prev = X[chunks.start[k] - 1] if k < k1 else None
        for i in range(k, k1):                   # x <- F^K x + v, in place
            xe = ends[i]
            dot(x_prev, powers[i], out=xe)
            add(xe, inputs[i], out=xe)
            x_prev = xe
        k = k1
        if a == N:
            break
        if p == 0:
            _one_at_a_time(X, A, G, L, which, Y0, a, b, A @ X[a - 1])
        elif p == 1:
            e = which[a]
            X[a - 1:b] = lti_response(F[e][None], L[e][None], Y0[None, a - 1:b], X[a - 1][None])[0]
        else:
            _periodic(X, F, Ft, Lt, Y0, which[a:a + p], a, b)
    chunks.fill(X)
    return X


def _one_at_a_time(X, A, G, L, which, Y0, a, b, z):
    """Steps ``a .. b-1`` of :func:`switched_filter`, each with its own gain, from the prior mean
    ``z`` of step ``a``: ``x = z - L (G z - y)``, then ``z = A x``."""
    for k in range(a, b):
        e = which[k]
        x = X[k]
        np.subtract(z, L[e] @ (G[e] @ z - Y0[k]), out=x)
        z = A @ x


def repeats(which, p):
    """The runs ``[(a, b)]`` over which ``which`` repeats with period ``p``: ``which[k] ==
    which[k - p]`` for every ``a + p <= k < b`` (maximal, ``b - a > p``).

    Parameters
    ----------
    which : ndarray (N,) of int
    p : int

    Returns
    -------
    list of (int, int)
    """
    if len(which) <= p:
        return []
    same = np.r_[False, which[p:] == which[:-p], False]         # same[k - p + 1]: which[k] == which[k - p]
    edges = np.flatnonzero(np.diff(same.astype(np.int8)))
    return [(int(r0), int(r1) + p) for r0, r1 in zip(edges[::2], edges[1::2])]


def _lifted_runs(which, period):
    """The stretches ``[(a, b, p)]`` (``a >= 1``) that run lifted: one gain (``p = 1``) or one cycle
    of ``p`` gains (``b - a`` a whole number of cycles), each at least :data:`LIFT_FROM` long."""
    runs = []
    for p in sorted({1, int(period)}):
        for a, b in repeats(which, p):
            a = max(a, 1)
            if p > 1:
                if np.all(which[a:b] == which[a]):
                    continue                                    # one gain: found with p = 1
                b = a + (b - a) // p * p
            if b - a >= LIFT_FROM:
                runs.append((a, b, p))
    runs.sort()
    kept, end = [], 0
    for a, b, p in runs:                                        # a constant stretch inside a cycle's run
        if a >= end:
            kept.append((a, b, p))
            end = b
    return kept


def _periodic(X, F, Ft, Lt, Y0, cycle, a, b):
    """Steps ``a .. b-1`` of :func:`switched_filter` whose gains repeat ``cycle`` (``p`` gains), from
    ``X[a - 1]``: the period map ``x -> Phi x + v_c`` and its lifted run over the periods, then the
    phases, each for all periods at once (written in place, through strides)."""
    p, n, m = len(cycle), F.shape[-1], Y0.shape[1]
    periods = (b - a) // p
    psi, blocks = np.eye(n), [None] * p
    for j in range(p - 1, -1, -1):                # Psi_j = F_(p-1) ... F_(j+1); its input block (Psi_j L_j)^T
        blocks[j] = Lt[cycle[j]] @ psi.T
        psi = psi @ F[cycle[j]]
    inputs = np.zeros((1, periods + 1, n))
    inputs[0, 1:] = np.ascontiguousarray(Y0[a:b]).reshape(periods, p * m) @ np.vstack(blocks)
    ends = lti_response(psi[None], np.eye(n)[None], inputs, X[a - 1][None])[0]   # psi = Phi; x at each period's end
    Xp, Yp, u = X[a:b].reshape(periods, p, n), Y0[a:b].reshape(periods, p, m), np.empty((periods, n))
    prev = ends[:-1]
    for j in range(p - 1):
        np.matmul(prev, Ft[cycle[j]], out=Xp[:, j])
        np.matmul(Yp[:, j], Lt[cycle[j]], out=u)
        Xp[:, j] += u
        prev = Xp[:, j]
    Xp[:, p - 1] = ends[1:]


class _Chunks:
    """The steps of :func:`switched_filter` that are not lifted, as chunks of ``2^q`` steps of one
    gain in time order: ``start``, ``end`` (last step), ``size`` and ``gain`` per chunk, the index
    ``power`` of its ``F^size`` (transposed, in ``power_t``) and its zero-state end ``v``."""

    def __init__(self, which, free, F, Ft, Lt, Y0):
        self.F, self.Ft, self.Lt, self.Y0 = F, Ft, Lt, Y0
        steps = np.flatnonzero(free)
        if not len(steps):
            self.start = self.end = np.zeros(0, np.int64)
            self.v = np.zeros((0, F.shape[-1]))
            self.power, self.power_t, self.groups = np.zeros(0, np.int64), [], []
            return
        # stretches of one gain among the free steps
        cut = np.r_[True, (np.diff(steps) != 1) | (which[steps[1:]] != which[steps[:-1]])]
        first = steps[cut]
        length = np.diff(np.r_[np.flatnonzero(cut), len(steps)])
        starts, sizes, gains = [], [], []
        step = LARGEST_CHUNK
        done = np.zeros_like(length)
        while step >= 1:                                        # largest chunks first
            count = (length - done) // step
            owner = np.repeat(np.arange(len(first)), count)
            nth = np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)
            starts.append(first[owner] + done[owner] + nth * step)
            sizes.append(np.full(len(owner), step))
            gains.append(which[first[owner]])
            done = done + count * step
            step //= 2
        start, size, gain = np.concatenate(starts), np.concatenate(sizes), np.concatenate(gains)
        order = np.argsort(start, kind="stable")
        self.start, self.size, self.gain = start[order], size[order], gain[order]
        self.end = self.start + self.size - 1
        # F^size of each (gain, size), by repeated squaring
        self.power = np.empty(len(self.start), np.int64)
        self.power_t = []
        key = self.gain * (2 * LARGEST_CHUNK) + self.size
        for code in np.unique(key):
            e, K = divmod(int(code), 2 * LARGEST_CHUNK)
            M = F[e]
            for _ in range(K.bit_length() - 1):
                M = M @ M
            self.power[key == code] = len(self.power_t)
            self.power_t.append(np.ascontiguousarray(M.T))
        # zero-state ends: singles are L y_k; longer chunks a phase at a time, per gain
        self.v = np.empty((len(self.start), F.shape[-1]))
        single = self.size == 1
        for e, idx in gain_groups(self.gain, single):
            self.v[idx] = Y0[self.start[idx]] @ Lt[e]
        self.groups = []
        for e, idx in gain_groups(self.gain, ~single):
            idx = idx[np.argsort(-self.size[idx], kind="stable")]          # longest first
            s, K = self.start[idx], self.size[idx]
            longer = np.searchsorted(-K, -np.arange(int(K[0]) + 1), side="left")    # longer[j]: chunks with K > j
            self.groups.append((e, idx, s, longer))
            z = Y0[s] @ Lt[e]
            for j in range(1, int(K[0])):
                z = z[:longer[j]] @ Ft[e] + Y0[s[:longer[j]] + j] @ Lt[e]
                done = slice(longer[j + 1], longer[j])                    # chunks whose last step is j
                self.v[idx[done]] = z[done]

    def first_after(self, a):
        """The number of chunks that start before step ``a``."""
        return int(np.searchsorted(self.start, a))

    def fill(self, X):
        """The inner steps of every chunk longer than one, from the state before it."""
        for e, idx, s, longer in self.groups:
            prev = X[s - 1]
            for j in range(int(self.size[idx[0]]) - 1):
                prev = prev[:longer[j + 1]] @ self.Ft[e] + self.Y0[s[:longer[j + 1]] + j] @ self.Lt[e]
                X[s[:longer[j + 1]] + j] = prev


def gain_groups(gain, mask=None):
    """The steps (or chunks) of each gain: ``[(gain, indices), ...]``, one stable sort.

    Parameters
    ----------
    gain : ndarray (N,) of int
    mask : ndarray (N,) of bool, optional
        Only these.

    Returns
    -------
    list of (int, ndarray of int)
    """
    idx = np.arange(len(gain)) if mask is None else np.flatnonzero(mask)
    if not len(idx):
        return []
    g = gain[idx]
    idx = idx[np.argsort(g.astype(np.int16) if g.max(initial=0) < 2 ** 15 else g, kind="stable")]   # int16: a radix sort
    bounds = np.r_[0, np.flatnonzero(np.diff(gain[idx])) + 1, len(idx)]
    return [(int(gain[idx[a]]), idx[a:b]) for a, b in zip(bounds[:-1], bounds[1:])]
