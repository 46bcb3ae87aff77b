"""Small input-validation helpers shared by the public functions."""
import os

import numpy as np

from .exceptions import AKFInputError, ModelError


def as_finite_array(value, name, ndim=None, shape=None, dtype=float):
    """Return ``value`` as a finite float array, or raise :class:`AKFInputError` naming it.

    Parameters
    ----------
    value : array_like
        The values to check.
    name : str
        What the values are, for the message ("measurements", "x0").
    ndim : int, optional
        The number of dimensions the array must have.
    shape : tuple of int, optional
        The shape the array must have.
    dtype : type, optional
        The type to convert to (default float).

    Returns
    -------
    ndarray
        ``value`` as an array of ``dtype``.

    Raises
    ------
    AKFInputError
        For values that are not numbers, NaN or infinite values (the first one located), or
        another dimension or shape.

    Examples
    --------
    >>> as_finite_array([1, 2], "dt").tolist()
    [1.0, 2.0]
    """
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
    """Raise :class:`ModelError` unless ``mat`` is a square symmetric matrix.

    Parameters
    ----------
    mat : array_like (n, n)
        The matrix (a stiffness, mass or damping matrix).
    name : str
        Its name in the message ("K", "M").
    rtol : float
        Largest asymmetry accepted, relative to the largest magnitude of ``mat``.
    """
    if mat.ndim != 2 or mat.shape[0] != mat.shape[1]:
        raise ModelError(f"{name} must be square, got shape {mat.shape}")
    scale = np.max(np.abs(mat)) if mat.size else 0.0
    asym = np.max(np.abs(mat - mat.T)) if mat.size else 0.0
    if asym > rtol * max(scale, np.finfo(float).tiny):
        sym = name.split()[-1]
        raise ModelError(f"{name} is not symmetric (max |{sym} - {sym}^T| = {asym:.3g}, max |{sym}| = {scale:.3g})")


def check_positive_definite(mat, name):
    """Raise :class:`ModelError` unless ``mat`` is symmetric positive definite.

    Parameters
    ----------
    mat : array_like (n, n)
        The matrix (a mass matrix).
    name : str
        Its name in the message.
    """
    check_square_symmetric(mat, name)
    try:
        np.linalg.cholesky(mat)
    except np.linalg.LinAlgError:
        w = np.linalg.eigvalsh(mat)
        raise ModelError(
            f"{name} is singular or not positive definite (smallest eigenvalue {w[0]:.3g}, "
            f"largest {w[-1]:.3g}); check for DOFs without mass or a missing support"
        ) from None


#: a variance above this (in SI units squared) is a unit mistake: it would overflow the filter
_MAX_VARIANCE = 1e100


def check_covariance(mat, name, definite=False):
    """Check a covariance matrix, or a stack of them.

    The tests are free of units (strain variances of 1e-16 next to acceleration variances of 1
    are common): a diagonal entry must be >= 0 (> 0 if definite), and the correlation matrix
    ``D^-1/2 C D^-1/2`` (unit diagonal) must have no eigenvalue below ``-n eps`` (definite: none
    below ``n eps``), the rounding level of an eigenvalue solver on it (Weyl).  An asymmetry above
    1e-9 of the larger diagonal entry of the pair is a mistake, not the rounding of the products
    that formed the matrix (about n eps).

    Parameters
    ----------
    mat : array_like (..., n, n)
        The covariance (leading batch axes allowed), in squared units of its variables.
    name : str
        Its name in the message ("R", "initial covariance P0").
    definite : bool
        Require positive definiteness, as a measurement-noise covariance must be (default:
        semi-definite).

    Returns
    -------
    ndarray (..., n, n)
        ``mat`` as a float array.

    Raises
    ------
    AKFInputError
        For a matrix that is not finite, real, square, symmetric or (semi-)definite.
    """
    arr = as_finite_array(mat, name)
    if arr.ndim < 2 or arr.shape[-1] != arr.shape[-2]:
        raise AKFInputError(f"{name} must be a square matrix, got shape {arr.shape}")
    n = arr.shape[-1]
    flat = arr.reshape(-1, n, n)
    where = (lambda b: f" (batch entry {b})") if arr.ndim > 2 else (lambda b: "")
    big = np.max(np.abs(arr), initial=0.0)
    if big > _MAX_VARIANCE:
        raise AKFInputError(f"{name} has entries up to {big:.3g}: not a physical variance in SI units squared "
                            f"(above {_MAX_VARIANCE:g}); check the units")
    for b, C in enumerate(flat):
        d = np.diag(C)
        low = int(np.argmin(d)) if n else 0
        if n and (d[low] < 0 or (definite and d[low] == 0)):
            need = "> 0: every channel needs some noise" if definite else ">= 0"
            raise AKFInputError(f"{name} must be positive {'definite' if definite else 'semi-definite'}{where(b)}; "
                                f"its variance at position {low + 1} is {d[low]:.3g} (variances must be {need})")
        off = C - np.diag(d)
        if not np.any(off):
            continue
        scale = np.sqrt(np.outer(d, d))
        asym = np.abs(C - C.T)
        if np.any(asym > 1e-9 * np.maximum(np.maximum.outer(d, d), np.finfo(float).tiny)):
            i, j = np.unravel_index(int(np.argmax(asym)), asym.shape)
            raise AKFInputError(f"{name} is not symmetric{where(b)}: entries ({i + 1}, {j + 1}) and ({j + 1}, {i + 1}) "
                                f"are {C[i, j]:.6g} and {C[j, i]:.6g}")
        orphan = (scale == 0) & (np.abs(off) > n * np.finfo(float).eps * np.max(d))
        if np.any(orphan):
            i, j = np.argwhere(orphan)[0]
            raise AKFInputError(f"{name} is not positive semi-definite{where(b)}: entry ({i + 1}, {j + 1}) is "
                                f"{C[i, j]:.3g} although a variance of that pair is 0")
        corr = np.divide(0.5 * (C + C.T), scale, out=np.zeros_like(C), where=scale > 0)
        w = np.linalg.eigvalsh(corr)
        tol = n * np.finfo(float).eps
        if w[0] < -tol or (definite and w[0] <= tol):
            raise AKFInputError(f"{name} must be positive {'definite' if definite else 'semi-definite'}{where(b)}; "
                                f"its correlation matrix has the eigenvalue {w[0]:.3g} (correlations above 1 "
                                "or inconsistent ones)")
    return arr


def available_memory():
    """Bytes of memory available to a new allocation.

    Returns
    -------
    int or None
        ``MemAvailable`` on Linux, else the physical memory; None if unknown.
    """
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(n_steps, floats_per_step, what, fix, items="time steps"):
    """Refuse, before allocating, a record that would not fit in memory.

    Parameters
    ----------
    n_steps : float
        Time steps (or other ``items``) of the record.
    floats_per_step : float
        float64 values held per step.
    what : str
        What the record is, for the message ("a 2 s record at dt = 0.001 s").
    fix : str
        What to do instead, for the message.
    items : str
        What ``n_steps`` counts (default "time steps").

    Raises
    ------
    AKFInputError
        When the record needs more than 80 % of the available memory.
    """
    need = 8.0 * float(n_steps) * float(floats_per_step)
    have = available_memory()
    if have is not None and need > 0.8 * have:
        raise AKFInputError(f"{what}: {n_steps:.4g} {items} need about {need / 2 ** 30:.3g} GiB, but this machine "
                            f"has {have / 2 ** 30:.3g} GiB available; {fix}")


def first_repeat(values):
    """The first value that repeats.

    Parameters
    ----------
    values : sequence
        Hashable values (sensor labels, node ids).

    Returns
    -------
    tuple or None
        ``(i, j, value)`` with positions ``i < j`` (0-based) of the first value that repeats, or
        ``None`` when every value is distinct.

    Examples
    --------
    >>> first_repeat(["strain:5", "acc:4:y", "strain:5"])
    (0, 2, 'strain:5')
    """
    seen = {}
    for j, v in enumerate(values):
        if v in seen:
            return seen[v], j, v
        seen[v] = j
    return None
