"""Error metrics (S17 eq. 38, IMP eq. 31, TH eq. 29)."""
from __future__ import annotations

import numpy as np

from .checks import as_finite_array
from .exceptions import AKFInputError
from .types import ArrayLike


def rms_error(estimate: ArrayLike, reference: ArrayLike, axis: int = 0) -> np.ndarray:
    """RMS error per channel: ``sqrt(sum_k (est_k - ref_k)^2 / N)`` (S17 eq. 38, IMP eq. 31, TH eq. 29).

    ``estimate`` and ``reference`` have the same shape, time along ``axis``.
    """
    est = as_finite_array(estimate, "estimate")
    ref = as_finite_array(reference, "reference")
    if est.shape != ref.shape:
        raise AKFInputError(f"estimate {est.shape} and reference {ref.shape} differ in shape")
    return np.sqrt(np.mean((est - ref) ** 2, axis=axis))


def rms(signal, axis=0):
    """RMS value per channel."""
    return np.sqrt(np.mean(np.asarray(signal, float) ** 2, axis=axis))


def average_strain_error(estimate: ArrayLike, reference: ArrayLike, axis: int = 0) -> float:
    """Mean of the per-component RMS strain errors (TH's "average strain error"), in strain.

    For ``(N, n_strain)`` inputs this is one number; a leading batch axis gives one per batch.
    """
    return np.mean(rms_error(estimate, reference, axis=axis), axis=-1)
