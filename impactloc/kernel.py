"""The batched inner loop of the location scan and the covariance tuning: many steady-state
AKFs (one per candidate location x role split x covariance set) that each predict the held-back
(AD) sensors, returning only the AD errors.

Per filter: the steady gain ``L`` (batched doubling Riccati solver of ``core_akf``), the
closed-loop transition ``F = (I - L G) A`` and the posterior recursion
``X_k = F X_{k-1} + L y_k`` as one batched product per step (measured faster than a
diagonalised, mode-by-mode recursion, whose eigenvector matrices are also ill-conditioned:
cond ~1e6-1e7 on the plate).  The Riccati solve dominates: keep the model small.
"""
from __future__ import annotations

import numpy as np

from core_akf.akf import lti_recursion
from core_akf.riccati import steady_gain


def ad_predictions(A, G, Q, R, Y, H):
    """AD predictions of a stack of steady-state AKFs.

    Parameters
    ----------
    A : (B, n, n) or (n, n) augmented transition;  G : (B, m, n) SE observation rows
    Q : (B, n, n) or (n, n);  R : (B, m, m);  Y : (B, N, m) SE measurements
    H : (B, a, n) AD observation rows

    Returns
    -------
    ndarray (B, N, a): ``H X_k`` with ``X_k`` the filtered (posterior) augmented state.
    """
    B, N, m = Y.shape
    n = G.shape[-1]
    A = np.broadcast_to(A, (B, n, n))
    _, L = steady_gain(A, G, np.broadcast_to(Q, (B, n, n)), R)
    F = (np.eye(n) - L @ G) @ A
    U = Y @ np.swapaxes(L, -1, -2)                          # (B, N, n): L y_k
    X = lti_recursion(F, U, U[:, 0])                         # X_0 = L y_0 (prior mean zero)
    out = X @ np.swapaxes(H, -1, -2)
    return out


def rms_errors(pred, Y_ad, skip=0):
    """RMS error per filter and AD channel over samples ``skip..N-1``, absolute and relative
    to the RMS of the measured channel: two arrays (B, a)."""
    d = pred[:, skip:] - Y_ad[:, skip:]
    err = np.sqrt(np.mean(d * d, axis=1))
    ref = np.sqrt(np.mean(Y_ad[:, skip:] ** 2, axis=1))
    return err, err / np.maximum(ref, np.finfo(float).tiny)
