"""Small input-validation helpers shared by the public functions."""
import numpy as np

from .exceptions import AKFInputError, ModelError


def as_finite_array(value, name, ndim=None, shape=None, dtype=float):
    """Return ``value`` as a float array, raising :class:`AKFInputError` naming ``name``."""
    try:
        arr = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise AKFInputError(f"{name} must be numeric: {exc}") from None
    if ndim is not None and arr.ndim not in np.atleast_1d(ndim):
        raise AKFInputError(f"{name} must have {ndim} dimension(s), got shape {arr.shape}")
    if shape is not None:
        for axis, (want, got) in enumerate(zip(shape, arr.shape)):
            if want is not None and want != got:
                raise AKFInputError(
                    f"{name} has shape {arr.shape}; expected {tuple('*' if s is None else s for s in shape)}"
                    f" (axis {axis} should be {want})"
                )
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))
        first = tuple(int(i) for i in bad[0])
        raise AKFInputError(
            f"{name} contains {len(bad)} NaN/inf value(s); first at index {first}"
        )
    return arr


def check_square_symmetric(mat, name, rtol=1e-9):
    """Raise :class:`ModelError` unless ``mat`` is a square symmetric matrix."""
    if mat.ndim != 2 or mat.shape[0] != mat.shape[1]:
        raise ModelError(f"{name} must be square, got shape {mat.shape}")
    scale = np.max(np.abs(mat)) if mat.size else 0.0
    asym = np.max(np.abs(mat - mat.T)) if mat.size else 0.0
    if asym > rtol * max(scale, np.finfo(float).tiny):
        raise ModelError(f"{name} is not symmetric (max |{name} - {name}^T| = {asym:.3g}, max |{name}| = {scale:.3g})")


def check_positive_definite(mat, name):
    """Raise :class:`ModelError` unless ``mat`` is symmetric positive definite."""
    check_square_symmetric(mat, name)
    try:
        np.linalg.cholesky(mat)
    except np.linalg.LinAlgError:
        w = np.linalg.eigvalsh(mat)
        raise ModelError(
            f"{name} is singular or not positive definite (smallest eigenvalue {w[0]:.3g}, "
            f"largest {w[-1]:.3g}); check for DOFs without mass or a missing support"
        ) from None
