"""Small input-validation helpers shared by the public functions."""
import numpy as np

from .exceptions import AKFInputError, ModelError


def as_finite_array(value, name, ndim=None, shape=None, dtype=float):
    """Return ``value`` as a float array, raising :class:`AKFInputError` naming ``name``."""
    if np.iscomplexobj(value):
        raise AKFInputError(f"{name} is complex; the filter works on real data (take .real, or the magnitude, first)")
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


def check_covariance(mat, name, definite=False):
    """Check a covariance matrix (or a stack of them, leading batch axes): finite, real, square,
    symmetric and positive semi-definite (``definite=True``: positive definite, as a measurement
    noise covariance must be).  Returns it as a float array.

    Tolerances: an asymmetry above 1e-9 of the largest entry is a mistake, not the rounding of
    the products that formed the matrix (about n eps); an eigenvalue below ``-n eps ||C||`` is
    negative beyond the rounding of an eigenvalue solver (Weyl), and for ``definite=True`` every
    eigenvalue must exceed ``n eps ||C||``.
    """
    arr = as_finite_array(mat, name)
    if arr.ndim < 2 or arr.shape[-1] != arr.shape[-2]:
        raise AKFInputError(f"{name} must be a square matrix, got shape {arr.shape}")
    n = arr.shape[-1]
    scale = np.max(np.abs(arr), axis=(-2, -1), initial=0.0)
    asym = np.max(np.abs(arr - np.swapaxes(arr, -1, -2)), axis=(-2, -1), initial=0.0)
    bad = np.flatnonzero(np.ravel(asym > 1e-9 * np.maximum(scale, np.finfo(float).tiny)))
    if bad.size:
        where = f" (batch entry {bad[0]})" if arr.ndim > 2 else ""
        raise AKFInputError(f"{name} is not symmetric{where}: max |C - C^T| = {np.ravel(asym)[bad[0]]:.3g} "
                            f"against max |C| = {np.ravel(scale)[bad[0]]:.3g}")
    diagonal = not np.any(arr - np.eye(n) * np.diagonal(arr, axis1=-2, axis2=-1)[..., None, :])
    eig = np.diagonal(arr, axis1=-2, axis2=-1) if diagonal else np.linalg.eigvalsh(arr)
    tol = n * np.finfo(float).eps * np.maximum(scale, np.finfo(float).tiny)
    low = np.min(eig, axis=-1)
    bad = np.flatnonzero(np.ravel(low <= tol if definite else low < -tol))
    if bad.size:
        b = bad[0]
        where = f" (batch entry {b})" if arr.ndim > 2 else ""
        e = np.reshape(eig, (-1, n))[b]
        what = "positive definite (every channel needs a noise variance > 0)" if definite else "positive semi-definite"
        detail = (f"variance {e.min():.3g} at position {int(np.argmin(e)) + 1}" if diagonal
                  else f"smallest eigenvalue {e.min():.3g}, largest {e.max():.3g}")
        raise AKFInputError(f"{name} must be {what}{where}; it has {detail}")
    return arr


def available_memory():
    """Bytes of memory available to a new allocation (``MemAvailable`` on Linux, else the
    physical memory); ``None`` if unknown."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        import os

        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(n_steps, floats_per_step, what, fix):
    """Refuse, before allocating, a record of ``n_steps`` time steps that needs more than 80 % of
    the available memory at ``floats_per_step`` float64 values per step."""
    need = 8.0 * float(n_steps) * float(floats_per_step)
    have = available_memory()
    if have is not None and need > 0.8 * have:
        raise AKFInputError(f"{what}: {n_steps:.4g} time steps need about {need / 2 ** 30:.3g} GiB, but this machine "
                            f"has {have / 2 ** 30:.3g} GiB available; {fix}")
