"""Accelerometer-only monitoring, worked on the ``s17-acc`` job (``akf study accelerations``): ten
accelerometers on the S17 truss, two zero-mean loads of 600 and 425 N RMS (band-limited to 200 Hz).

1. Detectability under each force model: the random walk is refused (accelerations do not see the
   static response), dummy displacements and the Matérn models are detectable.
2. The forces of: the random walk run anyway (time-varying, it drifts); the random walk with dummy
   displacements at the loaded joints; the Matérn-3/2 force model with the job's rough std and
   time scale, filtered and smoothed; and with both learnt by maximum likelihood.  Per estimator:
   the force error relative to the loads' RMS, the drift (error RMS of the last quarter over the
   second), the strain error, and for a smoothed estimate how well its bands fit the errors (the
   RMS of error over std; 1 when they are right) (figure ``accelerations.png``).
3. The log-likelihood and the force error against the Matérn time scale (figure
   ``timescale.png``): where the record's likelihood peaks, and where the force error is least.

Writes ``accelerations.csv`` (one row per estimator) and ``accelerations_timescale.csv`` (the
scan); the numbers are printed first, the figures drawn last.
"""
from __future__ import annotations

import logging
import os

import numpy as np

from core_akf.outputs import write_csv

from ..examples import example
from ._common import Progress, StudyResult, output_dir, save

log = logging.getLogger("akf")

NAME = "accelerations"
DESCRIPTION = "s17-acc: accelerometers only, random walk against dummy displacements and Matérn force models"
#: the Matérn time scales of the likelihood scan (s)
TIMESCALES = np.geomspace(5e-4, 3e-2, 13)


def _ratios(est, true):
    e = est.forces - true
    q = e.shape[0] // 4
    rel = np.sqrt(np.mean(e ** 2, axis=0)) / np.sqrt(np.mean(true ** 2, axis=0))
    drift = np.sqrt(np.mean(e[3 * q:] ** 2, axis=0)) / np.sqrt(np.mean(e[q:2 * q] ** 2, axis=0))
    return rel, drift


def run(out=None, quick=False, seed=0):
    """Run the worked example (``quick``: 1 s of record instead of 2), write the tables, print
    them, then draw the figures."""
    import pandas as pd

    from core_akf.calibration import calibrate
    from core_akf.filter import estimate
    from core_akf.forcemodels import DummyMeasurements, ForceModel
    from core_akf.metrics import average_strain_error
    from core_akf.statespace import detectability, static_gain

    out = output_dir(NAME, out)
    job = example("s17-acc", overrides={"simulation.duration": 1.0 if quick else 2.0, "simulation.seed": seed})
    sim = job.simulate()
    sensors, forces, dt, model = job.sensors, job.forces, job.dt, job.filter_model()
    R = job.noise_cov(sim)
    progress = Progress(NAME, 3)

    progress.step("detectability under each force model")
    disp = [f"disp:{node}:{d}" for node, d in forces]
    rms = np.sqrt(np.mean(sim.loads ** 2, axis=0))
    static_std = float(np.mean(np.abs(np.diag(static_gain(model, disp, forces).gain)) * rms))
    dummy = DummyMeasurements(disp, static_std ** 2)
    verdicts = {"random walk": detectability(model, sensors, forces),
                "random walk + dummy displacements": detectability(model, list(sensors) + disp, forces),
                "Matérn-3/2": detectability(model, sensors, forces, job.force_model)}

    progress.step("the forces of each estimator")
    fit = calibrate(model, sensors, forces, sim.measurements, dt, parameters=["force_std", "force_timescale"],
                    model_error_cov=job.model_error_cov, noise_cov=R,
                    force_model=ForceModel("matern32", std=300.0, timescale=0.01))
    runs = {"random walk (drifts)": dict(force_increment_cov=1e5, steady=False, allow_undetectable=True),
            "random walk + dummy displacements": dict(force_increment_cov=1e5, dummy=dummy),
            "Matérn-3/2, given, filtered": dict(force_model=job.force_model),
            "Matérn-3/2, given, smoothed": dict(force_model=job.force_model, smooth=True),
            "Matérn-3/2, ML, smoothed": dict(force_model=fit.force_model, smooth=True)}
    estimates, rows = {}, []
    for name, kw in runs.items():
        est = estimate(model, sensors, forces, sim.measurements, dt, model_error_cov=job.model_error_cov,
                       noise_cov=R, **kw)
        estimates[name] = est
        rel, drift = _ratios(est, sim.loads)
        rows.append({"estimator": name, **{f"force_error_rel_{a}:{b}": float(r) for (a, b), r in zip(forces, rel)},
                     "drift_max": float(drift.max()),
                     "strain_error_microstrain": float(average_strain_error(est.strains, sim.strains)) * 1e6,
                     "loglik": est.loglik,
                     # how well the smoother's bands fit the errors: RMS of error / std (1 when they are right)
                     "error_over_std_rms": float(np.mean(np.sqrt(np.mean(((est.forces - sim.loads) / est.force_std)
                                                                         [100:-100] ** 2, axis=0))))
                     if est.force_std is not None else float("nan")})
    summary = pd.DataFrame(rows)

    progress.step("the log-likelihood against the time scale")
    scan = []
    for ell in TIMESCALES:
        fm = ForceModel("matern32", std=fit.force_model.std, timescale=float(ell))
        est = estimate(model, sensors, forces, sim.measurements, dt, model_error_cov=job.model_error_cov, noise_cov=R,
                       force_model=fm)
        scan.append({"timescale_s": float(ell), "loglik": est.loglik,
                     "force_error_rel": float(np.mean(_ratios(est, sim.loads)[0]))})
    scan = pd.DataFrame(scan)
    files = {"table": os.path.join(out, f"{NAME}.csv"), "scan": os.path.join(out, f"{NAME}_timescale.csv")}
    write_csv(summary, files["table"])
    write_csv(scan, files["scan"])
    for name, report in verdicts.items():
        log.info(f"{name}: {'detectable' if report.detectable else 'NOT detectable'}")
    log.info(f"maximum likelihood: force_std {fit.values['force_std']:.4g} N, force_timescale "
             f"{1e3 * fit.values['force_timescale']:.3g} ms ({fit.seconds:.2f} s)")
    log.info(summary.round(4).to_string(index=False))
    log.info(scan.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    try:                      # the figures last: a figure that fails loses no number
        _figures(estimates, scan, fit, job, sim, out, files)
    except Exception as exc:  # noqa: BLE001 -- a figure is a warning, never a lost run
        log.warning(f"{NAME}: the figures failed ({type(exc).__name__}: {exc}); the tables are written")
    return StudyResult(NAME, scan, summary, files, {"fit": fit, "estimates": estimates, "verdicts": verdicts})


def _figures(estimates, scan, fit, job, sim, out, files):
    from core_akf.figures import subplots

    j = 0
    label = "{}:{}".format(*job.forces[j])
    fig, axes = subplots(3, 1, figsize=(9, 7), sharex=True)
    t = estimates["Matérn-3/2, given, smoothed"].time
    for ax, name in zip(axes, ("random walk (drifts)", "random walk + dummy displacements", "Matérn-3/2, given, smoothed")):
        est = estimates[name]
        if est.force_std is not None:
            band = 2 * est.force_std[:, j]
            ax.fill_between(t, est.forces[:, j] - band, est.forces[:, j] + band, color="tab:red", alpha=0.3, lw=0,
                            label="±2σ")
        ax.plot(t, sim.loads[:, j], "k", lw=0.5, label="true")
        ax.plot(t, est.forces[:, j], color="tab:red", lw=0.6, label="estimated")
        err = float(np.sqrt(np.mean((est.forces[:, j] - sim.loads[:, j]) ** 2)))
        ax.set_title(f"{name}: force {label}, RMS error {err:.0f} N", fontsize=8)
        ax.set_ylabel("force (N)")
        lim = 1.8 * np.abs(sim.loads[:, j]).max()
        ax.set_ylim(-lim, lim)
        ax.set_xlim(0.8, 0.95)            # 150 ms: the loads' peaks and the band can be told apart
    axes[0].legend(fontsize=7, ncol=3, loc="upper right")
    axes[-1].set_xlabel("time (s)")
    save(fig, os.path.join(out, "accelerations.png"), files, "accelerations_figure")

    fig, ax = subplots(figsize=(6.5, 3.4))
    ax.semilogx(1e3 * scan["timescale_s"], scan["loglik"], "o-", color="tab:blue", ms=4)
    ax.set_xlabel("Matérn-3/2 time scale (ms)")
    ax.set_ylabel("log-likelihood of the record", color="tab:blue")
    right = ax.twinx()
    right.semilogx(1e3 * scan["timescale_s"], scan["force_error_rel"], "s--", color="tab:red", ms=4)
    right.set_ylabel("force error / load RMS", color="tab:red")
    ax.axvline(1e3 * fit.values["force_timescale"], color="k", ls=":", lw=1, label="maximum likelihood")
    ax.legend(fontsize=7, loc="lower center")
    ax.set_title(f"s17-acc: the time scale (std {np.mean(fit.values['force_std']):.0f} N, the ML one)", fontsize=9)
    save(fig, os.path.join(out, "timescale.png"), files, "timescale_figure")
