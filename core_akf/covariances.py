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

from .checks import as_finite_array, check_covariance
from .exceptions import AKFInputError
from .sensors import as_layout


def diag_levels(level, size, name, definite=False):
    """A covariance matrix (size x size) from a scalar level, a vector of variances or a full
    matrix, checked by :func:`~core_akf.checks.check_covariance` (symmetric, PSD; PD with
    ``definite=True``)."""
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


def noise_covariance(sensors, noise_cov):
    """Measurement-noise covariance (m x m) from a scalar, per-channel variances, a matrix,
    or a dict of variances per sensor kind, e.g. ``{"strain": 1e-12, "acc": 1e-4}``."""
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
    velocities (a scalar level, a vector of 2 n_phys variances or a matrix), so the same level
    means the same thing for a full and a modally reduced model (``Q_q = P Q_u P^T`` with the
    structure's projection ``P``).  For a reduced structure a matrix of the generalised size
    (2n x 2n) is also accepted and used as it is.
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
    """``Q_a = blockdiag(Q, S)`` from levels (scalar, vector of variances or matrix)."""
    Q = diag_levels(model_error_cov, n_states, "model_error_cov")
    S = diag_levels(force_increment_cov, n_forces, "force_increment_cov")
    Q_a = np.zeros((n_states + n_forces,) * 2)
    Q_a[:n_states, :n_states] = Q
    Q_a[n_states:, n_states:] = S
    return Q_a
