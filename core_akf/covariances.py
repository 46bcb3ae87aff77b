"""The covariances of the augmented Kalman filter from the levels a user gives: ``Q`` (model
error, per physical DOF), ``S`` (force increments), ``R`` (measurement noise, per sensor kind or
channel) and the augmented ``Q_a = blockdiag(Q, S)``.  SI units squared, per time step.

>>> import numpy as np
>>> noise_covariance(["strain:5", "acc:4:y"], {"strain": 1e-12, "acc": 1e-4})
array([[1.e-12, 0.e+00],
       [0.e+00, 1.e-04]])
"""
from __future__ import annotations

import numpy as np
import scipy.linalg

from .checks import AKFInputError, FloatArray, Layout, NoiseCovariance, as_finite_array, check_covariance
from .sensors import as_layout


def diag_levels(level, size, name, definite=False):
    """A covariance matrix from a level, variances or a matrix, checked.

    Parameters
    ----------
    level : float, array_like (size,) or array_like (size, size)
        One variance for all, a variance per variable, or the full matrix.
    size : int
        The number of variables.
    name : str
        Its name in a message ("Q", "P0").
    definite : bool
        Require positive definiteness (default: semi-definite).

    Returns
    -------
    ndarray (size, size)
        The covariance, checked by :func:`~core_akf.checks.check_covariance`.

    Examples
    --------
    >>> diag_levels(2.0, 3, "S").diagonal().tolist()
    [2.0, 2.0, 2.0]
    """
    if isinstance(level, (bool, np.bool_)):
        raise AKFInputError(f"{name} must be a number, a vector of variances or a matrix, got {level!r}")
    arr = as_finite_array(level, name)
    if arr.ndim == 0:
        out = float(arr) * np.eye(size)
    elif arr.ndim == 1:
        if arr.size != size:
            raise AKFInputError(f"{name} has {arr.size} variances; expected {size}")
        out = np.diag(arr)
    elif arr.shape == (size, size):
        out = arr
    else:
        raise AKFInputError(f"{name} must be a scalar, a vector of {size} variances or a {size}x{size} matrix; got shape {arr.shape}")
    return check_covariance(out, name, definite=definite)


def noise_covariance(sensors: Layout, noise_cov: NoiseCovariance) -> FloatArray:
    """Measurement-noise covariance ``R`` of a sensor layout.

    Parameters
    ----------
    sensors : sequence of sensor specs
        The layout (strings such as ``"acc:4:y"`` or :class:`~core_akf.sensors.Sensor`), m channels.
    noise_cov : float, array_like (m,), array_like (m, m) or dict
        One variance for all channels, a variance per channel, the matrix, or a variance per
        sensor kind, e.g. ``{"strain": 1e-12, "acc": 1e-4}`` (SI units squared: (m/m)^2,
        (m/s^2)^2, (m/s)^2, m^2).

    Returns
    -------
    ndarray (m, m)
        ``R``, positive definite.

    Examples
    --------
    >>> noise_covariance(["strain:5", "acc:4:y"], {"strain": 1e-12, "acc": 1e-4}).diagonal().tolist()
    [1e-12, 0.0001]
    """
    layout = as_layout(sensors)
    m = len(layout)
    if isinstance(noise_cov, dict):
        missing = sorted({s.kind for s in layout} - set(noise_cov))
        if missing:
            raise AKFInputError(f"noise_cov has no variance for sensor kind(s) {missing}")
        for kind, var in noise_cov.items():
            if isinstance(var, (bool, np.bool_)) or not isinstance(var, (int, float, np.integer, np.floating)) \
                    or not np.isfinite(var) or var <= 0:
                raise AKFInputError(f"noise_cov[{kind!r}] must be a positive variance in SI units squared, got {var!r}")
        return np.diag([float(noise_cov[s.kind]) for s in layout])
    return diag_levels(noise_cov, m, "noise_cov", definite=True)


def state_covariance(structure, model_error_cov):
    """Model-error covariance ``Q`` (2n x 2n) in the structure's generalised coordinates.

    ``model_error_cov`` is given per *physical* free DOF for the displacements and the
    velocities, so the same level means the same thing for a full and a modally reduced model
    (``Q_q = P Q_u P^T`` with the structure's projection ``P``).

    Parameters
    ----------
    structure : Structure
        The filter's model (n generalised coordinates, n_phys physical free DOFs).
    model_error_cov : float, array_like (2 n_phys,) or array_like (2 n_phys, 2 n_phys)
        A level (m^2 and (m/s)^2 per step), a variance per displacement then velocity, or the
        matrix.  For a reduced structure a matrix of the generalised size (2n x 2n) is also
        accepted and used as it is.

    Returns
    -------
    ndarray (2n, 2n)
    """
    if not structure.is_reduced:
        return diag_levels(model_error_cov, 2 * structure.n, "model_error_cov")
    n_phys = structure.free_dofs.size
    P = structure.projection
    if np.ndim(model_error_cov) <= 1 and not isinstance(model_error_cov, (bool, np.bool_)):
        # P diag(q) P^T block by block: no (2 n_phys)^2 matrix for a large model
        q = as_finite_array(model_error_cov, "model_error_cov")
        q = np.broadcast_to(q, (2 * n_phys,)) if q.ndim == 0 else q
        if q.size != 2 * n_phys:
            raise AKFInputError(f"model_error_cov has {q.size} variances; expected {2 * n_phys} (displacements and "
                                "velocities of every free physical DOF)")
        if np.any(q < 0):
            raise AKFInputError("model_error_cov: variances must be >= 0")
        Q = scipy.linalg.block_diag((P * q[:n_phys]) @ P.T, (P * q[n_phys:]) @ P.T)
        return 0.5 * (Q + Q.T)
    if np.ndim(model_error_cov) == 2 and np.shape(model_error_cov) == (2 * structure.n,) * 2 \
            and structure.n != n_phys:
        return diag_levels(model_error_cov, 2 * structure.n, "model_error_cov")
    Q_phys = diag_levels(model_error_cov, 2 * n_phys, "model_error_cov")
    P = scipy.linalg.block_diag(structure.projection, structure.projection)
    Q = P @ Q_phys @ P.T
    return 0.5 * (Q + Q.T)


def augmented_covariance(n_states, n_forces, model_error_cov, force_increment_cov):
    """The augmented process covariance ``Q_a = blockdiag(Q, S)``.

    Parameters
    ----------
    n_states : int
        States of the structural model (2n).
    n_forces : int
        Unknown forces n_p.
    model_error_cov : float, array_like (n_states,) or array_like (n_states, n_states)
        ``Q``: state model-error level(s) per step.
    force_increment_cov : float, array_like (n_forces,) or array_like (n_forces, n_forces)
        ``S``: force-increment level(s) per step (N^2).

    Returns
    -------
    ndarray (n_states + n_forces, n_states + n_forces)
    """
    Q = diag_levels(model_error_cov, n_states, "model_error_cov")
    S = diag_levels(force_increment_cov, n_forces, "force_increment_cov")
    Q_a = np.zeros((n_states + n_forces,) * 2)
    Q_a[:n_states, :n_states] = Q
    Q_a[n_states:, n_states:] = S
    return Q_a
