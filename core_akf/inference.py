"""Standard errors of a maximum-likelihood fit that hold when the model is wrong.

The observed information ``I = -d^2 log L / du^2`` gives standard errors that are right only if
the model that wrote the likelihood made the record.  A filter's likelihood rarely is: the force
prior (a random walk, a Matérn process) is a guess at the loads' spectrum, and the noise is not
exactly Gaussian.  The robust (sandwich, Godambe) covariance of the estimate is::

    V = I^-1 J I^-1,     J = the long-run covariance of the per-step scores s_k = d l_k / du

where ``l_k`` is step k's log-likelihood term (the sum over steps is ``log L``).  Under a correct
model the scores are martingale differences with ``J = I`` (the information-matrix equality),
and ``V = I^-1``.  Under a wrong one the scores are neither: ``J`` differs from ``I`` and the
scores are correlated in time, so ``J`` is a heteroscedasticity and autocorrelation consistent
(HAC) estimate -- Newey & West (1987) with Bartlett weights, the bandwidth chosen from the data by
Andrews' (1991) AR(1) plug-in rule (:func:`hac_bandwidth`).

The ratio of the two standard errors per parameter (:func:`information_ratio`) is the
misspecification check (White 1982): near 1 when the model fits, far from 1 when it does not.
"""
from __future__ import annotations

import numpy as np

from .checks import AKFInputError, ArrayLike

#: a robust standard error more than this factor from the observed-information one (either way)
#: says the model does not fit the record as its likelihood assumes
MISFIT_RATIO = 2.0
#: the AR(1) coefficient of a score is clipped here in the bandwidth rule (a unit root has none)
MAX_RHO = 0.97
#: beyond this many lags the autocovariances are computed by FFT
FFT_LAGS = 64


def hac_bandwidth(scores: ArrayLike) -> float:
    """Andrews' (1991) automatic bandwidth of the Bartlett kernel from AR(1) fits of each score.

    ``S = 1.1447 (alpha T)^(1/3)`` with
    ``alpha = sum_a 4 rho_a^2 s_a^4 / ((1 - rho_a)^6 (1 + rho_a)^2) / sum_a s_a^4 / (1 - rho_a)^4``
    (``rho_a``, ``s_a^2``: the AR(1) coefficient and innovation variance of score ``a``).

    Parameters
    ----------
    scores : array_like (T, k)
        Per-step scores.

    Returns
    -------
    float
        The bandwidth (steps), between 0 and ``T / 3``.

    Examples
    --------
    >>> import numpy as np
    >>> white = np.random.default_rng(0).normal(size=(4000, 1))
    >>> hac_bandwidth(white) < 3           # uncorrelated scores: a few lags at most
    True
    """
    X = _centred(scores)
    T = X.shape[0]
    a, b = X[1:], X[:-1]
    denom = np.einsum("ij,ij->j", b, b)
    rho = np.clip(np.divide(np.einsum("ij,ij->j", a, b), denom, out=np.zeros(X.shape[1]), where=denom > 0),
                  -MAX_RHO, MAX_RHO)
    s2 = np.mean((a - rho * b) ** 2, axis=0)
    num = np.sum(4 * rho ** 2 * s2 ** 2 / ((1 - rho) ** 6 * (1 + rho) ** 2))
    den = np.sum(s2 ** 2 / (1 - rho) ** 4)
    alpha = num / den if den > 0 else 0.0
    return float(min(1.1447 * (alpha * T) ** (1.0 / 3.0), T / 3.0))


def long_run_covariance(scores: ArrayLike, bandwidth: float | None = None) -> np.ndarray:
    """``J``: the covariance of the sum of a series of scores, with its autocorrelation (HAC).

    ``J = sum_{|l| <= L} w_l Gamma_l`` with ``Gamma_l = sum_t s_t s_{t-l}^T`` of the centred scores
    and Bartlett weights ``w_l = 1 - |l| / (L + 1)``, ``L = floor(bandwidth)``.

    Parameters
    ----------
    scores : array_like (T, k)
        Per-step scores.
    bandwidth : float, optional
        The bandwidth (steps); default :func:`hac_bandwidth`.  0 gives the outer product of the
        scores (no autocorrelation).

    Returns
    -------
    ndarray (k, k)
        Scaled as the sum over steps (as the observed information is); statsmodels'
        ``S_hac_simple`` of the centred scores with ``nlags = floor(bandwidth)``.

    Raises
    ------
    AKFInputError
        For scores that are not finite, or a negative bandwidth.
    """
    X = _centred(scores)
    if bandwidth is None:
        bandwidth = hac_bandwidth(X)
    if not np.isfinite(bandwidth) or bandwidth < 0:
        raise AKFInputError(f"the HAC bandwidth must be a non-negative number of steps, got {bandwidth!r}")
    T = X.shape[0]
    L = min(int(np.floor(bandwidth)), T - 1)
    w = 1.0 - np.arange(1, L + 1) / (L + 1.0)
    if L <= FFT_LAGS:
        J = X.T @ X
        for lag in range(1, L + 1):
            G = X[lag:].T @ X[:-lag]
            J += w[lag - 1] * (G + G.T)
    else:                                   # many lags: every cross-covariance at once by FFT
        F = np.fft.rfft(X, n=2 * T, axis=0)
        C = np.fft.irfft(F[:, :, None] * np.conj(F[:, None, :]), n=2 * T, axis=0)[:L + 1]   # C[l] = sum_t x_t+l x_t^T
        G = np.tensordot(w, C[1:], axes=(0, 0))
        J = C[0] + G + G.T
    return 0.5 * (J + J.T)


def sandwich_covariance(information: ArrayLike, scores: ArrayLike, bandwidth: float | None = None) -> np.ndarray:
    """The robust covariance of a maximum-likelihood estimate, ``I^-1 J I^-1``.

    Parameters
    ----------
    information : array_like (k, k)
        The observed information (minus the Hessian of the log-likelihood at the estimate).
    scores : array_like (T, k)
        The per-step scores at the estimate.
    bandwidth : float, optional
        As :func:`long_run_covariance`.

    Returns
    -------
    ndarray (k, k)

    Raises
    ------
    numpy.linalg.LinAlgError
        For a singular information matrix.

    Examples
    --------
    The variance of Laplace data fitted as Gaussian: the scores of ``u = log var`` are
    ``(e^2 / var - 1) / 2`` and the information ``T / 2``; the kurtosis (6) makes the robust
    standard error ``sqrt((6 - 1) / T)``, not the model's ``sqrt(2 / T)``:

    >>> import numpy as np
    >>> e = np.random.default_rng(1).laplace(size=200000)
    >>> var = np.mean(e ** 2)
    >>> V = sandwich_covariance([[e.size / 2]], (e[:, None] ** 2 / var - 1) / 2, bandwidth=0)
    >>> round(float(np.sqrt(V[0, 0] * e.size)), 1), round(float(np.sqrt(5)), 1)
    (2.2, 2.2)
    """
    inv = np.linalg.inv(np.asarray(information, float))
    V = inv @ long_run_covariance(scores, bandwidth) @ inv
    return 0.5 * (V + V.T)


def information_ratio(observed: ArrayLike, robust: ArrayLike) -> np.ndarray:
    """The robust standard error over the observed-information one, per parameter.

    Near 1 where the model fits the record; beyond :data:`MISFIT_RATIO` (either way) the
    observed-information errors are not to be trusted.

    Parameters
    ----------
    observed, robust : array_like (k,)
        Standard errors.

    Returns
    -------
    ndarray (k,)
        NaN where either is not a positive number.
    """
    o, r = np.asarray(observed, float), np.asarray(robust, float)
    ok = np.isfinite(o) & np.isfinite(r) & (o > 0)
    return np.divide(r, o, out=np.full(o.shape, np.nan), where=ok)


def _centred(scores):
    """The scores as a finite (T, k) array less their mean."""
    X = np.asarray(scores, float)
    if X.ndim == 1:
        X = X[:, None]
    if X.ndim != 2 or X.shape[0] < 2:
        raise AKFInputError(f"scores must be (steps, parameters) with at least 2 steps, got shape {X.shape}")
    if not np.all(np.isfinite(X)):
        raise AKFInputError("the per-step scores are not finite: the likelihood is not defined near the estimate")
    return X - X.mean(axis=0)
