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
from .likelihood import loglik_terms, loglik_total
from .recursion import lti_response, solver_threads, stack_pieces
from .riccati import RiccatiError, RiccatiWarning, accurate_filter_dare, steady_gain
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
#: a hole within this many steps of a cycle's periodic gains (a mixed-rate record whose cycle is
#: broken) runs the exact covariance recursion until the cycle is back
BROKEN_CYCLE = 2 * MAX_CYCLE
HISTORY = max(LONG_STRETCH, 2 * MAX_CYCLE + BROKEN_CYCLE)


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
    hole_P : ndarray (B, n, n) or None
        The steady filter with missing samples (:func:`steady_gapped`): the prior covariance of the
        last step where it ran the exact recursion through a hole, NaN where it did not (a
        stream carries it to its next chunk); None without holes.
    """

    states: np.ndarray
    innovations: np.ndarray
    gain: np.ndarray
    P_prior: np.ndarray
    switched: bool = True
    loglik_terms: np.ndarray | None = None
    hole_P: np.ndarray | None = None

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
    E = np.empty(Y.shape)             # B-major even for a broadcast Y
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
    seen = observed(Y[None])
    if seen is not None:                               # missing samples: the filter of each pattern
        seen = np.broadcast_to(seen, Ys.shape)
        run = steady_gapped(A, G, Q, R, Ys, seen, np.zeros(A.shape[:-1]), loglik=True, full=(P, L))
        out[ok] = run.loglik_terms.sum(axis=-1) if per_step else run.loglik
        return out
    S = innovation_covariance(G, P, R)
    for i in stack_pieces(ok.size, 8 * Y.size, multiple=solver_threads()):   # a long record: piece by piece
        predicted = fixed_gain(A[i], G[i], L[i], Ys[i], outputs=G[i] @ A[i])   # G A X_k: the next step's channels
        E = np.empty(predicted.shape)
        E[:, 0] = Y[0]
        E[:, 1:] = Y[1:] - predicted[:, :-1]
        out[ok[i]] = loglik_terms(E, S[i]).sum(axis=-1) if per_step else loglik_total(E, S[i])
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


def steady_gapped(A, G, Q, R, Y, seen, x, loglik=False, long_stretch=LONG_STRETCH, full=None, seen_before=None,
                  carry=None, at_start=True):
    """The steady-state AKF over a stack of records with missing samples: cached gains per pattern
    of observed channels, and the exact covariance recursion through a hole where those would not
    be stable.

    - At a step where the channels ``W`` are observed the gain is that of the complete layout's
      steady prior covariance ``P`` updated with the observed rows only,
      ``L_W = P G_W^T (G_W P G_W^T + R_W)^-1`` -- the exact gain of the first step of any hole, one
      small solve per pattern, cached.
    - Applied step after step, ``L_W`` is not always a stable filter for the channels that are
      left (the spectral radius of ``(I - L_W G_W) A`` above one): from the first step of a hole
      with such a pattern on, until the layout is complete again, the filter runs the exact
      covariance recursion (from ``P``), one gain per distinct sequence of patterns, computed a
      depth at a time for all holes at once.  A record with mixed sampling rates does so at every
      step until its cycle of patterns has come round twice.
    - A pattern that has lasted ``long_stretch`` steps (a dead channel) goes on with its own
      steady-state gain (one Riccati solve per such pattern, cached) where one exists; where none
      exists the gain of that step is held.
    - A record whose channels repeat a cycle of ``p`` patterns (mixed sampling rates) runs with
      the cycle's periodic steady-state gains once the cycle has come round twice.
    - Back at the complete layout the filter is at its steady gain again.

    The rules are causal, so a record run in chunks gets the gains of the whole (``seen_before``,
    ``carry``).  The exact filter: ``steady=False``; the accuracy is measured in the docs' "real
    records" page.

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
        Also the log-likelihood terms, under each gain's innovation covariance.
    long_stretch : int
        Steps after which a pattern runs with its own steady-state gain.
    full : (P (B, n, n), L (B, n, m)), optional
        The complete layout's steady prior covariance and gain, if known.
    seen_before : ndarray (B, h, m) of bool, optional
        The observed samples of the ``h`` steps before the record (a stream's previous chunks,
        ``h <= HISTORY``): a pattern's run, and a cycle's, continues across.
    carry : ndarray (B, n, n), optional
        The prior covariance of the last step before the record where that step ran the exact
        recursion through a hole (NaN where it did not): the previous chunk's ``hole_P``.
    at_start : bool
        Whether the record (with ``seen_before``) starts at the filter's start; False for a
        stream's later chunk (whose steps before ``seen_before`` were complete).

    Returns
    -------
    FilterRun
        ``gain`` and ``P_prior`` are the complete layout's steady ones; ``hole_P`` the prior
        covariance of the last step where it ran the exact recursion (NaN elsewhere).
    """
    P_full, L_full = steady_gain(A, G, Q, R) if full is None else full
    B, N, m = Y.shape
    n = A.shape[-1]
    states = np.empty((B, N, n))
    terms = np.zeros((B, N, m)) if loglik else None
    h = 0 if seen_before is None else seen_before.shape[1]
    hole_P = np.full((B, n, n), np.nan)
    gains = []
    for b in range(B):
        seen_b = seen[b] if not h else np.vstack([seen_before[b], seen[b]])
        patterns, which = _patterns(seen_b)
        period = sampling_period(seen_b, min(MAX_CYCLE, CYCLE_BYTES // (8 * n ** 2)))
        G_p, R_p = masked(np.broadcast_to(G[b], (len(patterns),) + G.shape[1:]),
                          np.broadcast_to(R[b], (len(patterns),) + R.shape[1:]), patterns)
        P_carry = None if carry is None or not np.all(np.isfinite(carry[b])) else carry[b]
        plan = _pattern_gains(A[b], Q[b], G_p, R_p, patterns, P_full[b], which, long_stretch, period, h, P_carry,
                              at_start)
        if plan.P_last is not None:
            hole_P[b] = plan.P_last
        which = plan.which[h:]
        G_e, R_e = G_p[plan.pattern], R_p[plan.pattern]
        S = innovation_covariance(G_e, plan.P, R_e)
        L = np.swapaxes(np.linalg.solve(S, G_e @ plan.P), -1, -2)       # P G_W^T S^-1 (S symmetric)
        fixed = len(L)
        if len(plan.hole_pattern):
            which, order, held = _held_first(which, fixed, len(plan.hole_pattern))
            fixed += held                                  # a gain held through a long hole runs lifted
            G_e = np.concatenate([G_e, G_p[plan.hole_pattern[order]]])
            L, S = np.concatenate([L, plan.hole_L[order]]), np.concatenate([S, plan.hole_S[order]])
        Y0 = np.where(seen[b], Y[b], 0.0)
        switched_filter(A[b], G_e, L, which, Y0, x[b], period, out=states[b], fixed=fixed)
        gains.append((which, S))
    innov = innovations(A, G, states, Y, x)
    if loglik:
        for b, (which, S) in enumerate(gains):
            E0 = np.where(seen[b], innov[b], 0.0)
            for e, rows in gain_groups(which):                     # the steps of one gain at a time
                terms[b, rows] = loglik_terms(E0[rows], S[e])
        terms[~seen] = 0.0
    return FilterRun(states, innov, L_full, P_full, True, terms, hole_P)


def _held_first(which, fixed, count):
    """Renumber the ``count`` gains from ``fixed`` on so that those held for :data:`LIFT_FROM`
    steps or more in a row come first: ``which`` renumbered, the order of the old gains, and how
    many are held."""
    cuts = np.r_[0, np.flatnonzero(np.diff(which)) + 1, len(which)]
    long = (np.diff(cuts) >= LIFT_FROM) & (which[cuts[:-1]] >= fixed)
    held = np.unique(which[cuts[:-1][long]]) - fixed
    if not len(held):
        return which, np.arange(count), 0
    order = np.r_[held, np.setdiff1d(np.arange(count), held)]
    new = np.empty(count, np.int64)
    new[order] = np.arange(count)
    renumbered = which.copy()
    hole = which >= fixed
    renumbered[hole] = fixed + new[which[hole] - fixed]
    return renumbered, order, len(held)


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


@dataclass
class _GainPlan:
    """The gains of :func:`steady_gapped` for one record: ``which`` (h + N,) the gain of each
    step; the first gains from cached covariances, ``pattern`` (E,) and ``P`` (E, n, n); then the
    gains of the exact recursion through holes, ``hole_pattern`` (E_h,), ``hole_L`` (E_h, n, m),
    ``hole_S`` (E_h, m, m); ``P_last`` the prior covariance of the last step if it ran that
    recursion."""

    which: np.ndarray
    pattern: np.ndarray
    P: np.ndarray
    hole_pattern: np.ndarray
    hole_L: np.ndarray
    hole_S: np.ndarray
    P_last: np.ndarray | None


def _pattern_gains(A, Q, G_p, R_p, patterns, P_full, which, long_stretch, period=1, h=0, P_carry=None,
                   at_start=True):
    """The gains of :func:`steady_gapped` for one record (``h`` steps of history first), a
    :class:`_GainPlan`.

    Gain i < len(G_p) is pattern i's (``patterns`` (K, m), the observed channels) from the complete
    layout's ``P_full``; then the own steady states of patterns, used once a pattern has lasted
    ``long_stretch`` steps, and the periodic steady states of cycles of ``period`` patterns
    (:func:`_cycle_covariances`), used once a cycle has come round twice (``period <= MAX_CYCLE``,
    so a stream's last :data:`HISTORY` steps decide as the whole record does).  The steps of a
    hole from :func:`_exact_steps` on run the exact covariance recursion (:func:`_hole_gains`);
    ``P_carry`` continues the recursion of the step before the record; ``at_start``: the record
    (with its history) starts at the filter's start.
    """
    n_p = len(G_p)
    pattern, P = list(range(n_p)), [P_full] * n_p
    cuts = np.r_[0, np.flatnonzero(np.diff(which)) + 1, len(which)]
    run_start = np.repeat(cuts[:-1], np.diff(cuts))
    base, which = which, which.copy()
    _own_gains(A, Q, G_p, R_p, patterns, cuts, which, long_stretch, pattern, P)
    first_cycle = len(P)
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
    exact = _exact_steps(A, G_p, R_p, patterns, P_full, base, which, which >= first_cycle,
                         (which >= n_p) & (which < first_cycle), h, P_carry, at_start)
    hole = _hole_gains(A, Q, G_p, R_p, base, which, exact, np.array(P), np.array(pattern), P_full, run_start,
                       long_stretch, h, P_carry)
    if hole is None:
        empty = np.zeros((0,) + G_p.shape[1:])
        return _GainPlan(which, np.array(pattern), np.array(P), np.zeros(0, np.int64), np.swapaxes(empty, 1, 2),
                         np.zeros((0, G_p.shape[1], G_p.shape[1])), None)
    gain, hole_pattern, hole_L, hole_S, P_last = hole
    which[exact] = len(P) + gain
    return _GainPlan(which, np.array(pattern), np.array(P), hole_pattern, hole_L, hole_S, P_last)


def _own_gains(A, Q, G_p, R_p, patterns, cuts, which, long_stretch, pattern, P):
    """The own steady states of the patterns whose runs (between ``cuts``) outlast
    ``long_stretch`` steps, appended to ``pattern`` and ``P``; ``which`` set to them from then on."""
    own = {}
    for a, b in zip(cuts[:-1], cuts[1:]):
        p = int(which[a])
        if b - a <= long_stretch or patterns[p].all():     # short, or the complete layout (P_full)
            continue
        if p not in own:
            own[p] = None                     # no steady state (nothing observed, or not detectable)
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


def _exact_steps(A, G_p, R_p, patterns, P_full, base, which, periodic, own, h, P_carry, at_start):
    """(h + N,) bool: the steps that run the exact covariance recursion (none before ``h``).

    A hole's steps are those not at a cached steady state that are incomplete, or complete after
    an incomplete step, or within :data:`BROKEN_CYCLE` steps after a step with a cycle's periodic
    gain (``periodic``: a mixed-rate record whose cycle a hole broke).  A hole runs the recursion
    from its first step if it starts the record (``at_start``), follows a step with a pattern's
    own steady gain (``own``) or one that ran the recursion (``P_carry`` for the step before the
    record); else from its first step whose pattern's gain from ``P_full`` is not a stable filter
    (:func:`_unstable_patterns`) or that is in a broken cycle; to the hole's end, and then through
    up to :data:`SETTLE` steps of the complete layout.
    """
    N = len(base)
    complete = patterns[base].all(axis=1)
    after_complete = np.r_[not (at_start and h == 0), complete[:-1]]
    cyclic = np.maximum.accumulate(np.where(periodic, np.arange(N), -N - BROKEN_CYCLE))
    broken = np.arange(N) - np.r_[-N - BROKEN_CYCLE, cyclic[:-1]] <= BROKEN_CYCLE
    free = (which == base) & (broken | ~complete | ~after_complete)
    settles = (which == base) & complete & ~free             # steps of the complete layout's steady gain
    exact = np.zeros(N, bool)
    edges = np.flatnonzero(np.diff(np.r_[False, free, False].astype(np.int8)))
    unstable = None
    carried = P_carry is not None
    for a, b in zip(edges[::2], edges[1::2]):
        if b <= h:
            if carried:                                  # its settling may go on into the record
                _settle(exact, settles, b, h)
            continue
        a = max(a, h)
        if (a == h and carried) or (a == 0 and at_start) or (a >= 1 and (exact[a - 1] or own[a - 1])):
            first = 0
        else:
            if unstable is None:
                unstable = _unstable_patterns(A, G_p, R_p, P_full, np.unique(base[free & ~complete]))
            found = np.flatnonzero(unstable[base[a:b]] | broken[a:b])
            if not len(found):
                continue
            first = int(found[0])
        exact[a + first:b] = True
        _settle(exact, settles, b, h)
    return exact


def _settle(exact, settles, b, h):
    """Mark the steps of the complete layout from ``b`` on (up to :data:`SETTLE`, not before
    ``h``) as running the exact recursion."""
    c = b
    while c < len(settles) and c < b + SETTLE and settles[c]:
        c += 1
    exact[max(b, h):c] = True


#: whether each pattern's gain from the complete layout's covariance is a stable filter, by the
#: matrices (:func:`_unstable_patterns`)
_STABLE, _STABLE_LOCK = {}, threading.Lock()
#: a pattern's gain from the complete layout's covariance is not used step after step when its
#: closed loop's spectral radius exceeds one by more than this
STABLE_MARGIN = 1e-9
#: after a hole that ran the exact recursion, the filter runs it through this many more steps of
#: the complete layout before it takes the layout's steady gain again
SETTLE = 16


def _unstable_patterns(A, G_p, R_p, P_full, only=None):
    """(K,) bool: whether the gain of each pattern (``G_p``, ``R_p`` masked) from ``P_full`` is not
    a stable filter, ``max |eig((I - L_W G_W) A)| > 1 + STABLE_MARGIN`` (cached by the matrices);
    only the patterns ``only`` (indices) are checked, if given (the others: False)."""
    digest = hashlib.blake2b(digest_size=16)
    for array in (A, P_full):
        digest.update(np.ascontiguousarray(array).tobytes())
    base = digest.copy()
    keys, out, todo = {}, np.zeros(len(G_p), bool), []
    for i in (range(len(G_p)) if only is None else np.asarray(only).tolist()):
        d = base.copy()
        d.update(np.ascontiguousarray(G_p[i]).tobytes())
        d.update(np.ascontiguousarray(R_p[i]).tobytes())
        keys[i] = d.hexdigest()
    with _STABLE_LOCK:
        for i, key in keys.items():
            if key in _STABLE:
                out[i] = _STABLE[key]
            else:
                todo.append(i)
    if todo:
        G_t, R_t = G_p[todo], R_p[todo]
        S = innovation_covariance(G_t, P_full, R_t)
        L = np.swapaxes(np.linalg.solve(S, G_t @ P_full), -1, -2)
        F = (np.eye(A.shape[-1]) - L @ G_t) @ A
        radius = np.abs(np.linalg.eigvals(F)).max(axis=-1)
        out[todo] = ~(radius <= 1.0 + STABLE_MARGIN)
        with _STABLE_LOCK:
            if len(_STABLE) > 4096:
                _STABLE.clear()
            _STABLE.update({keys[i]: bool(out[i]) for i in todo})
    return out


def _riccati_step(A, Q, G, R, P):
    """The prior covariances (k, n, n) of the step after priors ``P`` (k, n, n) updated with
    observations ``G`` (k, m, n), ``R`` (k, m, m) (masked)."""
    GP = G @ P
    S = GP @ np.swapaxes(G, -1, -2) + R
    post = P - np.swapaxes(GP, -1, -2) @ np.linalg.solve(S, GP)
    nxt = A @ post @ A.T + Q
    return (nxt + np.swapaxes(nxt, -1, -2)) / 2


def _hole_gains(A, Q, G_p, R_p, base, which, exact, P_cached, pattern_cached, P_full, run_start, long_stretch, h,
                P_carry):
    """The gains of the exact covariance recursion over the steps ``exact`` of a record (patterns
    ``base``, the other steps' gains ``which`` from ``P_cached``, ``pattern_cached``).

    A stretch of such steps starts from the prior after the step before it (its cached gain's
    covariance updated with its pattern, and predicted; ``P_full`` at the record's first step;
    ``P_carry`` at a stream's).  Each step's prior is a node of :func:`_hole_nodes`; the nodes'
    covariances, and their gains, are computed a depth at a time for every hole at once.

    Returns None when no step runs the recursion; else the gain index of each such step (in
    order), the pattern, gain (E_h, n, m) and innovation covariance (E_h, m, m) of each gain, and
    the prior covariance of the record's last step if it ran the recursion.
    """
    steps = np.flatnonzero(exact)
    if not len(steps):
        return None
    step_gain, parent, via, depth, roots, gain_node, gain_pattern, last = _hole_nodes(
        steps, base, which, run_start, long_stretch, h, P_carry is not None)
    n, m = A.shape[-1], G_p.shape[1]
    hole_L, hole_S = np.empty((len(gain_node), n, m)), np.empty((len(gain_node), m, m))
    P_last = None
    level = np.flatnonzero(depth == 0)
    P_level = np.empty((len(level), n, n))
    for j, r in enumerate(level.tolist()):
        key = roots[r]
        if key[0] == "carry":
            P_level[j] = P_carry
        elif key[0] == "start":
            P_level[j] = P_full
        else:
            e = key[1]
            p = pattern_cached[e]
            P_level[j] = _riccati_step(A, Q, G_p[p][None], R_p[p][None], P_cached[e][None])[0]
    gain_order = np.argsort(gain_node, kind="stable")
    gain_bounds = np.searchsorted(gain_node[gain_order], np.arange(len(parent) + 1))
    by_depth = np.argsort(depth, kind="stable")
    depth_bounds = np.searchsorted(depth[by_depth], np.arange(depth.max() + 2))
    position = np.empty(len(parent), np.int64)
    for d in range(depth.max() + 1):
        if d:
            children = by_depth[depth_bounds[d]:depth_bounds[d + 1]]
            v = via[children]
            P_level = _riccati_step(A, Q, G_p[v], R_p[v], P_level[position[parent[children]]])
            level = children
        position[level] = np.arange(len(level))
        mine = np.concatenate([gain_order[gain_bounds[u]:gain_bounds[u + 1]] for u in level.tolist()])
        if len(mine):
            p = gain_pattern[mine]
            G_w, R_w = G_p[p], R_p[p]
            GP = G_w @ P_level[position[gain_node[mine]]]
            S = GP @ np.swapaxes(G_w, -1, -2) + R_w
            hole_S[mine] = S
            hole_L[mine] = np.swapaxes(np.linalg.solve(S, GP), -1, -2)
        if last is not None and depth[last] == d:
            P_last = P_level[position[last]].copy()
    return step_gain, gain_pattern, hole_L, hole_S, P_last


def _hole_nodes(steps, base, which, run_start, long_stretch, h, carried):
    """The nodes of the exact recursion over ``steps`` (the prior covariance of each step): a
    stretch's first step is a root -- ``("after", gain)`` of the step before, ``("start",)``, or
    the node of the step before the record ``("carry",)`` (``carried``) -- and every other step's
    node is the node of the step before updated with that step's pattern, or the same node where
    a pattern without a steady state has lasted ``long_stretch`` steps (its gain held).  Nodes,
    and gains (node, pattern), are shared by every hole with the same sequence of patterns.

    Returns the gain of each step, each node's ``parent``, the pattern ``via`` which it follows
    from it and its ``depth`` (arrays), the roots' keys by node, each gain's node and pattern, and
    the node of the record's last step (None unless it is in ``steps``).
    """
    node_of, parent, via, depth, roots = {}, [], [], [], {}
    gain_of, gain_node, gain_pattern = {}, [], []
    step_gain = np.empty(len(steps), np.int64)
    base_l, which_l, run_l = base.tolist(), which.tolist(), run_start.tolist()
    node, previous = -1, -2
    for i, k in enumerate(steps.tolist()):
        start = k != previous + 1
        if start:                                        # a stretch starts: its root
            if k == h and carried:
                key, start = ("carry",), False           # the node of the step before, carried
            else:
                key = ("start",) if k == 0 else ("after", which_l[k - 1])
            node = node_of.get(key)
            if node is None:
                node = node_of[key] = len(parent)
                parent.append(-1)
                via.append(-1)
                depth.append(0)
                roots[node] = key
        if not start and not (base_l[k] == base_l[k - 1] and k - run_l[k] >= long_stretch):
            key = (node, base_l[k - 1])
            child = node_of.get(key)
            if child is None:
                child = node_of[key] = len(parent)
                parent.append(node)
                via.append(base_l[k - 1])
                depth.append(depth[node] + 1)
            node = child
        previous = k
        gkey = (node, base_l[k])
        g = gain_of.get(gkey)
        if g is None:
            g = gain_of[gkey] = len(gain_node)
            gain_node.append(node)
            gain_pattern.append(base_l[k])
        step_gain[i] = g
    last = node if steps[-1] == len(base) - 1 else None
    return (step_gain, np.array(parent), np.array(via), np.array(depth), roots, np.array(gain_node),
            np.array(gain_pattern), last)


#: the periodic steady states of cycles of patterns, by their matrices (:func:`_cycle_covariances`)
_CYCLES, _CYCLES_LOCK = {}, threading.Lock()
#: the periodic Riccati recursion stops when a period changes the covariance by less than this
#: (relative), and gives up after this many steps (a cycle whose layout is not detectable)
CYCLE_TOL, CYCLE_STEPS = 1e-12, 20000
#: cycles in a row whose covariance grows like a random walk's (relative change >= 1 / (2 k)) before
#: the periodic recursion is given up as divergent (the exact recursion runs those steps)
CYCLE_DIVERGED = 200
#: the longest cycle, and the most channels over it, whose periodic steady state starts from the
#: lifted system's DARE (:func:`_lifted_cycle_start`)
LIFTED_CYCLE, LIFTED_CHANNELS = 64, 512
#: its solution is taken only if the lifted closed loop's spectral radius is below 1 - this
#: (else the recursion from ``P_start`` decides whether the cycle converges)
LIFTED_MARGIN = 1e-8


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
    observations ``G_c`` (p, m, n), ``R_c`` (p, m, m), or None.

    The recursion starts from the lifted system's steady state (:func:`_lifted_cycle_start`)
    where it has one, so it stops after a cycle or a few; else from ``P`` (it took ~1000 cycles
    on a lightly damped truss with a channel at half the rate: 0.15 s per candidate of a locate).
    """
    p = len(G_c)
    start = _lifted_cycle_start(A, Q, G_c, R_c)
    if start is not None:
        P = start
    out = np.empty((p,) + P.shape)
    scale = max(np.abs(P).max(), np.finfo(float).tiny)
    growing = 0
    for k in range(1, max(1, CYCLE_STEPS // p) + 1):
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
        change = np.abs(P - before).max() / scale
        if change <= CYCLE_TOL:
            return out
        # a state the cycle does not observe (a random walk): P grows by Q each cycle, its relative
        # change ~ 1/k, and it never converges -- said after CYCLE_DIVERGED cycles, not 20000 steps
        growing = growing + 1 if change * k > 0.5 else 0
        if growing >= CYCLE_DIVERGED:
            return None
    return None


def _lifted_cycle_start(A, Q, G_c, R_c):
    """The prior covariance (n, n) at the first step of the cycle's periodic steady state, from the
    lifted system (one step per cycle; None when the cycle is longer than :data:`LIFTED_CYCLE`
    steps or :data:`LIFTED_CHANNELS` channels, or its DARE has no accurate solution).

    Over a cycle of ``p`` steps from ``x_0``: ``x_p = A^p x_0 + e_p`` and ``y_j = G_j A^j x_0 +
    G_j e_j + v_j``, with ``e_j = A e_j-1 + w_j-1`` (``e_0 = 0``, ``cov e_j = Sigma_j``).  The
    lifted noise is correlated (``S = cov(e_p, G e + v)``); with ``A_bar = A^p - S R_L^-1 G_L``
    and ``Q_bar = Sigma_p - S R_L^-1 S^T`` its prior covariance solves the ordinary filter DARE.
    """
    p, m, n = G_c.shape
    if p > LIFTED_CYCLE or p * m > LIFTED_CHANNELS:
        return None
    power, sigma = [np.eye(n)], [np.zeros((n, n))]
    for _ in range(p):
        power.append(A @ power[-1])
        s = A @ sigma[-1] @ A.T + Q
        sigma.append((s + s.T) / 2)
    G_L = np.concatenate([G_c[j] @ power[j] for j in range(p)])
    R_L = np.zeros((p * m, p * m))
    S = np.empty((n, p * m))
    for j in range(p):
        rows = slice(j * m, (j + 1) * m)
        S[:, rows] = power[p - j] @ sigma[j] @ G_c[j].T
        R_L[rows, rows] = G_c[j] @ sigma[j] @ G_c[j].T + R_c[j]
        for k in range(j + 1, p):                   # cov(e_k, e_j) = A^(k-j) Sigma_j
            block = G_c[k] @ power[k - j] @ sigma[j] @ G_c[j].T
            R_L[k * m:(k + 1) * m, rows] = block
            R_L[rows, k * m:(k + 1) * m] = block.T
    R_L = (R_L + R_L.T) / 2
    try:
        RiG, RiS = np.split(np.linalg.solve(R_L, np.concatenate([G_L, S.T], axis=1)), [n], axis=1)
    except np.linalg.LinAlgError:
        return None
    A_bar = power[p] - S @ RiG
    Q_bar = sigma[p] - S @ RiS
    P = accurate_filter_dare(A_bar, G_L, (Q_bar + Q_bar.T) / 2, R_L)
    if P is None or not np.all(np.isfinite(P)):
        return None
    # only the stabilising solution: a state the cycle does not see (a random walk) gives a huge P
    # with a small residual, that the recursion from it would take as converged
    gain = np.linalg.solve(G_L @ P @ G_L.T + R_L, G_L @ P).T
    closed = A_bar @ (np.eye(n) - gain @ G_L)
    if not np.all(np.isfinite(closed)) or np.abs(np.linalg.eigvals(closed)).max() > 1 - LIFTED_MARGIN:
        return None
    return (P + P.T) / 2


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


def with_gain(f, Y, L, P, start=None, loglik=False, seen_before=None, carry=None, at_start=True):
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
    carry : ndarray (B, n_a, n_a), optional
        As :func:`steady_gapped` (the previous chunk's ``hole_P``).
    at_start : bool
        As :func:`steady_gapped`.

    Returns
    -------
    FilterRun
    """
    B, n = Y.shape[0], f.A_a.shape[0]
    A = np.broadcast_to(f.A_a, (B, n, n))
    seen = observed(Y)
    if seen is None and (seen_before is not None or carry is not None):   # a complete chunk after holes
        seen = np.ones(Y.shape, bool)
    if seen is not None:
        return steady_gapped(A, f.G_a, np.broadcast_to(f.Q_a, (B, n, n)), f.R, Y, seen, _start(f, B, start), loglik,
                             full=(P, L), seen_before=seen_before, carry=carry, at_start=at_start)
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
