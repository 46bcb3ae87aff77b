"""The steady-state augmented Kalman filter on stacks of problems: one batched Riccati solve for
the constant gain (:func:`core_akf.riccati.steady_gain`), then the constant-gain recursion in
lifted form (:func:`core_akf.recursion.lti_response`), to the filtered states or straight to a
few outputs.  Shapes: ``A``, ``Q`` (B, n, n); ``G`` (B, m, n); ``R`` (B, m, m); ``Y`` (B, N, m)."""
from __future__ import annotations

import numpy as np

from .recursion import lti_response
from .riccati import steady_gain


def steady_states(A, G, Q, R, Y, x=None):
    """Filtered states of a batch of steady-state AKFs.

    One batched Riccati solve (:func:`core_akf.riccati.steady_gain`), then the constant-gain
    recursion ``X_k = (I - L G) A X_{k-1} + L y_k`` (:func:`core_akf.recursion.lti_response`).

    Parameters
    ----------
    A : ndarray (B, n, n)
    G : ndarray (B, m, n)
    Q : ndarray (B, n, n)
    R : ndarray (B, m, m)
    Y : ndarray (B, N, m)
        Measurements.
    x : ndarray (B, n), optional
        Prior mean of the first step (default zero).

    Returns
    -------
    X : ndarray (B, N, n)
        Filtered states.
    L : ndarray (B, n, m)
        The gain.
    P : ndarray (B, n, n)
        The prior covariance.
    """
    P, L, F, first = steady_filter(A, G, Q, R, Y, x)
    return lti_response(F, L, Y, first), L, P


def steady_filter(A, G, Q, R, Y, x=None):
    """Gain and fixed-gain recursion of a batch of steady-state AKFs.

    The recursion is ``X_k = F X_{k-1} + L y_k`` from the first filtered state ``X_0``.

    Parameters
    ----------
    A, G, Q, R, Y, x
        As :func:`steady_states`.

    Returns
    -------
    P : ndarray (B, n, n)
        The prior covariance.
    L : ndarray (B, n, m)
        The gain.
    F : ndarray (B, n, n)
        ``(I - L G) A``.
    X_0 : ndarray (B, n)
        The first filtered state.
    """
    P, L = steady_gain(A, G, Q, R)
    n = A.shape[-1]
    I_LG = np.eye(n) - L @ G
    first = np.einsum("bij,bj->bi", L, Y[:, 0])
    if x is not None:
        first += np.einsum("bij,bj->bi", I_LG, x)
    return P, L, I_LG @ A, first


def steady_outputs(A, G, Q, R, Y, H):
    """Outputs ``H X_k`` of a stack of steady-state AKFs (filtered states, prior mean zero).

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

    One batched Riccati solve, then the lifted recursion straight to the outputs
    (:func:`core_akf.recursion.lti_response`): with few output rows the n states per step are
    never formed.
    """
    B, N, m = Y.shape
    n = G.shape[-1]
    P, L, F, first = steady_filter(np.broadcast_to(A, (B, n, n)), G, np.broadcast_to(Q, (B, n, n)), R, Y)
    return lti_response(F, L, Y, first, H)
