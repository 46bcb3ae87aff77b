"""``[filter] calibrate`` of a job: the record that calibrates, the fit
(:func:`core_akf.calibration.calibrate`) and its report in the job's own terms."""
from __future__ import annotations

import numpy as np

from core_akf.forcemodels import ForceModel

#: steps of a measured record that calibrate the filter without ``[filter] calibrate_window``
#: (the estimate's longest chunk: one read of the record)
CALIBRATION_STEPS = 65536


def calibration_record(job, record):
    """The part of a measured record that calibrates the filter: its first ``[filter]
    calibrate_window`` seconds, or the whole record up to :data:`CALIBRATION_STEPS` steps."""
    steps = CALIBRATION_STEPS if job.calibrate_window is None else max(2, int(round(job.calibrate_window / job.dt)))
    return next(iter(record.chunks(min(steps, record.n_steps))))[1]


def calibrate_job(job, model, sensors, forces, Y, noise_cov):
    """Fit ``[filter] calibrate`` of a job on the record ``Y`` (:func:`core_akf.calibration.calibrate`).

    Returns the fitted ``(model, Q, force_model, R)`` and the report of the fit (the ``calibration`` object of
    the metrics): the fitted values under their ``[filter]`` names (``stiffness_factor`` relative to
    ``[structure]``; ``noise_cov`` per sensor kind when the job gives it so, else per channel), the
    log-likelihood and the consistency per channel before and after, the standard errors
    (relative) and the warnings of the fit."""
    from core_akf.calibration import calibrate

    Q, fm = job.model_error_cov, job.force_model
    fit = calibrate(model, sensors, forces, Y, job.dt, parameters=job.calibrate, model_error_cov=Q,
                    force_model=fm, noise_cov=noise_cov, modes=job.calibrate_modes, dummy=job.dummy)
    fitted = list(fit.apply(model, sensors, Q, fm.increment_cov, noise_cov))
    fitted[2] = fit.force_model if fm.stationary else ForceModel("random_walk", increment_cov=fitted[2])

    report = {"parameters": list(job.calibrate), "record_steps": int(Y.shape[0])}
    m = fit.multipliers
    if "stiffness_factor" in m:
        report["stiffness_factor"] = job.stiffness_factor * m["stiffness_factor"]
    if "frequencies" in job.calibrate:          # on top of the job's own factors
        fitted_f = fit.values["frequency_factors"]
        given = job.frequency_factors + [1.0] * (len(fitted_f) - len(job.frequency_factors))
        report["frequency_factors"] = [float(g * (fitted_f[i] if i < len(fitted_f) else 1.0))
                                       for i, g in enumerate(given)]
        report["frequencies_hz"] = fitted[0].frequencies(len(report["frequency_factors"])).tolist()
    if "damping" in m:
        ratio = np.asarray(fitted[0].damping, float)
        report["damping"] = float(ratio) if ratio.ndim == 0 else ratio.tolist()
    if any(p.startswith("noise_cov") for p in job.calibrate):
        given = job.spec.filter.noise_cov
        if isinstance(given, dict) and "noise_cov" in fit.values and isinstance(fit.values["noise_cov"], dict):
            report["noise_cov"] = fit.values["noise_cov"]
        else:
            report["noise_cov"] = [float(v) for v in np.diag(fitted[3])]
    for name in ("force_increment_cov", "model_error_cov", "force_std", "force_timescale"):
        if name in job.calibrate or f"{name}:forces" in job.calibrate:
            report[name] = fit.values[name]
    report |= fit.to_dict()
    return (*fitted, report)
