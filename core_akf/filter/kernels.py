"""The AKF's kernels: pure functions over stacks (batches) of filters, and over a :class:`Filter`.

Shapes: ``A``, ``Q`` (B, n, n); ``G`` (B, m, n); ``R`` (B, m, m); ``Y`` (B, N, m); a prior mean
``x`` (B, n).  Each step first updates with ``y_k`` and then predicts; the states returned are the
filtered (posterior) ones.

Every path of the toolkit runs these:

- :func:`fixed_gain` -- THE fixed-gain continuation ``X_k = (I - L G) A X_k-1 + L y_k`` (the
  steady filter, a time-varying filter whose covariance has converged, a chunk of a stream, the
  smoother's forward pass), in lifted form (:func:`core_akf.filter.recursion.lti_response`);
  :func:`closed_loop` forms its matrices, once;
- :func:`time_varying_filter` -- the covariance recursion, step by step (cheaply for a modal
  transition, :class:`~core_akf.filter.recursion.ModalBlockTransition`), until the covariance
  has converged, then :func:`fixed_gain`;
- :func:`constant_gain` -- states, innovations and log-likelihood of a constant gain (the steady
  gain from one batched Riccati solve, :func:`core_akf.filter.riccati.steady_gain`);
- :func:`innovations` and :func:`innovation_covariance` -- the one-step prediction errors and
  their covariance; the log-likelihood is computed from them when it is asked for
  (:func:`core_akf.filter.likelihood.loglik_terms`, :func:`steady_logliks` for a stack).

:func:`steady` and :func:`time_varying` run a :class:`~core_akf.filter.model.Filter` (its modal
matrices and prior) and return a :class:`FilterRun`.  This module knows nothing of structures
or sensors.
"""
from __future__ import annotations

import hashlib
import math
import threading
import warnings
from dataclasses import dataclass

import numpy as np

from ..checks import AKFInputError
from .likelihood import loglik_terms
from .recursion import lti_response
from .riccati import RiccatiError, RiccatiWarning, steady_gain
from .switched import LIFT_FROM, gain_groups, repeats, switched_filter

#: the time-varying filter tests every this many steps whether its covariance has converged
CHECK_EVERY = 32
#: the steady filter with missing samples runs a stretch of one pattern of observed channels (or
#: of one cycle of patterns) this long with its own steady-state gains, and lifted
#: (:func:`~.switched.switched_filter`)
LONG_STRETCH = LIFT_FROM
#: the longest cycle of patterns (a slow channel sampled every p-th step) that gets periodic gains,
#: and the memory their covariances may take (bytes); a stream keeps the observed samples of its
#: last ``HISTORY`` steps, so a chunk decides on long stretches and cycles as the whole record does
MAX_CYCLE, CYCLE_BYTES = 1024, 2 ** 26
HISTORY = max(LONG_STRETCH, 2 * MAX_CYCLE)


@dataclass
class FilterRun:
    """What a kernel returns (a leading batch axis B).

    Attributes
    ----------
    states : ndarray (B, N, n)
        Filtered (posterior) states.
    innovations : ndarray (B, N, m)
        ``y_k - G X_k^-``.
    gain : ndarray (B, n, m)
        The steady-state gain, or the last one of the time-varying filter.
    P_prior : ndarray (B, n, n)
        The steady-state prior covariance, or the prior covariance of the step after the last.
    switched : bool
        Whether the filter runs with a constant gain at its end (steady, or converged).
    loglik_terms : ndarray (B, N, m) or None
        The log-likelihood of the innovations per step and channel
        (:func:`core_akf.filter.likelihood.loglik_terms`); None unless asked for.
    """

    states: np.ndarray
    innovations: np.ndarray
    gain: np.ndarray
    P_prior: np.ndarray
    switched: bool = True
    loglik_terms: np.ndarray | None = None

    @property
    def loglik(self):
        """The log-likelihood of each filter's record, shape (B,) (needs ``loglik=True``)."""
        if self.loglik_terms is None:
            raise AKFInputError("the log-likelihood was not asked for: run the kernel with loglik=True")
        return self.loglik_terms.sum(axis=(-2, -1))


# ------------------------------------------------------------------------------ the steps
def closed_loop(A, G, L):
    """The fixed-gain filter's matrices: ``I - L G`` and the closed loop ``F = (I - L G) A``.

    Parameters
    ----------
    A : ndarray (..., n, n)
    G : ndarray (..., m, n)
    L : ndarray (..., n, m)

    Returns
    -------
    I_LG, F : ndarray (..., n, n)
    """
    I_LG = np.eye(A.shape[-1]) - L @ G
    return I_LG, I_LG @ A


def fixed_gain(A, G, L, Y, x=None, outputs=None):
    """The fixed-gain filter ``X_k = (I - L G) A X_k-1 + L y_k`` over a stack of records.

    The one place every constant-gain stretch runs (lifted, :func:`~.recursion.lti_response`).

    Parameters
    ----------
    A : ndarray (B, n, n)
    G : ndarray (B, m, n)
    L : ndarray (B, n, m)
        The gain.
    Y : ndarray (B, N, m), N >= 1
        Measurements.
    x : ndarray (B, n), optional
        The prior mean of the first step (default zero).
    outputs : ndarray (B, k, n) or (k, n), optional
        Output rows ``H``: return ``H X_k`` without forming the states.

    Returns
    -------
    ndarray (B, N, n), or (B, N, k) with ``outputs``
    """
    I_LG, F = closed_loop(A, G, L)
    first = np.einsum("bij,bj->bi", L, Y[:, 0])
    if x is not None:
        first += np.einsum("bij,bj->bi", I_LG, x)
    return lti_response(F, L, Y, first, outputs)


def fixed_gain_records(A, G, L, Y):
    """:func:`fixed_gain` of each filter of a stack over several records of its own.

    The records of one filter share its closed loop, so they run as one matrix of states per
    step (the robust placement fitness: one gain per layout, a record per model and noise draw).

    Parameters
    ----------
    A : ndarray (B, n, n)
    G : ndarray (B, m, n)
    L : ndarray (B, n, m)
    Y : ndarray (B, S, N, m)
        S records per filter.

    Returns
    -------
    ndarray (B, S, N, n)
        The filtered states (prior mean zero).
    """
    _, F = closed_loop(A, G, L)
    U = Y @ np.swapaxes(L, -1, -2)[:, None]                 # (B, S, N, n): L y_k
    X = np.empty_like(U)
    x = U[:, :, 0]
    X[:, :, 0] = x
    Ft = np.swapaxes(F, -1, -2)
    for k in range(1, U.shape[2]):
        x = x @ Ft + U[:, :, k]
        X[:, :, k] = x
    return X


def innovations(A, G, X, Y, x=None):
    """The one-step prediction errors ``e_k = y_k - G A X_k-1`` of filtered states.

    Parameters
    ----------
    A : ndarray (B, n, n)
    G : ndarray (B, m, n)
    X : ndarray (B, N, n)
        Filtered states.
    Y : ndarray (B, N, m)
        Measurements.
    x : ndarray (B, n), optional
        The prior mean of the first step (default zero).

    Returns
    -------
    ndarray (B, N, m)
    """
    E = np.empty_like(Y)
    E[:, 0] = Y[:, 0] if x is None else Y[:, 0] - np.einsum("bij,bj->bi", G, x)
    E[:, 1:] = Y[:, 1:] - X[:, :-1] @ np.swapaxes(G @ A, -1, -2)      # (G A) is only m x n
    return E


def innovation_covariance(G, P, R):
    """The predicted innovation covariance ``S = G P G^T + R``, symmetrised.

    Parameters
    ----------
    G : ndarray (..., m, n)
    P : ndarray (..., n, n)
        A prior covariance.
    R : ndarray (..., m, m)

    Returns
    -------
    ndarray (..., m, m)
    """
    S = G @ P @ np.swapaxes(G, -1, -2) + R
    return 0.5 * (S + np.swapaxes(S, -1, -2))


def constant_gain(A, G, R, L, P, Y, x=None, loglik=False):
    """A stack of filters run with a constant gain: the states (:func:`fixed_gain`), the innovations
    and, when asked, their log-likelihood under the innovation covariance of ``P``.

    Parameters
    ----------
    A, G, R, Y
        As in the module's shapes.
    L : ndarray (B, n, m)
        The gain.
    P : ndarray (B, n, n)
        The prior covariance the gain belongs to.
    x : ndarray (B, n), optional
        The prior mean of the first step (default zero).
    loglik : bool
        Also the log-likelihood terms.

    Returns
    -------
    FilterRun
    """
    X = fixed_gain(A, G, L, Y, x)
    E = innovations(A, G, X, Y, x)
    terms = loglik_terms(E, innovation_covariance(G, P, R)) if loglik else None
    return FilterRun(X, E, L, P, True, terms)


def steady_states(A, G, Q, R, Y, x=None, loglik=False):
    """Filtered states of a stack of steady-state AKFs.

    Parameters
    ----------
    A, G, Q, R, Y
        As in the module's shapes.
    x : ndarray (B, n), optional
        Prior mean of the first step (default zero).
    loglik : bool
        Also the log-likelihood terms of the innovations.

    Returns
    -------
    FilterRun
    """
    P, L = steady_gain(A, G, Q, R)
    return constant_gain(A, G, R, L, P, Y, x, loglik)


def steady_outputs(A, G, Q, R, Y, H):
    """Outputs ``H X_k`` of a stack of steady-state AKFs (filtered states, prior mean zero).

    One batched Riccati solve, then the lifted recursion straight to the outputs: with few output
    rows the n states per step are never formed.  With missing samples (NaN) the states come from
    :func:`steady_gapped`.

    Parameters
    ----------
    A : ndarray (B, n, n) or (n, n)
    G : ndarray (B, m, n)
    Q : ndarray (B, n, n) or (n, n)
    R : ndarray (B, m, m)
    Y : ndarray (B, N, m)
        Measurements.
    H : ndarray (B, k, n) or (k, n)
        Output rows.

    Returns
    -------
    ndarray (B, N, k)
    """
    B, n = Y.shape[0], G.shape[-1]
    A, Q = np.broadcast_to(A, (B, n, n)), np.broadcast_to(Q, (B, n, n))
    P, L = steady_gain(A, G, Q, R)
    seen = observed(Y)
    if seen is not None:
        X = steady_gapped(A, G, Q, R, Y, seen, np.zeros((B, n)), full=(P, L)).states
        return X @ np.swapaxes(np.broadcast_to(H, (B,) + np.shape(H)[-2:]), -1, -2)
    return fixed_gain(A, G, L, Y, outputs=H)


def steady_logliks(A, G, Q, R, Y, per_step=False):
    """The log-likelihood of one record under a stack of steady-state filters.

    Parameters
    ----------
    A : ndarray (B, n, n)
    G : ndarray (B, m, n)
    Q : ndarray (B, n, n)
    R : ndarray (B, m, m)
    Y : ndarray (N, m)
        The record (SI), the same for every filter.
    per_step : bool
        Return each step's term (its channels summed) instead of the sum: the per-step scores of
        robust standard errors (:mod:`core_akf.inference`) are their differences.

    Returns
    -------
    ndarray (B,), or (B, N) with ``per_step``
        One log-likelihood per filter; ``-inf`` where the steady-state gain does not exist.

    Examples
    --------
    >>> import numpy as np
    >>> A, G = np.array([[[1.0]]]), np.array([[[1.0]]])
    >>> Y = np.random.default_rng(0).normal(size=(500, 1))
    >>> ll = steady_logliks(np.repeat(A, 2, 0), np.repeat(G, 2, 0), np.array([[[1e-6]], [[1e-6]]]),
    ...                     np.array([[[1.0]], [[4.0]]]), Y)
    >>> bool(ll[0] > ll[1])              # unit-variance data: R = 1 is likelier than R = 4
    True
    """
    Y = np.asarray(Y, float)
    B = A.shape[0]
    out = np.full((B, Y.shape[0]) if per_step else B, -np.inf)
    ok = np.arange(B)
    try:
        P, L = steady_gain(A, G, Q, R)
    except RiccatiError as exc:                        # the filters that have a steady state
        ok = np.array([b for b in range(B) if b not in set(exc.problems)], int)
        if not ok.size:
            return out
        A, G, Q, R = A[ok], G[ok], Q[ok], R[ok]
        P, L = steady_gain(A, G, Q, R)
    Ys = np.broadcast_to(Y, (ok.size,) + Y.shape)
    seen = observed(Ys)
    if seen is not None:                               # missing samples: the filter of each pattern
        run = steady_gapped(A, G, Q, R, Ys, seen, np.zeros(A.shape[:-1]), loglik=True, full=(P, L))
        out[ok] = run.loglik_terms.sum(axis=-1) if per_step else run.loglik
        return out
    predicted = fixed_gain(A, G, L, Ys, outputs=G @ A)           # G A X_k: the next step's predicted channels
    E = np.empty_like(Ys)
    E[:, 0] = Ys[:, 0]
    E[:, 1:] = Ys[:, 1:] - predicted[:, :-1]
    terms = loglik_terms(E, innovation_covariance(G, P, R))
    out[ok] = terms.sum(axis=-1) if per_step else terms.sum(axis=(1, 2))
    return out


def time_varying_filter(A, G, Q, R, Y, x, P, switch_tol, transition=None, loglik=False):
    """Time-varying AKF on a stack of B filters.

    Once the prior covariance has stopped changing (relative change over :data:`CHECK_EVERY`
    steps below ``switch_tol``, every filter of the stack), the gain is constant to that
    precision and the rest of the record runs as :func:`fixed_gain`.

    Parameters
    ----------
    A, G, Q, R, Y
        As in the module's shapes.
    x : ndarray (B, n)
        Prior mean of the first step.
    P : ndarray (B, n, n)
        Prior covariance of the first step.
    switch_tol : float
        Relative change of the covariance below which the gain is held (0: never).
    transition : ModalBlockTransition, optional
        Applies ``A`` cheaply in the covariance update.
    loglik : bool
        Also the log-likelihood terms (the innovation covariance of every step is kept until the
        switch, and the terms formed at the end in one batched call).

    Returns
    -------
    FilterRun
        ``P_prior`` the prior covariance of the next step (or, switched, the converged one).
    """
    B, N, m = Y.shape
    n = A.shape[-1]
    out = np.empty((B, N, n))
    innov = np.empty((B, N, m))
    # contiguous transposes: a batched matmul copies a strided operand at every call (70 states:
    # A P A^T 77 -> 53 us per step)
    At = np.ascontiguousarray(np.swapaxes(A, -1, -2))
    Gt = np.ascontiguousarray(np.swapaxes(G, -1, -2))
    S_steps = np.empty((B, N, m, m)) if loglik else None
    P_check = P.copy()
    for k in range(N):
        e = Y[:, k] - _times(G, x)
        PGt = P @ Gt
        S = G @ PGt + R
        GP = np.ascontiguousarray(np.swapaxes(PGt, -1, -2))                    # G P (P symmetric)
        L = np.swapaxes(np.linalg.solve(S, GP), -1, -2)                        # P G^T S^-1
        if switch_tol > 0 and k > 0 and k % CHECK_EVERY == 0:
            change = np.linalg.norm(P - P_check, axis=(-2, -1)) / np.linalg.norm(P, axis=(-2, -1))
            if np.all(change < switch_tol):
                rest = constant_gain(A, G, R, L, P, Y[:, k:], x, loglik)     # converged: one gain from here on
                out[:, k:], innov[:, k:] = rest.states, rest.innovations
                terms = None if not loglik else np.concatenate([_terms_per_step(innov[:, :k], S_steps[:, :k]),
                                                                 rest.loglik_terms], axis=1)
                return FilterRun(out, innov, L, P, True, terms)
            P_check = P.copy()
        if loglik:
            S_steps[:, k] = S
        x = x + _times(L, e)
        P = P - L @ GP                        # a new array: P0 given by the caller stays untouched
        out[:, k] = x
        innov[:, k] = e
        x = _times(A, x)
        if transition is None:
            P = A @ P @ At + Q
            P = 0.5 * (P + np.swapaxes(P, -1, -2))
        else:
            P = transition.propagate(P, Q)
    return FilterRun(out, innov, L, P, False, _terms_per_step(innov, S_steps) if loglik else None)


def _times(M, v):
    """``M v`` for a stack: (B, r, c) times (B, c) (a matmul: half an einsum's overhead)."""
    return (M @ v[..., None])[..., 0]


def _terms_per_step(E, S):
    """The log-likelihood terms of innovations ``E`` (B, k, m) with covariances ``S`` (B, k, m, m)."""
    if E.shape[1] == 0:
        return np.empty(E.shape)
    return loglik_terms(E, S)


# ------------------------------------------------------------------------ missing samples
def observed(Y):
    """Which samples of a stack of records are observed (not NaN).

    Parameters
    ----------
    Y : ndarray (B, N, m)
        Measurements, NaN where a sample is missing.

    Returns
    -------
    ndarray (B, N, m) of bool, or None when every sample is observed
    """
    missing = np.isnan(Y)
    return ~missing if missing.any() else None


def masked(G, R, seen):
    """The observation of the observed rows only: ``W G`` and ``W R W^T`` kept in place.

    A missing row of ``G`` becomes zero and its row and column of ``R`` those of the identity, so
    the innovation covariance splits into the observed block and a unit block, the gain has zero
    columns for the missing rows, and the update is exactly the one of the observed rows.

    Parameters
    ----------
    G : ndarray (B, m, n)
    R : ndarray (B, m, m)
    seen : ndarray (B, m) of bool
        The observed rows.

    Returns
    -------
    G_k : ndarray (B, m, n)
    R_k : ndarray (B, m, m)
    """
    both = seen[..., :, None] & seen[..., None, :]
    return G * seen[..., :, None], np.where(both, R, 0.0) + np.eye(R.shape[-1]) * ~seen[..., None, :]


def stretches(seen):
    """The stretches of steps over which the observed channels of every record stay the same.

    Parameters
    ----------
    seen : ndarray (B, N, m) of bool

    Returns
    -------
    list of (int, int)
        ``[(first, stop), ...]`` covering ``0 .. N``.
    """
    change = np.any(seen[:, 1:] != seen[:, :-1], axis=(0, 2))
    cuts = np.r_[0, np.flatnonzero(change) + 1, seen.shape[1]]
    return [(int(a), int(b)) for a, b in zip(cuts[:-1], cuts[1:])]


def gapped_filter(A, G, Q, R, Y, seen, x, P, switch_tol, transition=None, loglik=False, steady=False):
    """The AKF over a stack of records with missing samples (NaN).

    A step updates with its observed rows only (:func:`masked`); with no row observed it is a pure
    prediction.

    - ``steady=False``: exact.  The covariance recursion runs through every stretch of one pattern
      of observed channels (:func:`stretches`) and, within a stretch, holds its gain once the
      covariance has converged (as :func:`time_varying_filter`).  The log-likelihood is the exact
      one of the observed samples (statsmodels' convention).
    - ``steady=True``: :func:`steady_gapped` (cached gains per pattern, fast, approximate).

    Parameters
    ----------
    A, G, Q, R
        As in the module's shapes.
    Y : ndarray (B, N, m)
        Measurements, NaN where missing.
    seen : ndarray (B, N, m) of bool
        The observed samples (:func:`observed`).
    x : ndarray (B, n)
        Prior mean of the first step.
    P : ndarray (B, n, n) or None
        Prior covariance of the first step (not used with ``steady``).
    switch_tol, transition, loglik
        As :func:`time_varying_filter`.
    steady : bool
        See above.

    Returns
    -------
    FilterRun
        Innovations are NaN, and log-likelihood terms zero, at the missing samples.
    """
    if steady:
        return steady_gapped(A, G, Q, R, Y, seen, x, loglik)
    B, N, m = Y.shape
    Y0 = np.where(seen, Y, 0.0)
    states, innov = np.empty((B, N, A.shape[-1])), np.full((B, N, m), np.nan)
    terms = np.zeros((B, N, m)) if loglik else None
    for a, b in stretches(seen):
        pattern = seen[:, a]
        G_k, R_k = masked(G, R, pattern)
        run = time_varying_filter(A, G_k, Q, R_k, Y0[:, a:b], x, P, switch_tol, transition, loglik)
        P = run.P_prior
        states[:, a:b] = run.states
        innov[:, a:b] = np.where(pattern[:, None], run.innovations, np.nan)
        if loglik:
            terms[:, a:b] = np.where(pattern[:, None], run.loglik_terms, 0.0)
        x = _times(A, run.states[:, -1])
    return FilterRun(states, innov, run.gain, P, run.switched, terms)


def steady_gapped(A, G, Q, R, Y, seen, x, loglik=False, long_stretch=LONG_STRETCH, full=None, seen_before=None):
    """The steady-state AKF over a stack of records with missing samples: one cached gain per
    pattern of observed channels.

    At a step with pattern ``W`` (observed rows) the gain is that of the steady prior covariance
    ``P`` of the complete layout updated with the observed rows only,
    ``L_W = P G_W^T (G_W P G_W^T + R_W)^-1`` -- the exact gain of the first step of any hole, one
    small solve per pattern, also for a set of live channels that is not detectable.  A pattern
    that has lasted ``long_stretch`` steps (a dead channel) goes on with its own steady-state gain
    (one Riccati solve per such pattern, cached) where one exists: a causal rule, so a record run
    in chunks gets the gains of the whole (``seen_before``).  Back at the complete layout
    the filter is at its steady gain again.  The covariance is not propagated through a hole, so
    the gains are approximate while the layout is incomplete (the exact filter:
    ``steady=False``; the accuracy is measured in the docs' "real records" page).

    Parameters
    ----------
    A, G, Q, R
        As in the module's shapes.
    Y : ndarray (B, N, m)
        Measurements, NaN where missing.
    seen : ndarray (B, N, m) of bool
    x : ndarray (B, n)
        Prior mean of the first step.
    loglik : bool
        Also the log-likelihood terms, under each pattern's innovation covariance.
    long_stretch : int
        Steps after which a pattern runs with its own steady-state gain.
    full : (P (B, n, n), L (B, n, m)), optional
        The complete layout's steady prior covariance and gain, if known.
    seen_before : ndarray (B, h, m) of bool, optional
        The observed samples of the ``h`` steps before the record (a stream's previous chunks,
        ``h <= HISTORY``): a pattern's run, and a cycle's, continues across.

    Returns
    -------
    FilterRun
        ``gain`` and ``P_prior`` are the complete layout's steady ones.
    """
    P_full, L_full = steady_gain(A, G, Q, R) if full is None else full
    B, N, m = Y.shape
    states = np.empty((B, N, A.shape[-1]))
    terms = np.zeros((B, N, m)) if loglik else None
    h = 0 if seen_before is None else seen_before.shape[1]
    gains = []
    for b in range(B):
        seen_b = seen[b] if not h else np.vstack([seen_before[b], seen[b]])
        patterns, which = _patterns(seen_b)
        period = sampling_period(seen_b, min(MAX_CYCLE, CYCLE_BYTES // (8 * A.shape[-1] ** 2)))
        G_p, R_p = masked(np.broadcast_to(G[b], (len(patterns),) + G.shape[1:]),
                          np.broadcast_to(R[b], (len(patterns),) + R.shape[1:]), patterns)
        which, pattern, P = _pattern_gains(A[b], Q[b], G_p, R_p, patterns, P_full[b], which.reshape(-1), long_stretch,
                                           period)
        which = which[h:]
        G_e, R_e = G_p[pattern], R_p[pattern]
        S = innovation_covariance(G_e, P, R_e)
        L = np.swapaxes(np.linalg.solve(S, G_e @ P), -1, -2)       # P G_W^T S^-1 (S symmetric)
        Y0 = np.where(seen[b], Y[b], 0.0)
        switched_filter(A[b], G_e, L, which, Y0, x[b], period, out=states[b])
        gains.append((which, S))
    innov = innovations(A, G, states, Y, x)
    if loglik:
        for b, (which, S) in enumerate(gains):
            E0 = np.where(seen[b], innov[b], 0.0)
            for e, rows in gain_groups(which):                     # the steps of one gain at a time
                terms[b, rows] = loglik_terms(E0[rows], S[e])
        terms[~seen] = 0.0
    return FilterRun(states, innov, L_full, P_full, True, terms)


def _patterns(seen):
    """The distinct rows of ``seen`` (N, m) and the index of each step's row: (K, m), (N,)."""
    m = seen.shape[1]
    if m > 62:
        patterns, which = np.unique(seen, axis=0, return_inverse=True)
        return patterns, which.reshape(-1)
    codes = seen.astype(np.int64) @ (np.int64(1) << np.arange(m, dtype=np.int64))    # one integer per row
    if m <= 16:                                     # a table of every code: no sort
        present = np.zeros(1 << m, bool)
        present[codes] = True
        values = np.flatnonzero(present)
        index = np.cumsum(present) - 1
        which = index[codes]
    else:
        values, which = np.unique(codes, return_inverse=True)
    return ((values[:, None] >> np.arange(m)) & 1).astype(bool), which.reshape(-1)


def sampling_period(seen, longest=MAX_CYCLE):
    """The cycle of the observed channels of a record whose slower channels sample every ``d``-th
    step (mixed sampling rates): the least common multiple of each channel's ``d`` (the greatest
    common divisor of the distances between its samples), 1 when there is none or it is longer
    than ``longest`` steps.

    Parameters
    ----------
    seen : ndarray (N, m) of bool
    longest : int

    Returns
    -------
    int
    """
    p = 1
    for column in seen.T:
        if column.all():
            continue
        steps = np.flatnonzero(column)
        if len(steps) > 2:
            p = math.lcm(p, int(np.gcd.reduce(np.diff(steps))))
    return p if p <= longest else 1


def _pattern_gains(A, Q, G_p, R_p, patterns, P_full, which, long_stretch, period=1):
    """The covariances the gains of :func:`steady_gapped` come from, for one record.

    Returns ``which`` (N,) the gain of each step, ``pattern`` (E,) the pattern of each gain and
    ``P`` (E, n, n) its covariance: gain i < len(G_p) is pattern i's (``patterns`` (K, m), the
    observed channels) from the complete layout's ``P_full``; the others are the own steady
    states of patterns, used once a pattern has lasted ``long_stretch`` steps, and the periodic
    steady states of cycles of ``period`` patterns (:func:`_cycle_covariances`), used once a cycle
    has come round twice (``period <= MAX_CYCLE``, so a stream's last :data:`HISTORY` steps
    decide as the whole record does).
    """
    n_p = len(G_p)
    pattern, P = list(range(n_p)), [P_full] * n_p
    own = {}
    cuts = np.r_[0, np.flatnonzero(np.diff(which)) + 1, len(which)]
    base, which = which, which.copy()
    for a, b in zip(cuts[:-1], cuts[1:]):
        p = int(which[a])
        if b - a <= long_stretch or patterns[p].all():     # short, or the complete layout (P_full)
            continue
        if p not in own:
            own[p] = None                     # no steady state (nothing observed, or not detectable): the gain from P_full
            if patterns[p].any():
                try:
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore", RiccatiWarning)
                        P_own, _ = steady_gain(A[None], G_p[p:p + 1], Q[None], R_p[p:p + 1])
                    own[p] = len(P)
                    pattern.append(p)
                    P.append(P_own[0])
                except RiccatiError:
                    pass
        if own[p] is not None:
            which[a + long_stretch:b] = own[p]
    for a, b in (repeats(base, period) if period > 1 else []):
        cycle = base[a:a + period]
        if b - a <= 2 * period or np.all(cycle == cycle[0]):
            continue
        P_cycle = _cycle_covariances(A, Q, G_p, R_p, patterns, cycle, P_full)
        if P_cycle is None:
            continue
        k = np.arange(a + 2 * period, b)                  # once the cycle has come round twice
        which[k] = len(P) + (k - a) % period
        pattern.extend(cycle.tolist())
        P.extend(P_cycle)
    return which, np.array(pattern), np.array(P)


#: the periodic steady states of cycles of patterns, by their matrices (:func:`_cycle_covariances`)
_CYCLES, _CYCLES_LOCK = {}, threading.Lock()
#: the periodic Riccati recursion stops when a period changes the covariance by less than this
#: (relative), and gives up after this many steps (a cycle whose layout is not detectable)
CYCLE_TOL, CYCLE_STEPS = 1e-12, 20000


def _cycle_covariances(A, Q, G_p, R_p, patterns, cycle, P_start):
    """The periodic steady state of the filter whose observed channels repeat ``cycle`` (``p``
    pattern indices): the prior covariance (p, n, n) at each step of the cycle, from the
    covariance recursion run over whole cycles from ``P_start`` until a cycle no longer changes it
    (None when it does not settle in :data:`CYCLE_STEPS` steps).  The recursion starts at the
    cycle's canonical rotation, so every window of a record onto the same cycle gets the same
    numbers; they are cached by the matrices.
    """
    p = len(cycle)
    codes = [patterns[c].tobytes() for c in cycle]
    r = min(range(p), key=lambda i: codes[i:] + codes[:i])
    canonical = np.roll(cycle, -r)
    digest = hashlib.blake2b(digest_size=16)
    for array in (A, Q, P_start, G_p[canonical], R_p[canonical]):
        digest.update(np.ascontiguousarray(array).tobytes())
    key = digest.hexdigest()
    with _CYCLES_LOCK:
        found = _CYCLES.get(key, False)
    if found is False:
        found = _periodic_riccati(A, Q, G_p[canonical], R_p[canonical], P_start)
        with _CYCLES_LOCK:                       # threads of a batch may share it
            if len(_CYCLES) >= 32:
                _CYCLES.pop(next(iter(_CYCLES)))
            _CYCLES[key] = found
    return None if found is None else found[(np.arange(p) - r) % p]


def _periodic_riccati(A, Q, G_c, R_c, P):
    """The prior covariances (p, n, n) of the converged covariance recursion over the cycle of
    observations ``G_c`` (p, m, n), ``R_c`` (p, m, m), or None."""
    p = len(G_c)
    out = np.empty((p,) + P.shape)
    scale = max(np.abs(P).max(), np.finfo(float).tiny)
    for _ in range(max(1, CYCLE_STEPS // p)):
        before = P
        for j in range(p):
            out[j] = P
            GP = G_c[j] @ P
            S = GP @ G_c[j].T + R_c[j]
            P = A @ (P - GP.T @ np.linalg.solve(S, GP)) @ A.T + Q
            P = (P + P.T) / 2
        if not np.all(np.isfinite(P)):
            return None
        scale = max(scale, np.abs(P).max())
        if np.abs(P - before).max() <= CYCLE_TOL * scale:
            return out
    return None


# ------------------------------------------------------------------------- over a Filter
def steady(f, Y, start=None, loglik=False):
    """The steady-state filter ``f`` over a stack of records.

    Parameters
    ----------
    f : Filter
        Its modal matrices ``A_a``, ``G_a``, ``Q_a``, ``R`` and prior mean ``z0`` are used.
    Y : ndarray (B, N, m_f)
        Measurements with the filter's channels (:meth:`Filter.extend`), one record per layout.
    start : ndarray (B, n_a), optional
        The prior mean of the first step (default the filter's prior).
    loglik : bool
        Also the log-likelihood terms.

    Returns
    -------
    FilterRun
    """
    B, n = Y.shape[0], f.A_a.shape[0]
    A, Q = np.broadcast_to(f.A_a, (B, n, n)), np.broadcast_to(f.Q_a, (B, n, n))
    seen = observed(Y)
    try:
        if seen is None:
            return steady_states(A, f.G_a, Q, f.R, Y, _start(f, B, start), loglik)
        return steady_gapped(A, f.G_a, Q, f.R, Y, seen, _start(f, B, start), loglik)
    except RiccatiError as exc:
        raise f.riccati_error(exc) from None


def with_gain(f, Y, L, P, start=None, loglik=False, seen_before=None):
    """The filter ``f`` with a given constant gain over a stack of records (a stream's chunk once
    its gain is steady or has converged).

    With missing samples the gain changes with the pattern of observed channels
    (:func:`steady_gapped` from ``L`` and ``P``).

    Parameters
    ----------
    f : Filter
        Its modal matrices and prior mean are used.
    Y : ndarray (B, N, m_f)
        Measurements with the filter's channels.
    L : ndarray (B, n_a, m_f)
        The gain.
    P : ndarray (B, n_a, n_a)
        The prior covariance the gain belongs to (for the innovation covariance).
    start : ndarray (B, n_a), optional
        The prior mean of the first step (default the filter's prior).
    loglik : bool
        Also the log-likelihood terms.
    seen_before : ndarray (B, h, m_f) of bool, optional
        As :func:`steady_gapped`.

    Returns
    -------
    FilterRun
    """
    B, n = Y.shape[0], f.A_a.shape[0]
    A = np.broadcast_to(f.A_a, (B, n, n))
    seen = observed(Y)
    if seen is not None:
        return steady_gapped(A, f.G_a, np.broadcast_to(f.Q_a, (B, n, n)), f.R, Y, seen, _start(f, B, start), loglik,
                             full=(P, L), seen_before=seen_before)
    return constant_gain(A, f.G_a, f.R, L, P, Y, _start(f, B, start), loglik)


def time_varying(f, Y, start=None, loglik=False, switch_tol=1e-14):
    """The time-varying filter ``f`` over a stack of records.

    Parameters
    ----------
    f : Filter
        Its modal matrices, prior (``z0``, ``Pz0``) and :class:`ModalBlockTransition` are used.
    Y : ndarray (B, N, m_f)
        Measurements with the filter's channels.
    start : tuple (x (B, n_a), P (B, n_a, n_a)), optional
        The prior mean and covariance of the first step (default the filter's prior).
    loglik : bool
        Also the log-likelihood terms.
    switch_tol : float
        As :func:`time_varying_filter`.

    Returns
    -------
    FilterRun
    """
    B, n = Y.shape[0], f.A_a.shape[0]
    if start is None:
        P0 = f.Q_a if f.Pz0 is None else f.Pz0
        start = (None, np.broadcast_to(P0, (B, n, n)).copy())
    x = _start(f, B, start[0])
    seen = observed(Y)
    if seen is not None:
        return gapped_filter(np.broadcast_to(f.A_a, (B, n, n)), f.G_a, np.broadcast_to(f.Q_a, (B, n, n)), f.R, Y, seen,
                             x, start[1], switch_tol, f.transition, loglik)
    return time_varying_filter(np.broadcast_to(f.A_a, (B, n, n)), f.G_a, np.broadcast_to(f.Q_a, (B, n, n)), f.R, Y,
                               x, start[1], switch_tol, f.transition, loglik)


def _start(f, B, x):
    n = f.A_a.shape[0]
    if x is not None:
        return np.broadcast_to(x, (B, n)).copy()
    return np.zeros((B, n)) if f.z0 is None else np.broadcast_to(f.z0, (B, n)).copy()
