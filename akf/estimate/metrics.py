"""What an estimate run reports: its metrics (errors against a reference, log-likelihood,
per-channel diagnostics, warnings), the one-row-per-channel summary table, and
:class:`EstimateResult`."""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from core_akf.checks import AKFInputError
from core_akf.diagnostics import CONSISTENCY_LIMIT, scale_check, warnings_for
from core_akf.metrics import average_strain_error, rms_error
from core_akf.simulate import MICROSTRAIN

from ..job import Job

#: above this innovation consistency (innovation RMS / predicted) on any channel, a smoothed
#: estimate is reported as untrustworthy: the model disagrees with the data (S17 case 4 as shipped:
#: 2.1-3.6 on the gauges, and the smoother makes its forces 24 % worse; calibrated: 0.99-1.01)
SMOOTH_CONSISTENCY_LIMIT = 1.5

#: units of the numbers in :attr:`EstimateResult.metrics` (and the CLI's JSON)
METRIC_UNITS = {"rms_force": "N", "rms_strain": "m/m", "avg_strain_error": "m/m", "avg_strain_error_microstrain": "µε",
                "loglik": "the natural log of a probability density of the record in SI units (higher is likelier; "
                          "compare runs of one record only)",
                "forces": {"rms": "N", "peak": "N", "time_of_peak": "s"},
                "sensors": "per channel: the sensor's SI unit (m/m, m/s^2, m/s, m); consistency, whiteness and "
                           "missing_fraction are dimensionless, longest_missing_s in s; consistency, whiteness and "
                           "loglik over the observed samples"}


def summary_frame(metrics):
    """One row per channel of a job's metrics: every force location (estimated RMS and peak, and
    the RMS error against the reference if there is one), every sensor (measured RMS and the
    innovation statistics of :mod:`core_akf.diagnostics`) and, with a reference, every strain
    output (RMS error).  Never empty: measured data without a reference still has forces and sensors."""
    import pandas as pd

    m = metrics
    errors = m.get("rms_force", {})
    rows = [dict(quantity="force", **f, rms_error=errors.get(f["channel"], np.nan)) for f in m.get("forces", [])]
    rows += [dict(quantity="sensor", channel=d["channel"], unit=d["unit"], rms=d["measured_rms"],
                  **{k: v for k, v in d.items() if k not in ("channel", "unit", "measured_rms")})
             for d in m.get("sensors", [])]
    rows += [{"quantity": "strain", "channel": k, "unit": "m/m", "rms_error": v}
             for k, v in m.get("rms_strain", {}).items()]
    columns = ["quantity", "channel", "unit", "rms_error", "rms", "peak", "time_of_peak", "innovation_rms",
               "predicted_innovation_std", "consistency", "whiteness", "lag1_autocorrelation", "loglik",
               "missing_fraction", "missing_spans", "longest_missing_s"]
    return pd.DataFrame(rows, columns=columns)


@dataclass
class EstimateResult:
    """What :func:`akf.estimate.estimate_job` did.

    Attributes
    ----------
    job : Job
    metrics : dict
        ``detectable``, ``n_steps``, ``units`` (:data:`METRIC_UNITS`), ``calibration`` (with
        ``[filter] calibrate``: :func:`akf.calibrating.calibrate_job`), ``loglik`` (the Gaussian
        log-likelihood of the innovations, :mod:`core_akf.filter.likelihood`), ``forces`` and ``sensors``
        (per channel, :mod:`core_akf.diagnostics`, each with its ``loglik``), ``warnings``; for a simulated job also
        ``rms_force`` (N per force), ``rms_strain`` (m/m per output), ``avg_strain_error`` (m/m)
        and ``avg_strain_error_microstrain``.  Empty for a run stopped before its end.
    files : dict
        The files written (``timeseries``, ``summary``, ``figure``, ``sensors_figure``,
        ``checkpoint`` of a stopped run); empty without an output folder.
    channels : list of str
        The record's channels (file channel -> sensor, unit); empty for a simulated job.
    notes : list of str
    resumed_at : int
        The step a resumed run went on from (0: from the start).
    complete : bool
        False for a run stopped before its end (``stop_after``).
    estimate : core_akf.filter.Estimate or None
        The whole record's estimate, when it was filtered in one chunk (a simulated job, or any
        job without an output folder).
    simulation : core_akf.simulate.Simulation or None
        The truth of a simulated job.
    """

    job: Job
    metrics: dict
    files: dict = field(default_factory=dict)
    channels: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    resumed_at: int = 0
    complete: bool = True
    estimate: object = None
    simulation: object = None

    def summary_frame(self):
        """One row per channel (:func:`summary_frame` of the metrics)."""
        return summary_frame(self.metrics)

    def timeseries_frame(self, strains="all"):
        """The tidy time series of an estimate held in memory (as ``timeseries.csv``): forces, then
        the strain outputs ``strains`` ("all" or a list of labels), with the reference of a
        simulated job."""
        if self.estimate is None:
            raise AKFInputError("this run was filtered in chunks: its time series are in files['timeseries']")
        index = "all" if strains == "all" else self.estimate.structure.strain_label_index(strains)
        return self.estimate.to_frame(strains=index, reference=self.simulation, start=0)


def joined(parts):
    """One estimate of consecutive ones (a record smoothed with a lag comes in parts)."""
    parts = [p for p in parts if p.forces.shape[0]] or parts[:1]
    cat = {name: np.concatenate([getattr(p, name) for p in parts]) for name in
           ("states", "forces", "innovations", "measurements", "loglik_terms", "force_std", "strain_std")}
    return replace(parts[0], **cat)


def run_metrics(job, estimator, diag, last, n_total, t0, whole, sim, model, noise_cov, first_chunk):
    """The metrics of a finished run (see :class:`EstimateResult`); ``first_chunk()`` gives the
    record's first chunk, for the scale check of a channel that does not fit."""
    sensors, forces = job.sensors, job.forces
    metrics = {"detectable": estimator.report.detectable, "n_steps": int(n_total), "units": METRIC_UNITS}
    if sim is not None:
        rf = rms_error(whole.forces, sim.loads)
        metrics["rms_force"] = {f"{n}:{d}": float(v) for (n, d), v in zip(forces, rf)}
        if job.structure.n_strain:       # a model of one's own may have no strain outputs
            rs = rms_error(whole.strains, sim.strains)
            metrics["rms_strain"] = dict(zip(job.structure.strain_labels, map(float, rs)))
            metrics["avg_strain_error"] = float(average_strain_error(whole.strains, sim.strains))
            metrics["avg_strain_error_microstrain"] = metrics["avg_strain_error"] / MICROSTRAIN
    metrics["loglik"] = diag.loglik()
    metrics["forces"] = diag.forces(t0)
    metrics["sensors"] = diag.sensors()
    metrics["warnings"] = warnings_for(last, metrics["sensors"], duration=n_total * job.dt)
    if estimator.report.detectable and any(d["consistency"] > CONSISTENCY_LIMIT for d in metrics["sensors"]):
        # some channel does not fit: on the record's first chunk, find out whether a unit or a sign is wrong
        found = scale_check(model, sensors, forces, first_chunk(), job.dt, model_error_cov=estimator.model_error_cov,
                            force_model=estimator.force_model, noise_cov=noise_cov)
        metrics["warnings"] = found + metrics["warnings"]
        if sim is None:
            metrics["warnings"].append("check the channel map in [measurements]: units, invert (sign) and "
                                       "gauge_factor of the channels named above")
    return metrics
