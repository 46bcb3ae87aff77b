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

from ..checks import FloatArray, Layout, Reference
from ..quality import missing_statistics
from ..sensors import UNITS
from ..statespace import observation, strain_feedthrough
from .kernels import closed_loop

if TYPE_CHECKING:
    import pandas as pd


#: lags of the innovation autocorrelation checked for whiteness
WHITENESS_LAGS = 20
#: the columns of the one tidy table (:meth:`Estimate.to_frame`, ``timeseries.csv``)
TIDY_COLUMNS = ("time", "quantity", "channel", "unit", "estimated", "reference", "std")


def skipped(n):
    """Samples left out of the statistics as the start-up transient: the first 5 %.

    Parameters
    ----------
    n : int
        Steps of the record.

    Returns
    -------
    int
    """
    return n // 20


def whiteness(e, lags=WHITENESS_LAGS):
    """How white a sequence of innovations is.

    Parameters
    ----------
    e : ndarray (N,)
        Innovations of one channel (its unit); NaN where a sample is missing (left out).
    lags : int
        Autocorrelation lags tested, ``1..lags``.

    Returns
    -------
    share : float
        Share of the lags inside the 95 % band ``+-1.96 / sqrt(N)`` of white noise (about 0.95
        for white innovations); NaN for a constant sequence.
    lag1 : float
        The lag-1 autocorrelation.
    """
    e = np.asarray(e, float)
    seen = ~np.isnan(e)
    n = int(seen.sum())
    e = np.where(seen, e - (np.mean(e[seen]) if n else 0.0), 0.0)    # a missing sample adds nothing
    denom = float(e @ e)
    lags = min(lags, n - 1, e.size - 1)
    if denom == 0 or lags < 1:
        return float("nan"), float("nan")
    rho = np.array([float(e[:-k] @ e[k:]) / denom for k in range(1, lags + 1)])
    return float(np.mean(np.abs(rho) < 1.96 / np.sqrt(n))), float(rho[0])


def sensor_diagnostics(est):
    """Innovation statistics per sensor, over the record after its first 5 %.

    Parameters
    ----------
    est : Estimate
        An estimate (:func:`core_akf.filter.estimate`).

    Returns
    -------
    list of dict
        One per sensor: ``channel``, ``unit``, ``measured_rms``, ``innovation_rms``,
        ``predicted_innovation_std`` (``sqrt(S_ii)``), ``consistency`` (their ratio, about 1 when
        the model and the covariances fit the data), ``whiteness`` and ``lag1_autocorrelation``
        (:func:`whiteness`), and ``loglik``, the channel's log-likelihood over the whole record
        (:attr:`Estimate.loglik_channels`), all over the observed samples; and its holes
        (:func:`core_akf.quality.missing_statistics`): ``missing_fraction``, ``missing_spans`` and
        ``longest_missing_s`` (s).
    """
    Y, E = est.measurements, est.innovations
    k0 = skipped(Y.shape[0])
    loglik = est.loglik_channels                      # over the whole record
    out = []
    for j, (s, holes) in enumerate(zip(est.sensors, missing_statistics(Y, est.dt))):
        e = E[k0:, j]
        irms = _rms(e)
        std = float(np.sqrt(max(est.innovation_cov[j, j], 0.0)))
        white, lag1 = whiteness(e)
        out.append({"channel": s.label, "unit": UNITS[s.kind], "measured_rms": _rms(Y[k0:, j]),
                    "innovation_rms": irms, "predicted_innovation_std": std,
                    "consistency": irms / std if std > 0 else float("inf"), "whiteness": white,
                    "lag1_autocorrelation": lag1, "loglik": float(loglik[j]), **holes})
    return out


def _rms(x):
    """The RMS of the observed (not NaN) samples; NaN when there are none."""
    x = x[~np.isnan(x)]
    return float(np.sqrt(np.mean(x ** 2))) if x.size else float("nan")


def force_statistics(est):
    """Statistics of the estimated forces, after the first 5 % of the record.

    Parameters
    ----------
    est : Estimate
        An estimate (:func:`core_akf.filter.estimate`).

    Returns
    -------
    list of dict
        One per force location: ``channel`` ("8:y"), ``unit`` (N), ``rms`` (N), ``peak`` (N, the
        signed value of the largest magnitude) and ``time_of_peak`` (s).
    """
    k0 = skipped(est.forces.shape[0])
    out = []
    for j, (node, d) in enumerate(est.force_locations):
        f = est.forces[k0:, j]
        i = int(np.argmax(np.abs(f)))
        out.append({"channel": f"{node}:{d}", "unit": "N", "rms": float(np.sqrt(np.mean(f ** 2))),
                    "peak": float(f[i]), "time_of_peak": float((k0 + i) * est.dt)})
    return out


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
        rho = float(np.max(np.abs(np.linalg.eigvals(closed_loop(A, G, L)[1]))))
        return self.dt / -np.log(rho) if rho < 1 else np.inf

    @property
    def time(self):
        """Time of each step (s): ``t0 + k dt`` (``t0`` > 0 for a chunk of a streamed record)."""
        return self.t0 + np.arange(self.forces.shape[0]) * self.dt

    @cached_property
    def strains(self):
        """Strains at every member (truss) or node component (plate), shape (N, n_strain)."""
        return self.strain_outputs()

    def strain_outputs(self, index: list[int] | None = None) -> FloatArray:
        """Strains at the outputs ``index`` (0-based rows of the model's strain operator; None: all),
        with the static correction of a reduced model: the one place strains come from states.

        Parameters
        ----------
        index : list of int, optional

        Returns
        -------
        ndarray (N, k) (m/m)
        """
        if index is not None and "strains" in self.__dict__:
            return self.strains[:, index]
        n = self.structure.n
        rows = self.structure.strain_operator if index is None else self.structure.strain_operator[index]
        out = self.states[:, :n] @ rows.T
        extra = strain_feedthrough(self.structure, self.force_locations)
        if extra is None:
            return out
        return out + self.forces @ (extra if index is None else extra[index]).T

    def diagnostics(self) -> list[dict]:
        """Innovation statistics per sensor (:func:`sensor_diagnostics`): consistency, whiteness,
        log-likelihood, RMS.

        Returns
        -------
        list of dict
        """
        return sensor_diagnostics(self)

    def summary(self) -> pd.DataFrame:
        """One row per channel, as a statsmodels result's summary: every force location (RMS, peak,
        time of the peak, mean standard deviation of a smoothed estimate) and every sensor (measured
        RMS and :meth:`diagnostics`).  ``attrs`` holds the record's ``loglik``, ``transient_time``
        (s), ``n_steps``, ``dt`` (s) and whether it is ``smoothed``.

        Returns
        -------
        pandas.DataFrame
        """
        import pandas as pd

        rows = [dict(quantity="force", **f) for f in force_statistics(self)]
        if self.smoothed:
            for row, std in zip(rows, np.mean(self.force_std, axis=0)):
                row["mean_std"] = float(std)
        rows += [dict(quantity="sensor", channel=d["channel"], unit=d["unit"], rms=d["measured_rms"],
                      **{k: v for k, v in d.items() if k not in ("channel", "unit", "measured_rms")})
                 for d in self.diagnostics()]
        columns = ["quantity", "channel", "unit", "rms", "peak", "time_of_peak", "mean_std", "innovation_rms",
                   "predicted_innovation_std", "consistency", "whiteness", "lag1_autocorrelation", "loglik",
                   "missing_fraction", "missing_spans", "longest_missing_s"]
        frame = pd.DataFrame(rows, columns=columns)
        frame.attrs = {"loglik": self.loglik if self.loglik_terms is not None else float("nan"),
                       "transient_time": float(self.transient_time) if self.filter_matrices is not None
                       else float("nan"), "n_steps": int(self.forces.shape[0]), "dt": self.dt,
                       "smoothed": self.smoothed}
        return frame

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

    def to_frame(self, wide: bool = False, *, strains: list[int] | str = "all", reference: Reference | None = None,
                 start: int | None = None) -> pd.DataFrame:
        """The estimated forces and strains as a :class:`pandas.DataFrame` (the tidy schema of
        ``timeseries.csv``).

        Parameters
        ----------
        wide : bool
            False (default), tidy: one row per time step and channel, columns :data:`TIDY_COLUMNS`:
            ``time`` (s), ``quantity`` ("force" or "strain"), ``channel`` (``"8:y"``,
            ``"strain:13"``, ``"strain:70:ex"``), ``unit`` ("N", "m/m"), ``estimated``,
            ``reference`` (NaN without one) and ``std`` (the standard deviation of a smoothed
            estimate, NaN for a filtered one); text columns are categoricals.  True: one row per
            time step and one column per channel (``force:8:y``, ``strain:13``), for spreadsheets.
        strains : "all" or list of int
            The strain outputs (0-based rows of the model's strain operator) after the forces.
        reference : Reference, optional
            The truth, e.g. a :class:`core_akf.simulate.Simulation`: its ``loads`` (N_ref, n_p) and
            ``strains`` (N_ref, n_strain), of which this estimate covers the steps from ``start``.
        start : int, optional
            The step of the reference this estimate starts at (default ``t0 / dt``).

        Returns
        -------
        pandas.DataFrame
        """
        import pandas as pd

        index = list(range(self.structure.n_strain)) if isinstance(strains, str) and strains == "all" else list(strains)
        labels = [f"{node}:{d}" for node, d in self.force_locations] + [self.structure.strain_labels[i] for i in index]
        values = np.hstack([self.forces] + ([self.strain_outputs(index)] if index else []))
        if wide:
            cols = {"time": self.time}
            cols.update({(f"force:{c}" if j < len(self.force_locations) else c): values[:, j]
                         for j, c in enumerate(labels)})
            return pd.DataFrame(cols)
        n, k = self.time.size, len(labels)
        if reference is not None:
            s0 = int(round(self.t0 / self.dt)) if start is None else int(start)
            ref = np.hstack([reference.loads[s0:s0 + n]] + ([reference.strains[s0:s0 + n, index]] if index else []))
            ref = ref.T.reshape(-1)
        else:
            ref = np.full(n * k, np.nan)
        if self.smoothed:
            std = np.hstack([self.force_std] + ([self.strain_std[:, index]] if index else [])).T.reshape(-1)
        else:
            std = np.full(n * k, np.nan)
        is_strain = np.repeat(np.arange(k) >= len(self.force_locations), n).astype(np.int8)

        def column(codes, categories):
            return pd.Categorical.from_codes(codes, categories=categories)
        return pd.DataFrame({"time": np.tile(self.time, k), "quantity": column(is_strain, ["force", "strain"]),
                             "channel": column(np.repeat(np.arange(k), n), labels),
                             "unit": column(is_strain, ["N", "m/m"]),
                             "estimated": values.T.reshape(-1), "reference": ref, "std": std})
