"""Error metrics (S17 eq. 38, IMP eq. 31, TH eq. 29)."""
from __future__ import annotations

import numpy as np

from .checks import AKFInputError, ArrayLike, as_finite_array


def rms_error(estimate: ArrayLike, reference: ArrayLike, axis: int = 0) -> np.ndarray:
    """RMS error per channel: ``sqrt(sum_k (est_k - ref_k)^2 / N)`` (S17 eq. 38, IMP eq. 31, TH eq. 29).

    Parameters
    ----------
    estimate, reference : array_like
        The same shape, time along ``axis`` (SI).
    axis : int
        The time axis.

    Returns
    -------
    ndarray
        One value per channel, in the channels' unit.

    Examples
    --------
    >>> rms_error([[1.0, 0.0], [3.0, 0.0]], [[0.0, 0.0], [0.0, 0.0]]).tolist()
    [2.23606797749979, 0.0]
    """
    est = as_finite_array(estimate, "estimate")
    ref = as_finite_array(reference, "reference")
    if est.shape != ref.shape:
        raise AKFInputError(f"estimate {est.shape} and reference {ref.shape} differ in shape")
    return np.sqrt(np.mean((est - ref) ** 2, axis=axis))


def rms(signal, axis=0):
    """RMS value per channel.

    Parameters
    ----------
    signal : array_like
        Time along ``axis``.
    axis : int
        The time axis.

    Returns
    -------
    ndarray
    """
    return np.sqrt(np.mean(np.asarray(signal, float) ** 2, axis=axis))


def average_strain_error(estimate: ArrayLike, reference: ArrayLike, axis: int = 0) -> float:
    """Mean of the per-component RMS strain errors (TH's "average strain error").

    Parameters
    ----------
    estimate, reference : array_like (N, n_strain) or (B, N, n_strain)
        Strains (m/m).
    axis : int
        The time axis.

    Returns
    -------
    float or ndarray (B,)
        In m/m: one number, or one per batch for a leading batch axis.

    Examples
    --------
    >>> import numpy as np
    >>> float(average_strain_error(np.full((4, 3), 2e-6), np.full((4, 3), 1e-6))) / 1e-6      # µε
    1.0
    """
    return np.mean(rms_error(estimate, reference, axis=axis), axis=-1)
