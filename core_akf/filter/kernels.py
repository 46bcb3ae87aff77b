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

from dataclasses import dataclass

import numpy as np

from ..checks import AKFInputError, ArrayLike, BatchMeasurements, Matrix, Measurements, as_finite_array, check_covariance
from .likelihood import loglik_terms
from .recursion import lti_response
from .riccati import RiccatiError, steady_gain

#: the time-varying filter tests every this many steps whether its covariance has converged
CHECK_EVERY = 32


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
    rows the n states per step are never formed.

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
    return fixed_gain(A, G, L, Y, outputs=H)


def steady_logliks(A, G, Q, R, Y):
    """The log-likelihood of one record under a stack of steady-state filters.

    Parameters
    ----------
    A : ndarray (B, n, n)
    G : ndarray (B, m, n)
    Q : ndarray (B, n, n)
    R : ndarray (B, m, m)
    Y : ndarray (N, m)
        The record (SI), the same for every filter.

    Returns
    -------
    ndarray (B,)
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
    out = np.full(B, -np.inf)
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
    predicted = fixed_gain(A, G, L, Ys, outputs=G @ A)           # G A X_k: the next step's predicted channels
    E = np.empty_like(Ys)
    E[:, 0] = Ys[:, 0]
    E[:, 1:] = Ys[:, 1:] - predicted[:, :-1]
    out[ok] = loglik_terms(E, innovation_covariance(G, P, R)).sum(axis=(1, 2))
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
    try:
        return steady_states(A, f.G_a, Q, f.R, Y, _start(f, B, start), loglik)
    except RiccatiError as exc:
        raise f.riccati_error(exc) from None


def with_gain(f, Y, L, P, start=None, loglik=False):
    """The filter ``f`` with a given constant gain over a stack of records (a stream's chunk once
    its gain is steady or has converged).

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

    Returns
    -------
    FilterRun
    """
    B, n = Y.shape[0], f.A_a.shape[0]
    A = np.broadcast_to(f.A_a, (B, n, n))
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
    return time_varying_filter(np.broadcast_to(f.A_a, (B, n, n)), f.G_a, np.broadcast_to(f.Q_a, (B, n, n)), f.R, Y,
                               x, start[1], switch_tol, f.transition, loglik)


def _start(f, B, x):
    n = f.A_a.shape[0]
    if x is not None:
        return np.broadcast_to(x, (B, n)).copy()
    return np.zeros((B, n)) if f.z0 is None else np.broadcast_to(f.z0, (B, n)).copy()


# ------------------------------------------------------------------------------ low level
def _batchify(A_a, G_a, Q_a, R, Y, check=True):
    """Validate shapes (and with ``check`` the covariances); return arrays with a leading batch
    axis and whether the input had one."""
    A_a = as_finite_array(A_a, "A_a", ndim=(2, 3))
    G_a = as_finite_array(G_a, "G_a", ndim=(2, 3))
    Q_a = as_finite_array(Q_a, "Q_a", ndim=(2, 3))
    R = as_finite_array(R, "R", ndim=(2, 3))
    Y = as_finite_array(Y, "measurements Y", ndim=(2, 3))
    if Y.shape[-2] < 1:
        raise AKFInputError("measurements Y have no time steps")
    n = A_a.shape[-1]
    m = G_a.shape[-2]
    if A_a.shape[-2] != n:
        raise AKFInputError(f"A_a must be square, got {A_a.shape}")
    if G_a.shape[-1] != n:
        raise AKFInputError(f"G_a has {G_a.shape[-1]} columns; A_a has {n} states")
    if Q_a.shape[-2:] != (n, n):
        raise AKFInputError(f"Q_a must be {n}x{n}, got {Q_a.shape}")
    if R.shape[-2:] != (m, m):
        raise AKFInputError(f"R must be {m}x{m} for {m} channels, got {R.shape}")
    if Y.shape[-1] != m:
        raise AKFInputError(f"measurements have {Y.shape[-1]} channels but G_a has {m} rows")
    if check:
        check_covariance(Q_a, "process covariance Q_a")
        check_covariance(R, "measurement-noise covariance R", definite=True)
    batched = any(x.ndim == 3 for x in (A_a, G_a, Q_a, R, Y))
    if not batched:
        return A_a[None], G_a[None], Q_a[None], R[None], Y[None], False
    sizes = {x.shape[0] for x in (A_a, G_a, Q_a, R, Y) if x.ndim == 3}
    if len(sizes) > 1:
        raise AKFInputError(f"batched inputs disagree on the batch size: {sorted(sizes)}")
    B = sizes.pop()
    expand = [x if x.ndim == 3 else np.broadcast_to(x, (B,) + x.shape) for x in (A_a, G_a, Q_a, R, Y)]
    return (*expand, True)


def filter_states(A_a, G_a, Q_a, R, Y, x0=None, P0=None, steady=False, switch_tol=1e-14, transition=None,
                  check=True, loglik=False):
    """Run one AKF or a batch of them on matrices of one's own (see :func:`run`).

    Parameters
    ----------
    A_a, G_a, Q_a, R, Y
        As in :func:`run`.
    x0 : ndarray (n_a,) or (B, n_a), optional
        Prior mean at step 0 (default zero).
    P0 : ndarray (n_a, n_a) or (B, n_a, n_a), optional
        Prior covariance at step 0 (default ``Q_a``); not used by the steady-state filter.
    steady : bool
        The steady-state gain instead of the time-varying filter.
    switch_tol : float
        The time-varying filter continues with its (then constant) gain once its covariance
        changes by less than this, relatively; 0 keeps it time-varying to the end.
    transition : ModalBlockTransition, optional
        A structured form of a shared ``A_a`` for a cheaper time-varying covariance update.
    check : bool
        Check that Q_a, R and P0 are symmetric PSD (R PD); False for matrices already checked.
    loglik : bool
        Also the log-likelihood terms (:attr:`FilterRun.loglik_terms`); off by default: they
        cost a Cholesky factor per time-varying step.

    Returns
    -------
    FilterRun
        Without a batch axis when no input had one.
    """
    A, G, Q, Rb, Yb, batched = _batchify(A_a, G_a, Q_a, R, Y, check)
    B, n = Yb.shape[0], A.shape[-1]
    if x0 is not None:
        x0 = as_finite_array(x0, "x0")
        if x0.shape[-1:] != (n,):
            raise AKFInputError(f"x0 must have {n} entries (the augmented state), got shape {x0.shape}")
    x = np.zeros((B, n)) if x0 is None else np.broadcast_to(x0, (B, n)).copy()
    if steady:
        res = steady_states(A, G, Q, Rb, Yb, x, loglik)
    else:
        if P0 is not None:
            P0 = check_covariance(P0, "initial covariance P0") if check else np.asarray(P0, float)
            if P0.shape[-2:] != (n, n):
                raise AKFInputError(f"P0 must be {n}x{n}, got {P0.shape}")
        P = Q.copy() if P0 is None else np.broadcast_to(P0, (B, n, n)).copy()
        res = time_varying_filter(A, G, Q, Rb, Yb, x, P, switch_tol, transition, loglik)
    if not batched:
        res = FilterRun(res.states[0], res.innovations[0], res.gain[0], res.P_prior[0], res.switched,
                        None if res.loglik_terms is None else res.loglik_terms[0])
    return res


def run(A_a: Matrix, G_a: ArrayLike, Q_a: Matrix, R: Matrix, Y: Measurements | BatchMeasurements, x0: ArrayLike | None = None,
        P0: ArrayLike | None = None, steady: bool = False) -> np.ndarray:
    """Filtered (posterior) augmented states of the AKF.

    Parameters
    ----------
    A_a : ndarray (n_a, n_a) or (B, n_a, n_a)
        Augmented transition matrix ``[[A, B], [0, I]]``.
    G_a : ndarray (m, n_a) or (B, m, n_a)
        Augmented observation ``[G, D]``.
    Q_a : ndarray (n_a, n_a) or (B, n_a, n_a)
        Process covariance ``blockdiag(Q, S)`` (model error, force increments).
    R : ndarray (m, m) or (B, m, m)
        Measurement-noise covariance.
    Y : ndarray (N, m) or (B, N, m)
        Measurements, one row per time step.
    x0, P0 : optional
        Prior mean (default 0) and covariance (default ``Q_a``) at step 0; ``P0`` is
        ignored by the steady-state filter.
    steady : bool
        Use the steady-state gain (one Riccati solution) instead of the time-varying filter.

    Returns
    -------
    ndarray (N, n_a), or (B, N, n_a) when any input carries a batch axis.

    Notes
    -----
    The filter works in whatever coordinates the matrices are given in.  For stiff FE models
    in raw ``[u; u']`` the Riccati iteration is ill-conditioned; :func:`core_akf.filter.estimate`
    therefore transforms to energy-normalised modal coordinates first
    (:func:`core_akf.statespace.modal_state_transform`) and back afterwards.

    Examples
    --------
    The AKF on matrices of one's own (here the S17 truss' augmented model):

    >>> import numpy as np
    >>> from core_akf import simulate, state_space
    >>> from core_akf.models import s17_truss
    >>> sensors, forces = ["strain:13", "acc:8:y"], ["8:y"]
    >>> sim = simulate(s17_truss(), sensors, forces, np.full((200, 1), 100.0), 1e-3, relative_noise=0.02, seed=0)
    >>> ss = state_space(s17_truss(), sensors, forces, 1e-3)
    >>> Q = np.diag(np.r_[np.full(66, 1e-16), 1e4])
    >>> X = run(ss.A_a, ss.G_a, Q, np.diag(sim.noise_std ** 2), sim.measurements, steady=True)
    >>> X.shape, round(float(X[-1, -1]))          # the last state is the force (N)
    ((200, 67), 100)
    """
    return filter_states(A_a, G_a, Q_a, R, Y, x0=x0, P0=P0, steady=steady).states
