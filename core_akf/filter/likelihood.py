"""The Gaussian log-likelihood of a filter's innovations: how probable the record is under the
filter's model and covariances (the quantity maximum-likelihood calibration maximises).

For innovations ``e_k`` with predicted covariance ``S_k = G_a P_k G_a^T + R``::

    log L = -1/2 sum_k (m log 2 pi + log det S_k + e_k^T S_k^-1 e_k)

It is split per step and per channel by the Cholesky factor ``S_k = C_k C_k^T``: with
``z = C_k^-1 e_k``, channel j contributes ``-1/2 (log 2 pi + 2 log C_jj + z_j^2)``, the log density
of its innovation given those of the channels before it in the layout (the sequential form of a
univariate Kalman filter).  The terms sum to ``log L`` exactly; a channel whose data disagree with
the model (a wrong unit, a wrong sign, a model error it sees) has a low sum.
"""
from __future__ import annotations

import numpy as np

from ..checks import AKFInputError

#: log(2 pi)
LOG_2PI = float(np.log(2.0 * np.pi))


def loglik_terms(innovations, S):
    """The log-likelihood of innovations, per step and per channel.

    Parameters
    ----------
    innovations : ndarray (..., N, m)
        ``y_k - G_a x_k^-`` (the sensors' SI units).
    S : ndarray (..., m, m) or (..., N, m, m)
        Their predicted covariance: one for every step (a steady or converged filter), or one
        per step.

    Returns
    -------
    ndarray (..., N, m)
        The terms; their sum is the log-likelihood.

    Raises
    ------
    AKFInputError
        For a covariance that is not positive definite.

    Examples
    --------
    Two unit innovations of unit variance: ``-1/2 (2 log 2 pi + 2)``

    >>> import numpy as np
    >>> ll = loglik_terms(np.array([[1.0], [-1.0]]), np.eye(1)).sum()
    >>> bool(np.isclose(ll, -(np.log(2 * np.pi) + 1.0)))
    True
    """
    E = np.asarray(innovations, float)
    C = _cholesky(S)
    log_diag = np.log(np.diagonal(C, axis1=-2, axis2=-1))
    if C.ndim == E.ndim + 1:                                   # one covariance per step
        z = np.linalg.solve(C, E[..., None])[..., 0]
        return -0.5 * (LOG_2PI + 2.0 * log_diag + z ** 2)
    C_inv = np.linalg.inv(C)                                   # constant: z = E C^-T, one product
    z = E @ np.swapaxes(C_inv, -1, -2)
    return -0.5 * (LOG_2PI + 2.0 * log_diag[..., None, :] + z ** 2)


def loglik_total(innovations, S):
    """The log-likelihood of innovations of one constant covariance, summed over steps and channels.

    The sum of :func:`loglik_terms` without forming them: ``-1/2 (N m log 2 pi + N log det S +
    tr(S^-1 E^T E))``, with ``E^T E`` one (m, m) product per stack entry.

    Parameters
    ----------
    innovations : ndarray (..., N, m)
    S : ndarray (..., m, m)
        Their predicted covariance, the same for every step.

    Returns
    -------
    ndarray (...)

    Raises
    ------
    AKFInputError
        For a covariance that is not positive definite.

    Examples
    --------
    >>> import numpy as np
    >>> E = np.random.default_rng(0).normal(size=(50, 2))
    >>> S = np.array([[2.0, 0.3], [0.3, 1.0]])
    >>> bool(np.isclose(loglik_total(E, S), loglik_terms(E, S).sum()))
    True
    """
    E = np.asarray(innovations, float)
    C = _cholesky(S)
    N, m = E.shape[-2:]
    C_inv = np.linalg.inv(C)
    gram = np.swapaxes(E, -1, -2) @ E                                 # (..., m, m)
    quad = np.einsum("...ij,...jk,...ik->...", C_inv, gram, C_inv)   # tr(C^-1 E^T E C^-T)
    log_det = 2.0 * np.log(np.diagonal(C, axis1=-2, axis2=-1)).sum(axis=-1)
    return -0.5 * (N * m * LOG_2PI + N * log_det + quad)


def _cholesky(S):
    """The Cholesky factor of innovation covariances, or the error that names them."""
    try:
        return np.linalg.cholesky(np.asarray(S, float))
    except np.linalg.LinAlgError:
        raise AKFInputError("the predicted innovation covariance is not positive definite: the likelihood is "
                            "undefined (check the noise covariance R)") from None
