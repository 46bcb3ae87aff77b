"""``[filter] calibrate`` of a job: the record that calibrates, the fit
(:func:`core_akf.calibration.calibrate`) and its report in the job's own terms."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

#: steps of a measured record that calibrate the filter without ``[filter] calibrate_window``, at
#: most (the estimate's longest chunk: one read of the record)
CALIBRATION_STEPS = 65536
#: without ``[filter] calibrate_window``, the window holds about this many steps x (filter states)^2:
#: each of the fit's few hundred filters costs in proportion to it (about 0.3 s at 2e8 on 2 cores)
CALIBRATION_BUDGET = 2e8
#: ... but never fewer than this many periods of the model's first mode (nor 2048 steps)
CALIBRATION_PERIODS = 50


def calibration_steps(job, model):
    """The steps of a measured record that calibrate the filter: ``[filter] calibrate_window``, or
    the rule without it -- :data:`CALIBRATION_BUDGET` over the squared states of the filter the fit
    runs on (its modes below 3x Nyquist, :func:`core_akf.defaults.band_modes`, and the force
    states), at least :data:`CALIBRATION_PERIODS` periods of the first mode and 2048 steps, at
    most :data:`CALIBRATION_STEPS`."""
    from core_akf.defaults import band_modes

    if job.calibrate_window is not None:
        return max(2, int(round(job.calibrate_window / job.dt)))
    modes = model.n if job.n_modes is not None else band_modes(model, job.dt, any(s.kind == "acc" for s in job.sensors))
    states = 2 * modes + job.force_model.n_states(len(job.forces))
    floor = max(2048, int(CALIBRATION_PERIODS / (float(model.frequencies(1)[0]) * job.dt)))
    return int(min(CALIBRATION_STEPS, max(floor, CALIBRATION_BUDGET / states ** 2)))


def calibration_record(job, record, model):
    """The part of a measured record that calibrates the filter: its first
    :func:`calibration_steps`."""
    return next(iter(record.chunks(min(calibration_steps(job, model), record.n_steps))))[1]


#: the periods of the model's first mode a record must hold for its modal analysis
MIN_PERIODS = 20.0
#: a calibrated frequency this many OMA standard errors from the identified one is named in a warning
OMA_SIGMAS = 3.0
#: the record is cut into this many pieces for the OMA frequencies' standard errors
OMA_PIECES = 4


def identify_modes(job, model, Y, source, block_rows=None, max_order=None):
    """SSI-cov (:func:`core_akf.oma.ssi_cov`) of a job's accelerometer channels of the record ``Y``
    (its longest stretch without missing samples), paired with ``model``'s modes by MAC.

    Returns ``(result, paired, labels, Y_used, source, k)``: the identification, its modes with
    their model modes (:func:`core_akf.oma.pair_modes`), the channels, the samples used, where
    they came from, and the model modes compared.  Fewer than 2 accelerometers, or a record
    shorter than :data:`MIN_PERIODS` periods of the model's first mode, is an
    :class:`~core_akf.checks.AKFInputError`."""
    from core_akf.checks import AKFInputError
    from core_akf.oma import pair_modes, ssi_cov
    from core_akf.sensors import selection_matrices

    picked = [i for i, s in enumerate(job.sensors) if s.kind == "acc"]
    if len(picked) < 2:
        raise AKFInputError(f"operational modal analysis needs at least 2 accelerometers; the job has {len(picked)} "
                            f"({', '.join(s.label for s in job.sensors)})")
    labels = [job.sensors[i].label for i in picked]
    Y = np.asarray(Y, float)[:, picked]
    seen = np.all(np.isfinite(Y), axis=1)
    if not seen.any():
        raise AKFInputError(f"{source}: no step where all of {', '.join(labels)} are observed: modal analysis needs a "
                            "stretch without missing samples")
    if not seen.all():                  # the longest stretch without a hole
        edges = np.flatnonzero(np.diff(np.r_[0, seen.astype(int), 0]))
        starts, ends = edges[::2], edges[1::2]
        j = int(np.argmax(ends - starts))
        Y = Y[starts[j]:ends[j]]
        source += f" (its longest stretch without missing samples: steps {starts[j]}-{ends[j] - 1})"
    first = float(model.frequencies(1)[0])
    if Y.shape[0] * job.dt * first < MIN_PERIODS:
        raise AKFInputError(f"{source} holds {Y.shape[0] * job.dt:.4g} s, {Y.shape[0] * job.dt * first:.3g} periods "
                            f"of the model's first mode ({first:.4g} Hz): modal analysis needs at least "
                            f"{MIN_PERIODS:g} ({MIN_PERIODS / first:.4g} s)")
    res = ssi_cov(Y, job.dt, channels=labels, block_rows=block_rows, max_order=max_order, min_periods=MIN_PERIODS)
    k = min(model.n, max(12, 2 * len(res.modes)))
    shapes = (selection_matrices(model, [job.sensors[i] for i in picked])["acc"] @ model.modes(k)).T
    return res, pair_modes(res, model.frequencies(k), shapes), labels, Y, source, k


def oma_frequencies(job, model, Y, modes):
    """The identified frequency of each of ``modes`` (1-based, of ``model``) and its standard
    error: SSI-cov of the whole record, and the spread over :data:`OMA_PIECES` pieces of it
    (each long enough; else halves) divided by the square root of their number.

    Returns ``{mode: (frequency_hz, std_error_hz)}`` for the modes identified and paired (the
    error NaN when fewer than two pieces found the mode).  Raises
    :class:`~core_akf.checks.AKFInputError` where no modal analysis can run."""
    from core_akf.checks import AKFInputError

    _, paired, _, Y_used, source, _ = identify_modes(job, model, Y, "the calibration record")
    found = {}
    for r in paired.itertuples():
        if r.model_mode is not None and r.model_mode == r.model_mode and int(r.model_mode) in modes:
            found.setdefault(int(r.model_mode), float(r.frequency_hz))
    pieces = {}
    for n in (OMA_PIECES, 2):
        step = Y_used.shape[0] // n
        try:
            for i in range(n):
                part = identify_modes(job, model, Y_used[i * step:(i + 1) * step], source)[1]
                for r in part.itertuples():
                    if r.model_mode is not None and r.model_mode == r.model_mode and int(r.model_mode) in found:
                        pieces.setdefault(int(r.model_mode), []).append(float(r.frequency_hz))
            break
        except AKFInputError:
            pieces = {}
    return {k: (f, float(np.std(pieces[k], ddof=1) / np.sqrt(len(pieces[k]))) if len(pieces.get(k, [])) > 1
                else float("nan")) for k, f in sorted(found.items())}


def _oma_start(job, model, Y):
    """The OMA seed of ``frequencies``: the starting factors, the identified frequencies and a note
    (why none, when no modal analysis can run)."""
    import time

    from core_akf.calibration import REST_FREQUENCIES, calibration_modes
    from core_akf.checks import AKFInputError
    from core_akf.defaults import default

    modes = job.calibrate_modes or calibration_modes(model, job.dt)
    t0 = time.perf_counter()
    try:
        identified = oma_frequencies(job, model, Y, range(1, model.n + 1))
    except AKFInputError as exc:
        return {}, {}, f"no operational modal analysis to start from: {exc}"
    f_model = model.frequencies(max(identified, default=1))
    lo, hi = default("calibration_frequency_range")
    ratio = {k: f / f_model[k - 1] for k, (f, _) in identified.items() if lo <= f / f_model[k - 1] <= hi}
    start = {f"frequencies:{k}": ratio[k] for k in modes if k in ratio}
    others = [r for k, r in ratio.items() if k not in modes] or [ratio[k] for k in modes if k in ratio]
    if others:        # the other modes' factor: the median of the identified ones not listed (else of the listed)
        start[REST_FREQUENCIES] = float(np.median(others))
    missed = [k for k in modes if f"frequencies:{k}" not in start]
    note = (f"started from the frequencies of an operational modal analysis of the accelerometers "
            f"({time.perf_counter() - t0:.2f} s)" + (f"; modes {missed} were not identified (scanned)" if missed else ""))
    return start, {k: v for k, v in identified.items() if k in modes}, note


def _oma_check(identified, fitted_hz, modes):
    """The calibrated frequencies against the identified ones: per mode a row, and a warning for
    each mode more than :data:`OMA_SIGMAS` standard errors away."""
    rows, warnings = [], []
    for k in modes:
        if k not in identified:
            continue
        f, se = identified[k]
        z = (fitted_hz[k - 1] - f) / se if np.isfinite(se) and se > 0 else float("nan")
        rows.append({"mode": k, "oma_hz": f, "oma_std_error_hz": se, "calibrated_hz": float(fitted_hz[k - 1]), "z": z})
        if abs(z) > OMA_SIGMAS:
            warnings.append(f"mode {k}: calibrated at {fitted_hz[k - 1]:.4f} Hz, outside the operational modal "
                            f"analysis' {f:.4f} +- {OMA_SIGMAS:g} x {se:.2g} Hz ({z:+.1f} standard errors): one of the "
                            "two is wrong -- the calibration when the force prior cannot take the loads' spectrum near "
                            "the mode (a force_std or force_timescale held fixed, or another force_model) or the "
                            "model's mode shapes are off (frequencies keep them); the modal analysis when the loads "
                            "are not white near the mode (see oma_modes in akf oma)")
    return rows, warnings


class _CalibrationBar:
    """A tqdm bar on stderr over the filters a calibration runs (``progress`` of
    :func:`core_akf.calibration.calibrate`): its ETA from the first filters, the best
    log-likelihood so far as its postfix.  Shown once the fit runs longer than 1 s; ``--quiet``
    (``TQDM_DISABLE``) silences it."""

    def __enter__(self):
        from tqdm.auto import tqdm
        self._bar = tqdm(total=1, desc="calibrate", unit="filter", leave=False, delay=1.0)
        return self

    def update(self, evaluations, expected, best):
        bar = self._bar
        if expected != bar.total:
            bar.total = expected
        bar.update(evaluations - bar.n)
        if np.isfinite(best):
            bar.set_postfix_str(f"loglik {best:.6g}", refresh=False)

    def __exit__(self, *exc):
        self._bar.close()
        return False


def window_note(job, Y, record_steps):
    """What part of the record calibrates, in words naming ``[filter] calibrate_window``."""
    used = Y.shape[0]
    seconds = used * job.dt
    if record_steps is None:
        return f"calibrated on the whole simulated record ({used} steps, {seconds:.3g} s)"
    if used < record_steps:
        how = (f"[filter] calibrate_window = {job.calibrate_window:g} s" if job.calibrate_window is not None
               else "without [filter] calibrate_window: about a minute of fitting for this filter's size, at least "
                    f"{CALIBRATION_PERIODS} periods of the first mode, at most {CALIBRATION_STEPS} steps")
        return (f"calibrated on the record's first {seconds:.3g} s ({used} of {record_steps} steps; {how}); a "
                "longer window narrows the standard errors and costs time in proportion")
    return (f"calibrated on the whole record ({used} steps, {seconds:.3g} s); [filter] calibrate_window = "
            "SECONDS fits on its first part only, faster in proportion")


def calibrate_job(job, model, sensors, forces, Y, noise_cov, record_steps=None):
    """Fit ``[filter] calibrate`` of a job on the record ``Y`` (:func:`core_akf.calibration.calibrate`).

    Returns the fitted ``(model, Q, force_model, R)`` and the report of the fit (the ``calibration`` object of
    the metrics): the fitted values under their ``[filter]`` names (``stiffness_factor`` relative to
    ``[structure]``; ``noise_cov`` per sensor kind when the job gives it so, else per channel), the
    log-likelihood and the consistency per channel before and after, the standard errors
    (relative), the warnings of the fit and ``window``, what part of the record calibrated
    (``record_steps``: the steps of the whole measured record; None for a simulated one).  A full
    model (no ``[filter] n_modes``) is fitted on its modes below 3x the Nyquist frequency
    (``n_modes="band"`` of :func:`core_akf.calibration.calibrate`), said in ``model_note``."""
    from core_akf.calibration import REST_FREQUENCIES, calibrate

    Q, fm = job.model_error_cov, job.force_model
    start, identified, oma_note = _oma_start(job, model, Y) if "frequencies" in job.calibrate else ({}, {}, None)
    with _CalibrationBar() as bar:
        fit = calibrate(model, sensors, forces, Y, job.dt, parameters=job.calibrate, model_error_cov=Q,
                        force_model=fm, noise_cov=noise_cov, modes=job.calibrate_modes, dummy=job.dummy, start=start,
                        progress=bar.update, method=job.calibrate_method, held=job.calibrate_held,
                        n_modes="band" if job.n_modes is None else None)
    fitted = list(fit.apply(model, sensors, Q, fm.increment_cov, noise_cov))
    fitted[2] = fit.force_model if fm.stationary else replace(fm, increment_cov=fitted[2])

    report = {"parameters": list(job.calibrate), "record_steps": int(Y.shape[0]),
              "window": window_note(job, Y, record_steps)}
    if fit.filter_modes is not None:
        report["model_note"] = (f"fitted on the lowest {fit.filter_modes} of the model's {model.n} modes (those below 3x "
                                "the Nyquist frequency, with a static correction and the dropped modes' noise); the "
                                "factors apply to the whole model")
    m = fit.multipliers
    if "stiffness_factor" in m:
        report["stiffness_factor"] = job.stiffness_factor * m["stiffness_factor"]
    if "frequencies" in job.calibrate:          # on top of the job's own factors
        # the rest factor is a stiffness factor of its square; the listed modes' factors are then relative to it
        rest = m.get(REST_FREQUENCIES, 1.0)
        if REST_FREQUENCIES in m:
            report["stiffness_factor"] = job.stiffness_factor * rest ** 2
        fitted_f = fit.values["frequency_factors"]
        given = job.frequency_factors + [1.0] * (len(fitted_f) - len(job.frequency_factors))
        report["frequency_factors"] = [float(g * (fitted_f[i] / rest if i < len(fitted_f) else 1.0))
                                       for i, g in enumerate(given)]
        report["frequencies_hz"] = fitted[0].frequencies(len(report["frequency_factors"])).tolist()
    if "damping" in m:
        ratio = np.asarray(fitted[0].damping, float)
        report["damping"] = float(ratio) if ratio.ndim == 0 else ratio.tolist()
    if any(p.startswith("noise_cov") for p in m):            # asked, or a held level learnt as well
        given = job.spec.filter.noise_cov
        if isinstance(given, dict) and "noise_cov" in fit.values and isinstance(fit.values["noise_cov"], dict):
            report["noise_cov"] = fit.values["noise_cov"]
        else:
            report["noise_cov"] = [float(v) for v in np.diag(fitted[3])]
    for name in ("force_increment_cov", "model_error_cov", "force_std", "force_timescale", "force_band"):
        if name in fit.values:          # asked, or fitted with the frequencies
            report[name] = fit.values[name]
    report |= fit.to_dict()
    if oma_note is not None:
        modes = sorted(int(n.split(":")[1]) for n in fit.multipliers
                       if n.startswith("frequencies:") and n != REST_FREQUENCIES)
        rows, warnings = _oma_check(identified, fitted[0].frequencies(max(modes)), modes)
        report["oma"] = {"note": oma_note, "modes": rows}
        report["warnings"] = report["warnings"] + warnings
    return (*fitted, report)
