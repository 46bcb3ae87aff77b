"""Locate jobs: impact localisation from a job file (measured data), and the output files.

A locate job (TOML)::

    name = "truss-impact"
    dt = 0.001                      # s; must match the data's sampling interval
    sensors = ["strain:5", "strain:9", "acc:6:y"]

    [structure]
    model = "s17_truss"

    [locate]
    n_ad = 4                        # AD (held-back) sensors per role split
    ad_kinds = ["strain"]           # kinds that may be AD
    direction = "y"                 # force direction at the candidates
    candidates = [2, 3, 4]          # optional: node ids (default every free node)
    max_splits = 50                 # optional cap (seeded sample)
    tune = true                     # covariance tuning: true or "ga" (the paper's GA), "ml" (maximum likelihood), false
    n_modes = "auto"                # filter reduction for scan/tuning ("auto", an int, or "full")

    [locate.covariances]            # optional assumed levels (default: from the data)
    model_error_cov = 1e-16
    force_increment_cov = 1e6
    noise_cov = {strain = 1e-13, acc = 1e-3}

    [locate.tuning]                 # optional GA settings
    population = 12
    generations = 8

    [measurements]
    file = "impact.csv"             # time column + one column per sensor label
"""
from __future__ import annotations

import logging
import os

import numpy as np

from core_akf.checks import AKFInputError
from core_akf.outputs import confined, write_csv

from .figures import draw, plot_events

log = logging.getLogger("akf")

def run_locate_job(job, n_jobs=1, seed=0, progress=False, tune=None, simulation=None):
    """Run a locate :class:`~akf.job.Job` (:func:`akf.job.load_job`); returns the
    :class:`~impactloc.locate.LocateResult`.

    ``simulation``: for a job with ``[simulation]``, the :class:`~core_akf.simulate.Simulation`
    already run from it (the truth a built-in example shows beside the result), so that it is not
    simulated twice; ``tune`` overrides ``[locate] tune`` (``--no-tune``: False, ``--tune``: "ga" or "ml")."""
    from impactloc.locate import locate
    from impactloc.scan import Covariances
    from impactloc.tuning import check_decades

    from .job import check_covariance_levels

    spec = job.spec
    sensors = job.sensors           # checked against the structure
    record_notes = []
    if spec.measurements is not None:
        record = job.open_record()
        Y = record.read()[1]
        record_notes = list(record.warnings) + record.rate_notes() + record.gap_notes()
    elif spec.simulation is not None:
        if spec.forces is None:
            raise AKFInputError("a simulated locate job needs forces = ['NODE:DIR'] (where the impact hits)")
        Y = (job.simulate() if simulation is None else simulation).measurements
    else:
        raise AKFInputError("the locate job needs a [measurements] section (or a [simulation] to try the method)")
    loc = spec.locate
    c = loc.covariances
    if c is not None:
        check_covariance_levels(c.model_error_cov, c.force_increment_cov, "[locate.covariances]")
    covariances = None if c is None else Covariances(c.model_error_cov, c.force_increment_cov, dict(c.noise_cov))
    force_model = job.force_model if job.force_model.stationary else None
    if force_model is not None and covariances is None:      # the Matérn std of [filter] starts the levels
        from impactloc.scan import default_covariances

        start = default_covariances(sensors, Y)
        covariances = Covariances(start.model_error, float(np.mean(np.asarray(force_model.std, float) ** 2)), start.noise)
    tuning = None if loc.tuning is None else loc.tuning.model_dump(exclude_none=True)
    if tuning and "decades" in tuning:
        check_decades(tuning["decades"], "[locate.tuning] decades")
    result = locate(job.structure, sensors, Y, job.dt, n_ad=loc.n_ad, direction=loc.direction,
                    ad_kinds=tuple(loc.ad_kinds or ["strain"]), candidates=loc.candidates, covariances=covariances,
                    tune=(True if loc.tune is None else loc.tune) if tune is None else tune, max_splits=loc.max_splits,
                    n_modes=job.n_modes, skip=loc.skip or 0.0, n_jobs=n_jobs, seed=seed, progress=progress,
                    tuning=tuning, force_model=force_model)
    result.record_notes = record_notes
    return result


def is_event_folder(job):
    """Whether a locate job's ``[measurements] file`` names many impact records (a folder or a glob
    pattern): then every file is one event (:func:`locate_events`)."""
    import glob

    f = job.spec.measurements.file if job.spec.measurements is not None else None
    return isinstance(f, str) and (os.path.isdir(f) or glob.has_magic(f))


def locate_events(job, out, n_jobs=1, seed=0, progress=False, tune=None, plot=True):
    """Locate the impact of every file of a folder (or glob pattern) of impact records.

    Each event is located as a job of its own (:func:`run_locate_job`) and its ranking and force
    history are written to ``out/events/<file name>/``.  One table, ``events.csv``, has a row per
    file: ``file`` (relative to the output folder when it can be), ``node``, ``direction``,
    ``confidence``, ``margin``, ``peak_force_N``, ``time_of_peak_s`` (from the record's start),
    ``duration_s``, ``impulse_Ns``, ``warnings`` and ``error`` (why a file could not be used; the
    others go on).  ``events.png`` draws the located
    impacts on the structure.  Returns ``(DataFrame, {name: path})``."""
    import pandas as pd

    from core_akf.io import record_files

    files = record_files(job.spec.measurements.file)
    rows, written = [], {}
    os.makedirs(confined(out), exist_ok=True)
    columns = ["file", "node", "direction", "confidence", "margin", "peak_force_N", "time_of_peak_s", "duration_s",
               "impulse_Ns", "warnings", "error"]
    written["events"] = os.path.join(out, "events.csv")
    for i, path in enumerate(files):
        shown = printable_path(_relative(path, out))
        name = os.path.splitext(os.path.basename(shown))[0]
        row = {"file": shown}
        try:
            result = run_locate_job(job.with_record(path), n_jobs=n_jobs, seed=seed, progress=False, tune=tune)
            d = result.to_dict()
            row |= {"node": d["identified"], "direction": d["direction"], "confidence": d["confidence"],
                    "margin": d["margin"], "peak_force_N": d["peak_force"], "time_of_peak_s": d["time_of_peak"],
                    "duration_s": d["duration"], "impulse_Ns": d["impulse"], "warnings": "; ".join(d["warnings"]),
                    "error": ""}
            write_outputs(result, os.path.join(out, "events", name), plot=False)
        except Exception as exc:  # noqa: BLE001 -- one event that fails must not lose the others
            message = str(exc) if isinstance(exc, AKFInputError) else f"{type(exc).__name__}: {exc}"
            row = {"file": shown, "error": message}
            if progress:
                log.info(f"  [{i + 1}/{len(files)}] {name}: not located: {message}")
        else:
            if progress:
                log.info(f"  [{i + 1}/{len(files)}] {name}: node {row['node']} ({row['direction']}), confidence "
                      f"{row['confidence']:.2f}, peak {row['peak_force_N'] / 1e3:.3f} kN at {row['time_of_peak_s']:.4f} s")
                for w in d["warnings"]:
                    log.warning(f"      WARNING: {w}")
        rows.append(row)
        write_csv(pd.DataFrame(rows, columns=columns), written["events"])   # after every event: nothing located is lost
    frame = pd.DataFrame(rows, columns=columns)
    written["event_folders"] = os.path.join(out, "events")
    if plot and frame["node"].notna().any():
        notes = []
        draw(written, "events_figure", notes, plot_events, job.structure, frame,
             os.path.join(out, "events.png"), job.name)
        if notes and progress:
            log.warning(f"  WARNING: {notes[0]}")
    return frame, written


def _relative(path, out):
    """``path`` relative to the output folder ``out`` (a table that moves with its records), or as
    given where it cannot be (another drive)."""
    try:
        return os.path.relpath(os.path.abspath(path), os.path.abspath(out))
    except ValueError:
        return path


def printable_path(path):
    """A path as text that any terminal and any UTF-8 file can hold: bytes of a file name that are
    not valid UTF-8 are shown as ``\\xNN`` escapes."""
    return os.fsencode(path).decode("utf-8", "backslashreplace")


def write_outputs(result, out, scenario=None, plot=True, notes=None):
    """Write ranking.csv, scan.csv, force.csv, response.csv, tuning.csv and then the figures; a
    figure that fails is a note in ``notes`` (default ``result.warnings``).  Returns {name: path}."""
    import pandas as pd

    from impactloc.plots import plot_locate

    os.makedirs(confined(out), exist_ok=True)
    files = {"ranking": os.path.join(out, "ranking.csv"), "scan": os.path.join(out, "scan.csv"),
             "force_history": os.path.join(out, "force.csv")}
    write_csv(result.scan.summary, files["ranking"])
    write_csv(result.scan.frame, files["scan"])
    est = result.reconstruction.estimate
    cols = {"time": est.time, "force_assumed": result.initial.force, "force_tuned": result.reconstruction.force}
    if scenario is not None:
        cols["force_true"] = scenario.true_force
    write_csv(pd.DataFrame(cols), files["force_history"])
    files["response"] = os.path.join(out, "response.csv")   # strain at every member / node component
    strains = pd.DataFrame(est.strains, columns=est.structure.strain_labels)
    strains.insert(0, "time", est.time)
    write_csv(strains, files["response"], float_format="%.6e")
    if result.tuning is not None:
        files["tuning"] = os.path.join(out, "tuning.csv")
        write_csv(result.tuning.logbook, files["tuning"])
    if plot:            # after the results: a figure that fails is a note
        try:
            files.update(plot_locate(result, out, true_force=None if scenario is None else scenario.true_force,
                                     true_strains=None if scenario is None else scenario.simulation.strains))
        except Exception as exc:  # noqa: BLE001 -- any failure of a figure is only a warning
            (notes if notes is not None else result.warnings).append(
                f"the locate figures were not drawn ({type(exc).__name__}: {exc}); the result files are complete")
    return files


