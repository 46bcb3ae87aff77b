"""The AKF's result: :class:`Estimate`, forces, states and strains with what the filter knew of them.

An estimate carries its own summary, as a statsmodels result does: :attr:`Estimate.loglik`,
:attr:`Estimate.transient_time`, :meth:`Estimate.diagnostics` (consistency and whiteness per
channel), :meth:`Estimate.summary` (one row per channel) and :meth:`Estimate.to_frame` (the one
tidy table of the toolkit).  Forces and strains come from the model's output rows, here only.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from ..statespace import observation, strain_feedthrough
from ..types import FloatArray, Layout

if TYPE_CHECKING:
    import pandas as pd


@dataclass
class Estimate:
    """AKF estimate of forces, states and strains.

    Attributes
    ----------
    structure : Structure
        The filter's model.
    sensors : tuple of Sensor
        The layout, m channels.
    force_locations : list of tuple
        The unknown force locations, 1-based ``(node, direction)``.
    dt : float
        Time step (s).
    time : ndarray (N,)
        Time of each step (s).
    forces : ndarray (N, n_p)
        Estimated forces (N) at ``force_locations``.
    states : ndarray (N, 2n)
        ``[u; u']`` in generalised coordinates (m, m/s for a full model).
    innovations : ndarray (N, m)
        ``y_k - G_a X_k^-``, in the sensors' units.
    gain : ndarray (n_a, m)
        Steady-state (or last) Kalman gain for ``[u; u'; f]``.
    detectability : DetectabilityReport
        The PBH test of the sensor layout.
    measurements : ndarray (N, m)
        The data the filter ran on (SI).
    innovation_cov : ndarray (m, m)
        Predicted innovation covariance ``G_a P G_a^T + R`` of the steady-state (or last) prior
        covariance ``P``, in squared sensor units.
    filter_matrices : tuple
        ``(A_a, G_a, L)`` in the filter's internal coordinates, with the steady-state (or last)
        gain ``L``; the closed loop ``(I - L G_a) A_a`` sets the transient.
    t0 : float
        Time of the first step (s); 0 except for chunks of a streamed record
        (:class:`core_akf.filter.streaming.Estimator`).
    loglik_terms : ndarray (N, m)
        The log-likelihood of the innovations per step and channel
        (:func:`core_akf.filter.likelihood.loglik_terms`); see :attr:`loglik`.
    force_std : ndarray (N, n_p) or None
        The standard deviation of every smoothed force (N); None for a filtered estimate.
    strain_std : ndarray (N, n_strain) or None
        The standard deviation of every smoothed strain output (m/m); None for a filtered estimate.
    """

    structure: object
    sensors: tuple
    force_locations: list
    dt: float
    states: np.ndarray
    forces: np.ndarray
    innovations: np.ndarray
    gain: np.ndarray = field(repr=False, default=None)
    detectability: object = field(repr=False, default=None)
    measurements: np.ndarray = field(repr=False, default=None)
    innovation_cov: np.ndarray = field(repr=False, default=None)
    filter_matrices: tuple = field(repr=False, default=None)
    t0: float = 0.0
    loglik_terms: np.ndarray = field(repr=False, default=None)
    force_std: np.ndarray = field(repr=False, default=None)
    strain_std: np.ndarray = field(repr=False, default=None)

    @property
    def smoothed(self):
        """Whether the states are smoothed (:func:`estimate` with ``smooth=True``): then
        :attr:`force_std` and :attr:`strain_std` hold their standard deviations."""
        return self.force_std is not None

    @property
    def loglik(self):
        """The Gaussian log-likelihood of the innovations (a float, dimensionless): how probable
        the record is under the filter's model and covariances (:mod:`core_akf.filter.likelihood`)."""
        return float(np.sum(self.loglik_terms))

    @property
    def loglik_channels(self):
        """The log-likelihood per channel, shape (m,): each channel's innovations given those of
        the channels before it in the layout; they sum to :attr:`loglik`."""
        return np.sum(self.loglik_terms, axis=0)

    @property
    def predicted(self):
        """One-step predictions of the measurements, ``y_k - innovation_k``, shape (N, m)."""
        return self.measurements - self.innovations

    @cached_property
    def transient_time(self):
        """Time constant (s) of the filter's slowest error mode, ``-dt / ln(rho)`` with ``rho`` the
        spectral radius of the closed loop ``(I - L G_a) A_a``; ``inf`` if it does not decay."""
        A, G, L = self.filter_matrices
        rho = float(np.max(np.abs(np.linalg.eigvals(A - L @ (G @ A)))))
        return self.dt / -np.log(rho) if rho < 1 else np.inf

    @property
    def time(self):
        """Time of each step (s): ``t0 + k dt`` (``t0`` > 0 for a chunk of a streamed record)."""
        return self.t0 + np.arange(self.forces.shape[0]) * self.dt

    @cached_property
    def strains(self):
        """Strains at every member (truss) or node component (plate), shape (N, n_strain)."""
        n = self.structure.n
        out = self.states[:, :n] @ self.structure.strain_operator.T
        extra = strain_feedthrough(self.structure, self.force_locations)
        return out if extra is None else out + self.forces @ extra.T

    def response(self, sensors: Layout) -> FloatArray:
        """Estimated response at any sensors (e.g. held-back validation sensors).

        Parameters
        ----------
        sensors : sequence of sensor specs
            k sensors on the filter's model.

        Returns
        -------
        ndarray (N, k)
            In the sensors' SI units.
        """
        G, D = observation(self.structure, sensors, self.force_locations)
        return self.states @ G.T + self.forces @ D.T

    def to_frame(self, wide: bool = False) -> pd.DataFrame:
        """The estimated forces and strains as a :class:`pandas.DataFrame`.

        Parameters
        ----------
        wide : bool
            False (default), tidy: one row per time step and channel, columns ``time`` (s),
            ``quantity`` ("force" or "strain"), ``channel`` (``"8:y"``, ``"strain:13"``,
            ``"strain:70:ex"``: the names of force locations and sensors), ``unit`` ("N", "m/m") and
            ``value``.  True: one row per time step and one column per channel (``force:8:y``,
            ``strain:13``), for spreadsheets.

        Returns
        -------
        pandas.DataFrame
        """
        import pandas as pd

        forces = [f"{node}:{d}" for node, d in self.force_locations]
        strains = self.structure.strain_labels
        if wide:
            cols = {"time": self.time}
            cols.update({f"force:{c}": self.forces[:, j] for j, c in enumerate(forces)})
            cols.update(dict(zip(strains, self.strains.T)))
            return pd.DataFrame(cols)
        N = self.time.size
        values = np.hstack([self.forces, self.strains])
        channels = forces + strains
        return pd.DataFrame({
            "time": np.tile(self.time, len(channels)),
            "quantity": np.repeat(["force"] * len(forces) + ["strain"] * len(strains), N),
            "channel": np.repeat(channels, N),
            "unit": np.repeat(["N"] * len(forces) + ["m/m"] * len(strains), N),
            "value": values.T.reshape(-1)})


