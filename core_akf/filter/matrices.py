"""The AKF on matrices of one's own: :func:`run` and :func:`filter_states` (checked inputs, an
optional batch axis), on the kernels of :mod:`core_akf.filter.kernels`.

A NaN in the measurements is a missing sample: the update uses the observed rows only
(:func:`core_akf.filter.kernels.gapped_filter`).
"""
from __future__ import annotations

import numpy as np

from ..checks import AKFInputError, ArrayLike, BatchMeasurements, Matrix, Measurements, as_finite_array, as_measurements, check_covariance
from .kernels import FilterRun, gapped_filter, observed, steady_gapped, steady_states, time_varying_filter


def _batchify(A_a, G_a, Q_a, R, Y, check=True):
    """Validate shapes (and with ``check`` the covariances); return arrays with a leading batch
    axis and whether the input had one."""
    A_a = as_finite_array(A_a, "A_a", ndim=(2, 3))
    G_a = as_finite_array(G_a, "G_a", ndim=(2, 3))
    Q_a = as_finite_array(Q_a, "Q_a", ndim=(2, 3))
    R = as_finite_array(R, "R", ndim=(2, 3))
    Y = as_measurements(Y, "measurements Y", ndim=(2, 3))
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
    seen = observed(Yb)
    if steady:
        res = steady_states(A, G, Q, Rb, Yb, x, loglik) if seen is None else \
            steady_gapped(A, G, Q, Rb, Yb, seen, x, loglik)
    else:
        if P0 is not None:
            P0 = check_covariance(P0, "initial covariance P0") if check else np.asarray(P0, float)
            if P0.shape[-2:] != (n, n):
                raise AKFInputError(f"P0 must be {n}x{n}, got {P0.shape}")
        P = Q.copy() if P0 is None else np.broadcast_to(P0, (B, n, n)).copy()
        res = time_varying_filter(A, G, Q, Rb, Yb, x, P, switch_tol, transition, loglik) if seen is None else \
            gapped_filter(A, G, Q, Rb, Yb, seen, x, P, switch_tol, transition, loglik)
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
