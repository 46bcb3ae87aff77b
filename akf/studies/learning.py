"""Learning from the data, worked on S17 case 4 (``akf study learning``): the job's filter model
is 5 % stiffer than the truss that made the record.

1. The record's log-likelihood against the filter's stiffness factor (0.90-1.10 of the truss):
   it peaks at the truth (figure ``likelihood.png``).
2. Calibration of the stiffness factor by maximum likelihood: the factor, the log-likelihood and
   the gauges' consistency before and after, and the force error.
3. Filtered against smoothed forces, with the smoother's +-2 sigma bands, for the model as given
   and the calibrated one (figure ``smoothed.png``): smoothing helps the calibrated model only.

Writes ``learning.csv`` (the likelihood scan), ``learning_summary.csv`` (one row per model and
estimator) and the two figures; the numbers are printed first, the figures drawn last.
"""
from __future__ import annotations

import logging
import os

import numpy as np

from core_akf.outputs import write_csv

from ..examples import example
from ._common import Progress, StudyResult, output_dir, save

log = logging.getLogger("akf")

NAME = "learning"
DESCRIPTION = "S17 case 4: log-likelihood against stiffness, calibration, filtered against smoothed with bands"
#: the filter's stiffness factors of the likelihood scan (relative to the truss)
FACTORS = np.round(np.arange(0.90, 1.1001, 0.01), 2)


def run(out=None, quick=False, seed=0):
    """Run the worked example (``quick``: 1 s of record instead of 2), write the tables, print
    them, then draw the figures."""
    import pandas as pd

    from core_akf.calibration import calibrate
    from core_akf.filter import Filter, estimate
    from core_akf.filter.kernels import steady_logliks
    from core_akf.metrics import rms_error

    out = output_dir(NAME, out)
    job = example("s17-case4", overrides={"simulation.duration": 1.0 if quick else 2.0, "simulation.seed": seed})
    sim = job.simulate()
    sensors, forces, dt = job.sensors, job.forces, job.dt
    levels = dict(model_error_cov=job.model_error_cov, force_increment_cov=job.force_increment_cov,
                  noise_cov=job.noise_cov(sim))
    progress = Progress(NAME, 3)

    progress.step("the log-likelihood against the stiffness factor")
    base = Filter(job.structure, [sensors], forces, dt, **levels)
    setups = [base.with_structure(job.structure.scaled(float(f))) for f in FACTORS]
    ll = steady_logliks(np.stack([s.A_a for s in setups]), np.stack([s.G_a[0] for s in setups]),
                        np.stack([s.Q_a for s in setups]), np.stack([s.R[0] for s in setups]), sim.measurements)
    scan = pd.DataFrame({"stiffness_factor": FACTORS, "loglik": ll})

    progress.step("calibration of the stiffness factor")
    given = job.filter_model()
    fit = calibrate(given, sensors, forces, sim.measurements, dt, parameters=["stiffness_factor"], **levels)
    calibrated = fit.apply(given, sensors, **levels)[0]
    fitted_factor = job.stiffness_factor * fit.multipliers["stiffness_factor"]

    progress.step("filtered against smoothed")
    rows, estimates = [], {}
    for model_name, model, factor in (("as given", given, job.stiffness_factor),
                                      ("calibrated", calibrated, fitted_factor)):
        for smoothed in (False, True):
            est = estimate(model, sensors, forces, sim.measurements, dt, steady=True, smooth=smoothed, **levels)
            estimates[model_name, smoothed] = est
            gauges = [d["consistency"] for d in est.diagnostics() if d["channel"].startswith("strain")]
            row = {"model": model_name, "stiffness_factor": factor, "estimator": "smoothed" if smoothed else "filtered",
                   "loglik": est.loglik, "force_rms_error_N": float(np.mean(rms_error(est.forces, sim.loads))),
                   "gauge_consistency_min": min(gauges), "gauge_consistency_max": max(gauges)}
            if smoothed:       # how well the bands fit the errors: RMS of error / std (1 when they are right)
                z = (est.forces - sim.loads)[100:-100] / est.force_std[100:-100]
                row["error_over_std_rms"] = float(np.mean(np.sqrt(np.mean(z ** 2, axis=0))))
            rows.append(row)
    summary = pd.DataFrame(rows)
    files = {"table": os.path.join(out, f"{NAME}.csv"), "summary": os.path.join(out, f"{NAME}_summary.csv")}
    write_csv(scan, files["table"])
    write_csv(summary, files["summary"])
    log.info(f"S17 case 4: the log-likelihood of the record against the filter's stiffness factor\n"
             f"{scan.to_string(index=False, float_format=lambda v: f'{v:.4g}')}")
    log.info(f"calibrated: stiffness factor {job.stiffness_factor:g} -> {fitted_factor:.5f} (standard error "
             f"{fit.std_errors['stiffness_factor']:.2g}), log-likelihood {fit.loglik_before:.4g} -> "
             f"{fit.loglik_after:.4g}, {fit.seconds:.2f} s")
    log.info(summary.round(4).to_string(index=False))
    try:                      # the figures last: a figure that fails loses no number
        _figures(scan, fitted_factor, job.stiffness_factor, estimates, sim, job, out, files)
    except Exception as exc:  # noqa: BLE001 -- a figure is a warning, never a lost run
        log.warning(f"{NAME}: the figures failed ({type(exc).__name__}: {exc}); the tables are written")
    return StudyResult(NAME, scan, summary, files, {"fit": fit, "estimates": estimates})


def _figures(scan, fitted, given, estimates, sim, job, out, files):
    from core_akf.figures import subplots

    fig, ax = subplots(figsize=(6.5, 3.4))
    ax.plot(scan["stiffness_factor"], scan["loglik"], "o-", color="tab:blue", ms=4)
    ax.axvline(1.0, color="k", ls="--", lw=0.9, label="the truss (1.00)")
    ax.axvline(given, color="tab:orange", lw=1.2, label=f"the job's model ({given:g})")
    ax.axvline(fitted, color="tab:red", ls=":", lw=1.5, label=f"calibrated ({fitted:.4f})")
    ax.set_xlabel("filter's stiffness factor (relative to the truss)")
    ax.set_ylabel("log-likelihood of the record")
    ax.set_title("S17 case 4: the record says which model made it", fontsize=9)
    ax.legend(fontsize=7)
    save(fig, os.path.join(out, "likelihood.png"), files, "likelihood_figure")

    j = 2                                                     # force 3 (8:y): a slow half-sine and noise
    label = "{}:{}".format(*job.forces[j])
    fig, axes = subplots(2, 1, figsize=(9, 5.2), sharex=True)
    t = estimates["calibrated", True].time
    for ax, name in zip(axes, ("as given", "calibrated")):
        f, s = estimates[name, False], estimates[name, True]
        band = 2 * s.force_std[:, j]
        ax.fill_between(t, (s.forces[:, j] - band) / 1e3, (s.forces[:, j] + band) / 1e3, color="tab:red", alpha=0.35,
                        lw=0, label="smoothed ±2σ")
        ax.plot(t, f.forces[:, j] / 1e3, color="tab:blue", lw=0.6, label="filtered")
        ax.plot(t, s.forces[:, j] / 1e3, color="tab:red", lw=0.8, label="smoothed")
        ax.plot(t, sim.loads[:, j] / 1e3, "k--", lw=0.8, label="true")
        err = [float(np.sqrt(np.mean((e.forces[:, j] - sim.loads[:, j]) ** 2))) for e in (f, s)]
        ax.set_title(f"model {name}: force {label}, RMS error filtered {err[0]:.0f} N, smoothed {err[1]:.0f} N",
                     fontsize=8)
        ax.set_ylabel("force (kN)")
        window = (t >= 0.94) & (t <= 0.98)           # 40 ms: the bands are tens of newtons wide
        shown = np.concatenate([x[window, j] for x in (f.forces, s.forces, sim.loads)]) / 1e3
        pad = 0.1 * np.ptp(shown)
        ax.set_xlim(0.94, 0.98)
        ax.set_ylim(shown.min() - pad, shown.max() + pad)
    axes[0].legend(fontsize=7, ncol=4, loc="upper right")
    axes[1].set_xlabel("time (s)")
    save(fig, os.path.join(out, "smoothed.png"), files, "smoothed_figure")
