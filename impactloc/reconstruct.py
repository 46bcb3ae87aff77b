"""Force and response reconstruction at the identified location with all installed sensors."""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from core_akf.checks import AKFInputError, ForceLocation, Layout, Measurements, Signal
from core_akf.filter import estimate
from core_akf.forcemodels import ForceModel

if TYPE_CHECKING:
    from core_akf.structure import Structure

    from .scan import Covariances


@dataclass
class ForceSummary:
    """Impact characteristics of a force history (SI).

    Attributes
    ----------
    peak : float
        N, signed.
    time_of_peak : float
        s.
    duration : float
        s: the contiguous span around the peak where ``|f|`` exceeds ``level`` x ``|peak|``.
    impulse : float
        N s: the integral over that span.
    """

    peak: float
    time_of_peak: float
    duration: float
    impulse: float

    def as_dict(self) -> dict[str, float]:
        """The summary as a dict for JSON.

        Returns
        -------
        dict
            ``peak_force``, ``time_of_peak``, ``duration``, ``impulse``.
        """
        return {"peak_force": self.peak, "time_of_peak": self.time_of_peak, "duration": self.duration,
                "impulse": self.impulse}


def force_summary(force: Signal, dt: float, level: float = 0.1) -> ForceSummary:
    """The impact characteristics of a force history.

    Parameters
    ----------
    force : ndarray (N,)
        N.
    dt : float
        Time step (s).
    level : float
        The duration is where ``|f|`` exceeds this share of ``|peak|``.

    Returns
    -------
    ForceSummary

    Examples
    --------
    >>> import numpy as np
    >>> from core_akf.loads import half_sine_pulse
    >>> s = force_summary(half_sine_pulse(np.arange(1000) * 1e-3, 0.1, 0.004, 1e4), 1e-3)
    >>> round(s.peak), round(s.duration, 3)
    (10000, 0.003)
    """
    f = np.asarray(force, float)
    if f.ndim != 1 or f.size == 0:
        raise AKFInputError("force must be a non-empty 1-D history")
    k = int(np.argmax(np.abs(f)))
    peak = float(f[k])
    above = np.abs(f) >= level * abs(peak)
    a = k
    while a > 0 and above[a - 1]:
        a -= 1
    b = k
    while b < f.size - 1 and above[b + 1]:
        b += 1
    return ForceSummary(peak, k * dt, (b - a + 1) * dt, float(np.sum(f[a:b + 1]) * dt))


@dataclass
class Reconstruction:
    """The AKF with all installed sensors at the identified location.

    Attributes
    ----------
    estimate : Estimate
        Force, states and strains at every member or node (:class:`core_akf.filter.Estimate`).
    force : ndarray (N,)
        The force history (N).
    summary : ForceSummary
    """

    estimate: object
    force: np.ndarray
    summary: ForceSummary


#: above this many DOFs the reconstruction runs on the scan's reduced model (with its static
#: correction) instead of the full one, whose steady-state gain would cost minutes
FULL_MODEL_LIMIT = 500


def reconstruct(structure: Structure, sensors: Layout, measurements: Measurements, dt: float, location: ForceLocation,
                covariances: Covariances, n_modes: int | str | None = None,
                force_model: ForceModel | None = None) -> Reconstruction:
    """Reconstruct the force history at a location and the response everywhere.

    The steady-state AKF fed by every installed sensor with the given covariances.

    Parameters
    ----------
    structure : Structure
        The filter's model.
    sensors : sequence of sensor specs
        The installed layout.
    measurements : array_like (N, m)
        The record (SI).
    dt : float
        Time step (s).
    location : (int, str)
        The force location ``(node, direction)``.
    covariances : Covariances
    n_modes : int, "auto" or None
        The filter modes of the scan; a structure of more than :data:`FULL_MODEL_LIMIT` DOFs is
        then reduced to them with a static correction, a smaller one is used whole (the papers'
        cases).
    force_model : ForceModel, optional
        A Matérn model (kind and time scale; std ``sqrt(covariances.force_increment)``); default
        the random walk.

    Returns
    -------
    Reconstruction

    Examples
    --------
    The force of the impact of :func:`impactloc.locate`'s example (10 kN at 0.3 s), at the joint
    it hit:

    >>> from core_akf.models import s17_truss
    >>> from impactloc import default_covariances, simulate_impact
    >>> sensors = ["strain:5", "strain:9", "strain:13", "strain:22", "strain:26", "acc:6:y", "acc:10:y"]
    >>> Y = simulate_impact(s17_truss(), sensors, "14:y").measurements
    >>> rec = reconstruct(s17_truss(), sensors, Y, 1e-3, (14, "y"), default_covariances(sensors, Y))
    >>> round(rec.summary.time_of_peak, 3), rec.estimate.strains.shape
    (0.303, (600, 34))
    """
    if n_modes is not None and structure.n > FULL_MODEL_LIMIT and not structure.is_reduced:
        from core_akf.defaults import resolve_modes

        k = resolve_modes(n_modes, structure, dt, accelerations=True)
        if k is not None:
            structure = structure.reduce(k, static_correction=True)
    est = estimate(structure, sensors, [location], measurements, dt, model_error_cov=covariances.model_error,
                   force_model=covariances.force_model(force_model), noise_cov=dict(covariances.noise), steady=True)
    force = est.forces[:, 0]
    return Reconstruction(est, force, force_summary(force, dt))
