"""AKF estimates of forces and the full response: :func:`estimate` for one sensor layout and
:func:`estimate_batch` for many layouts of one structure in one batched call.

Both build one :class:`~core_akf.filter.model.Filter` (every input checked there, once), run a
kernel (:mod:`core_akf.filter.kernels`) and return :class:`~core_akf.filter.results.Estimate`.

Conventions: ``X_k = [x_k; f_k]`` (``n_a = 2n + n_p``; ``[x_k; xi_k]`` with the force states of a
Matérn model, ``f_k = H xi_k``), the prior at step 0 is ``x0`` with covariance ``P0``; each step
first updates with ``y_k`` and then predicts.  The returned states are the filtered (posterior) ones.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from ..checks import AKFInputError, ArrayLike, BatchMeasurements, Covariance, Forces, Layout, Measurements, NoiseCovariance, as_measurements
from ..forcemodels import DummyMeasurements, ForceModel
from . import kernels
from .model import Filter
from .results import Estimate

if TYPE_CHECKING:
    from ..structure import Structure


def estimate_batch(structure: Structure, layouts: Sequence[Layout], forces: Forces, measurements: BatchMeasurements,
                   dt: float, *, model_error_cov: Covariance, force_increment_cov: Covariance | None = None,
                   noise_cov: NoiseCovariance, steady: bool | None = None, allow_undetectable: bool = False,
                   x0: ArrayLike | None = None, P0: ArrayLike | None = None, smooth: bool = False,
                   force_model: ForceModel | None = None, dummy: DummyMeasurements | None = None) -> list[Estimate]:
    """AKF estimates for many sensor layouts of one structure in one batched filter call.

    Parameters
    ----------
    structure : Structure
        The filter's model.
    layouts : sequence of sensor layouts
        B layouts, all with the same number m of sensors.
    forces : sequence of force specs
        The unknown force locations (shared).
    measurements : ndarray (B, N, m) or sequence of (N, m)
        One measurement set per layout, columns in layout order (SI); NaN marks a missing sample.
    dt : float
        Time step (s).
    model_error_cov, force_increment_cov
        Q and S, as in :func:`estimate`.
    noise_cov : float, ndarray, dict, or one per layout
        R as in :func:`estimate`, applied to every layout; or one entry per layout (a (B, m, m)
        array or a list of B dicts of variances per sensor kind).
    steady : bool or None
        As in :func:`estimate` (None: steady where every layout is detectable).
    allow_undetectable : bool
        Run layouts that fail the PBH test.
    x0, P0 : optional
        Prior mean (n_a,) and covariance of the physical augmented state ``[u; u'; f]``.
    smooth : bool
        As in :func:`estimate`.
    force_model, dummy : optional
        As in :func:`estimate`.

    Returns
    -------
    list of Estimate
        One per layout.

    Examples
    --------
    Two layouts, each with its own record, in one call:

    >>> import numpy as np
    >>> from core_akf import simulate
    >>> from core_akf.models import s17_truss
    >>> truss, layouts = s17_truss(), [["strain:13", "acc:8:y"], ["strain:12", "acc:8:y"]]
    >>> Y = np.stack([simulate(truss, l, ["8:y"], np.full((200, 1), 100.0), 1e-3, relative_noise=0.02,
    ...                        seed=0).measurements for l in layouts])
    >>> ests = estimate_batch(truss, layouts, ["8:y"], Y, 1e-3, model_error_cov=1e-16, force_increment_cov=1e4,
    ...                       noise_cov={"strain": 1e-14, "acc": 1e-4})
    >>> [round(float(e.forces[-50:].mean())) for e in ests]      # the 100 N step
    [100, 100]
    """
    Y = as_measurements(measurements, "measurements", ndim=3)
    f = Filter(structure, layouts, forces, dt, model_error_cov=model_error_cov, force_increment_cov=force_increment_cov,
               noise_cov=noise_cov, steady=steady, allow_undetectable=allow_undetectable, x0=x0, P0=P0,
               force_model=force_model, dummy=dummy)
    if Y.shape[0] != len(f.layouts) or Y.shape[2] != f.m:
        if len(f.layouts) == 1 and Y.shape[0] == 1:
            raise AKFInputError(f"measurements have {Y.shape[2]} columns for {f.m} sensors")
        raise AKFInputError(f"measurements must have shape ({len(f.layouts)}, N, {f.m}); got {Y.shape}")
    return run_filter(f, Y, smooth=smooth)


def run_filter(f: Filter, Y: BatchMeasurements, *, smooth: bool = False, loglik: bool = True) -> list[Estimate]:
    """The estimates of a built filter, one per layout.

    Parameters
    ----------
    f : Filter
        The filter (its steady or time-varying form).
    Y : ndarray (B, N, m)
        One record per layout (SI, the real channels).
    smooth : bool
        The smoothed estimates (:meth:`Filter.smooth`).
    loglik : bool
        With the log-likelihood terms (:attr:`Estimate.loglik`).

    Returns
    -------
    list of Estimate
    """
    if Y.shape[1] < 1:
        raise AKFInputError("measurements have no time steps")
    kernel = kernels.steady if f.steady else kernels.time_varying
    estimates = f.estimates(kernel(f, f.extend(Y), loglik=loglik), Y)
    if smooth:
        estimates = [f.smooth(est, b, Y[b]) for b, est in enumerate(estimates)]
    return estimates


def estimate(structure: Structure, sensors: Layout, forces: Forces, measurements: Measurements, dt: float, *,
             model_error_cov: Covariance, force_increment_cov: Covariance | None = None, noise_cov: NoiseCovariance,
             steady: bool | None = None, allow_undetectable: bool = False, x0: ArrayLike | None = None,
             P0: ArrayLike | None = None, smooth: bool = False, force_model: ForceModel | None = None,
             dummy: DummyMeasurements | None = None) -> Estimate:
    """Estimate unknown forces and the full response with the AKF.

    Parameters
    ----------
    structure : Structure
        The filter's model (it may differ from the true structure: that is model error).
    sensors : sequence of sensor specs
        ``Sensor`` objects or strings such as ``"acc:4:y"``, ``"strain:5"``.
    forces : sequence
        Force locations ``"node:direction"`` or ``(node, direction)``.
    measurements : ndarray (N, m)
        One column per sensor in layout order (SI: m/m, m/s^2, m/s, m).  A NaN is a missing
        sample: the update uses the observed channels only (exactly with ``steady=False``; with
        cached gains per pattern of observed channels with the steady filter,
        :func:`core_akf.filter.kernels.steady_gapped`).
    dt : float
        Sampling interval (s).
    model_error_cov : float, ndarray
        ``Q``: variance level(s) of the state model error per step, per physical DOF
        (displacements then velocities: scalar, vector or matrix); see :func:`state_covariance`.
    force_increment_cov : float, ndarray, optional
        ``S``: variance of the force increment per step (N^2) of the random-walk force model
        (required with it; leave it out with a Matérn ``force_model``).
    noise_cov : float, ndarray or dict
        ``R``: measurement-noise variance(s), e.g. ``{"strain": (1e-6)**2, "acc": 0.01**2}``.
    steady : bool or None
        True: the steady-state gain (fast); False: the time-varying filter.  None (default,
        :data:`core_akf.defaults.DEFAULTS`): the steady-state filter, or the time-varying one for
        an undetectable set run with ``allow_undetectable`` (no steady state exists there).
    allow_undetectable : bool
        Run even if the PBH test fails (the estimate will drift).
    x0 : array_like (2n + n_g,), optional
        Prior mean of the augmented state ``[u; u'; xi]`` at step 0 (default zero); ``xi = f``
        (``n_g = n_p``) for the random walk, the force states of a Matérn model otherwise.
    P0 : float or array_like, optional
        Prior covariance at step 0 (a level, variances or the matrix; default ``Q_a``, with the
        stationary covariance of a Matérn model's force states); the steady-state filter does not
        use it.
    smooth : bool
        Smooth the states with the whole record (the RTS smoother, :func:`core_akf.filter.smoother.smooth`):
        forces and strains are then the smoothed ones, with their standard deviations
        (:attr:`Estimate.force_std`, :attr:`Estimate.strain_std`).  Smoothing helps only a model
        the data agree with: check the consistency first (calibrate).
    force_model : ForceModel, optional
        The forces' prior (:mod:`core_akf.forcemodels`): default the random walk of
        ``force_increment_cov``; a Matérn model (``ForceModel("matern32", std=..., timescale=...)``)
        makes accelerometer-only sets detectable for zero-mean loads.
    dummy : DummyMeasurements, optional
        Zero pseudo-measurements of displacements or strains, appended to the sensors (they keep a
        random-walk filter on accelerations from drifting).

    Returns
    -------
    Estimate

    Examples
    --------
    >>> import numpy as np
    >>> from core_akf.models import s17_truss
    >>> est = estimate(s17_truss(), ["strain:13", "acc:8:y"], ["8:y"], np.zeros((100, 2)), 1e-3,
    ...                model_error_cov=1e-16, force_increment_cov=1e4, noise_cov={"strain": 1e-14, "acc": 1e-4})
    >>> est.forces.shape, est.strains.shape
    ((100, 1), (100, 34))
    """
    Y = as_measurements(measurements, "measurements", ndim=2)
    return estimate_batch(structure, [sensors], forces, Y[None], dt, model_error_cov=model_error_cov,
                          force_increment_cov=force_increment_cov, noise_cov=noise_cov, steady=steady,
                          allow_undetectable=allow_undetectable, x0=x0, P0=P0, smooth=smooth,
                          force_model=force_model, dummy=dummy)[0]
