"""Measured records estimated in constant memory: read in chunks, filtered with the state carried
over, the results written as they come, and a checkpoint after every chunk so that an interrupted
run continues where it ended (``akf estimate JOB --resume``).

The time series go to ``timeseries.csv`` (appended) or ``timeseries.parquet`` (a folder of one
Parquet file per chunk: a dataset that ``pandas.read_parquet`` reads whole), tidy as for simulated
jobs: one row per time step and channel.  The checkpoint (``.akf-resume.npz``) holds the filter's
state, the running diagnostics, how much of the output is written and a fingerprint of the job
and its files; a resumed run cuts the output back to the checkpoint and goes on from there.
"""
from __future__ import annotations

import copy
import json
import os
from dataclasses import dataclass, field

import numpy as np

from core_akf.defaults import default
from core_akf.diagnostics import CONSISTENCY_LIMIT, RunningDiagnostics, scale_check, warnings_for
from core_akf.exceptions import AKFInputError
from core_akf.outputs import atomic_path, confined, write_csv
from core_akf.sensors import as_layout, parse_force_locations, selection_matrices
from core_akf.streaming import CheckpointError, Estimator

from .jobs import METRIC_UNITS, build_structure, open_record, summary_frame
from .plots import plot_estimate, plot_sensors
from .schema import parse_job
from .writers import draw

#: steps per chunk at most, unless the job says ``[measurements] chunk`` (seconds)
DEFAULT_CHUNK_STEPS = 65536
#: bytes a chunk may hold (states, their transforms, channels, output rows)
CHUNK_BYTES = 256e6


def default_chunk(n_states, n_channels, n_outputs):
    """Steps per chunk: :data:`DEFAULT_CHUNK_STEPS`, fewer for a large model so that a chunk holds
    about :data:`CHUNK_BYTES` (about four copies of the augmented states of ``n_states``, the
    channels and a tidy output row of six columns per written channel), at least 1024."""
    per_step = 8 * (4 * n_states + 4 * n_channels + 6 * n_outputs)
    return int(min(DEFAULT_CHUNK_STEPS, max(1024, CHUNK_BYTES // per_step)))
#: points per channel kept for the figure (the record decimated to at most this)
_PLOT_POINTS = 20000
CHECKPOINT = ".akf-resume.npz"


@dataclass
class StreamResult:
    """What :func:`stream_job` did: the metrics (as :class:`akf.jobs.JobResult`), the files written,
    the record's channels and the steps done in this call."""

    job: dict
    metrics: dict
    files: dict
    channels: list
    notes: list = field(default_factory=list)
    resumed_at: int = 0
    complete: bool = True


class _Writer:
    """Tidy rows appended chunk by chunk, to CSV or to Parquet parts; cut back on resume."""

    def __init__(self, out, fmt):
        self.fmt = fmt
        self.path = os.path.join(out, "timeseries.csv" if fmt == "csv" else "timeseries.parquet")
        self.position = 0        # CSV: bytes written; Parquet: parts written

    def start(self, position=0):
        """Begin anew (0) or cut the output back to a checkpoint's ``position``.  Nothing is
        written or deleted through a symbolic link that leads out of the output folder."""
        confined(self.path)
        if self.fmt == "csv":
            if position == 0:
                with open(self.path, "w") as fh:
                    fh.write("time,quantity,channel,unit,estimated,reference\n")
                position = os.path.getsize(self.path)
            else:
                if not os.path.exists(self.path) or os.path.getsize(self.path) < position:
                    raise CheckpointError(f"{self.path} is shorter than the checkpoint says: start the run anew")
                with open(self.path, "r+b") as fh:
                    fh.truncate(position)
        else:
            if os.path.isfile(self.path):
                os.remove(self.path)
            os.makedirs(self.path, exist_ok=True)
            for name in os.listdir(self.path):
                if name.startswith("part-") and (position == 0 or int(name[5:10]) >= position):
                    os.remove(os.path.join(self.path, name))
            if position and not os.path.exists(os.path.join(self.path, f"part-{position - 1:05d}.parquet")):
                raise CheckpointError(f"{self.path} lacks parts the checkpoint says were written: start the run anew")
        self.position = position

    def write(self, frame):
        confined(self.path)
        if self.fmt == "csv":
            with open(self.path, "a") as fh:
                frame.to_csv(fh, header=False, index=False, float_format="%.17g")
                fh.flush()
                os.fsync(fh.fileno())
            self.position = os.path.getsize(self.path)
        else:
            with atomic_path(os.path.join(self.path, f"part-{self.position:05d}.parquet")) as tmp:
                frame.to_parquet(tmp, index=False)
            self.position += 1


def _fingerprint(job, record, options):
    """What shapes a run's outputs, for its checkpoint: ``(spec, files)`` as canonical JSON -- the
    job without its free-text description plus the command's ``options`` (filter form, ...),
    and the record's files (names, sizes, times of change)."""
    spec = copy.deepcopy(job)
    spec.pop("description", None)
    spec["command-line options"] = options
    files = [[os.path.abspath(f), os.path.getsize(f), os.path.getmtime(f)] for f in record.files]
    return json.dumps(spec, sort_keys=True, default=str), json.dumps(files, default=str)


def _flat(value, prefix=()):
    """A nested dict as ``{(table, ..., key): value}``."""
    if isinstance(value, dict):
        out = {}
        for k, v in value.items():
            out.update(_flat(v, prefix + (str(k),)))
        return out
    return {prefix: value}


def _changed_keys(old, new):
    """The job keys that differ between two canonical JSON specs, as ``[table] key`` strings."""
    a, b = _flat(json.loads(old)), _flat(json.loads(new))
    keys = sorted(k for k in set(a) | set(b) if a.get(k, "<absent>") != b.get(k, "<absent>"))
    return [(f"[{'.'.join(k[:-1])}] " if len(k) > 1 else "") + k[-1] for k in keys]


#: what a checkpoint of :func:`stream_job` holds besides the filter's and the diagnostics' state
_CHECKPOINT_KEYS = ("job", "files", "next_step", "position", "chunk", "plot_t", "plot_f", "plot_y", "plot_p")


def _load_checkpoint(path):
    """A checkpoint's arrays, or a :class:`CheckpointError` that says what is wrong with the file:
    truncated, not a checkpoint of ``akf estimate``, or holding values that are not finite."""
    import zipfile

    try:
        with np.load(path, allow_pickle=False) as data:
            saved = {k: data[k] for k in data.files}
    except (zipfile.BadZipFile, EOFError, OSError, ValueError) as exc:
        raise CheckpointError(f"the checkpoint {path} is truncated or not a checkpoint of akf estimate "
                              f"({type(exc).__name__}: {exc}); start anew with --overwrite") from None
    missing = [k for k in _CHECKPOINT_KEYS if k not in saved]
    if missing:
        what = "was written by an earlier version of akf" if "next_step" in saved else "is not a checkpoint of akf estimate"
        raise CheckpointError(f"{path} {what} (it lacks {', '.join(missing)}); start anew with --overwrite")
    for k, v in saved.items():
        if v.dtype.kind == "f" and k not in ("z",) and not np.all(np.isfinite(v)):
            raise CheckpointError(f"the checkpoint {path} holds NaN or infinite values in {k!r}: it cannot be "
                                  "continued; start anew with --overwrite")
    return saved


def _frame(est, strain_index, strain_labels, strain_rows):
    """Tidy rows of one chunk: forces, then the chosen strains (text columns as categoricals: the
    same rows, built and written ten times faster than strings)."""
    import pandas as pd

    t = est.time
    n = t.size
    names = [f"{node}:{d}" for node, d in est.force_locations]
    blocks = [est.forces] + ([est.states[:, :est.structure.n] @ strain_rows.T] if len(strain_index) else [])
    values = np.hstack(blocks)
    channels = names + [strain_labels[i] for i in strain_index]
    is_strain = np.repeat(np.arange(len(channels)) >= len(names), n).astype(np.int8)

    def column(codes, categories):
        return pd.Categorical.from_codes(codes, categories=categories)
    return pd.DataFrame({"time": np.tile(t, len(channels)),
                         "quantity": column(is_strain, ["force", "strain"]),
                         "channel": column(np.repeat(np.arange(len(channels)), n), channels),
                         "unit": column(is_strain, ["N", "m/m"]),
                         "estimated": values.T.reshape(-1), "reference": np.full(n * len(channels), np.nan)})


def stream_job(job, out, *, resume=False, overwrite=False, allow_undetectable=None, steady=None, plot=True,
               progress=False, stop_after=None):
    """Estimate forces and strains for a job with ``[measurements]``, chunk by chunk, into ``out``.

    ``resume``: continue an interrupted run from its checkpoint in ``out``; it must have been
    written for the same job, options and data files (else a :class:`CheckpointError` names
    what changed).  Without it, an interrupted run's checkpoint in ``out`` is refused unless
    ``overwrite`` (start anew; a finished run leaves no checkpoint).  ``stop_after``: stop
    after this many chunks (as if interrupted; for tests and for splitting work).  Returns a
    :class:`StreamResult`; its metrics have the keys of :attr:`akf.jobs.JobResult.metrics`.
    """

    job = copy.deepcopy(job)
    spec = parse_job(job, "estimate")
    if spec.measurements is None:
        raise AKFInputError("streamed estimation needs a [measurements] section")
    dt, filt = spec.dt, spec.filter
    structure = build_structure(job["structure"])
    sensors = as_layout(job["sensors"])
    selection_matrices(structure, sensors)
    forces = parse_force_locations(structure, job["forces"])
    record = open_record(spec.measurements, sensors)
    record.check_dt(dt)
    model = structure.scaled(default("stiffness_factor", filt.stiffness_factor))
    if filt.n_modes:
        model = model.reduce(filt.n_modes, static_correction=True)
    noise_cov = filt.noise_cov
    if noise_cov is None or isinstance(noise_cov, str):
        raise AKFInputError("measured data need the noise variances: [filter] noise_cov = {strain = ..., acc = ...} "
                            "(SI units squared) or one variance per sensor")
    estimator = Estimator(model, sensors, forces, dt, steady=filt.steady if steady is None else steady,
                          allow_undetectable=bool(filt.allow_undetectable if allow_undetectable is None
                                                  else allow_undetectable),
                          model_error_cov=default("model_error_cov", filt.model_error_cov),
                          force_increment_cov=default("force_increment_cov", filt.force_increment_cov),
                          noise_cov=noise_cov, t0=record.start)
    n_total = record.n_steps
    notes = []
    wanted = (spec.output.strains if spec.output is not None else None) or "all"
    labels = structure.strain_labels
    if wanted == "all":
        if structure.n_strain * n_total <= 2_000_000 or (spec.output is not None and spec.output.strains == "all"):
            strain_index = list(range(len(labels)))
        else:
            strain_index = []
            notes.append(f"strain histories not written ({structure.n_strain} channels x {n_total} steps); list the "
                         "channels you want in [output] strains")
    else:
        strain_index = structure.strain_label_index(wanted)
    strain_rows = model.strain_operator[strain_index]
    chunk = default_chunk(estimator.setup.A_a.shape[0], len(sensors), len(forces) + len(strain_index)) \
        if spec.measurements.chunk is None else max(1, int(round(spec.measurements.chunk / dt)))
    os.makedirs(confined(out), exist_ok=True)
    writer = _Writer(out, (spec.output.format if spec.output is not None else None) or "csv")
    diag = RunningDiagnostics(n_total)
    spec, data_files = _fingerprint(job, record, {"steady": steady, "allow_undetectable": allow_undetectable})
    checkpoint = os.path.join(out, CHECKPOINT)
    start = 0
    decimate = max(1, -(-n_total // _PLOT_POINTS))
    kept = {"t": [], "f": [], "y": [], "p": []}      # the record decimated for the figures
    if resume and overwrite:
        raise AKFInputError("--resume continues a run and --overwrite starts anew: give one of them")
    if not resume and os.path.lexists(checkpoint) and not overwrite:
        raise AKFInputError(f"{out} holds an interrupted run (its checkpoint {CHECKPOINT} and partial output): "
                            "continue it with --resume, or start anew with --overwrite")
    if resume:
        if not os.path.exists(checkpoint):
            raise AKFInputError(f"nothing to resume in {out}: no checkpoint {CHECKPOINT} (run without --resume)")
        saved = _load_checkpoint(checkpoint)
        if str(saved["job"]) != spec:
            raise CheckpointError(f"the job changed since the checkpoint in {out} was written ("
                                  + ", ".join(_changed_keys(str(saved["job"]), spec)) + "); resuming would mix two "
                                  "runs in one output: start anew with --overwrite, or undo the change")
        if str(saved["files"]) != data_files:
            raise CheckpointError(f"the data files changed since the checkpoint in {out} was written (names, sizes or "
                                  "times of change); start anew with --overwrite")
        if int(saved["chunk"]) != chunk:
            raise CheckpointError("the checkpoint was written with another chunk length; start anew with --overwrite")
        estimator.restore(saved)
        start = int(saved["next_step"])
        writer.start(int(saved["position"]))
        kept = {k: [saved[f"plot_{k}"]] for k in kept}
    else:
        writer.start(0)
    last = None
    done = 0
    progress_bar = _progress(progress, n_total, start)
    for step, Y in record.chunks(chunk, start):
        est = estimator.update(Y)
        if last is None and resume:
            try:
                diag.restore(saved, est)
            except (KeyError, ValueError) as exc:
                raise CheckpointError(f"the checkpoint {checkpoint} lacks the running diagnostics ({exc}); start anew "
                                      "with --overwrite") from None
        diag.update(est)
        last = est
        writer.write(_frame(est, strain_index, labels, strain_rows))
        sel = np.arange((-step) % decimate, est.forces.shape[0], decimate)
        kept["t"].append(est.time[sel])
        kept["f"].append(est.forces[sel])
        kept["y"].append(est.measurements[sel])
        kept["p"].append(est.predicted[sel])
        done += 1
        progress_bar(Y.shape[0])
        if step + Y.shape[0] < n_total:      # after the last chunk the summary follows: a resume redoes that chunk
            state = estimator.state() | diag.state() | {
                "next_step": np.array(step + Y.shape[0]), "position": np.array(writer.position),
                "job": np.array(spec), "files": np.array(data_files), "chunk": np.array(chunk)} | {
                f"plot_{k}": np.concatenate(v) if k == "t" else np.vstack(v) for k, v in kept.items()}
            with atomic_path(checkpoint) as tmp:
                with open(tmp, "wb") as fh:
                    np.savez(fh, **state)
            if stop_after is not None and done >= stop_after:
                notes.append(f"stopped after {done} chunk(s) at step {step + Y.shape[0]} of {n_total}; continue with "
                             "--resume")
                return StreamResult(job, {}, {"timeseries": writer.path, "checkpoint": checkpoint}, record.describe(),
                                    notes, start, complete=False)
    metrics = {"detectable": estimator.report.detectable, "n_steps": int(n_total), "units": METRIC_UNITS,
               "forces": diag.forces(record.start), "sensors": diag.sensors()}
    metrics["warnings"] = warnings_for(last, metrics["sensors"], duration=n_total * dt)
    if estimator.report.detectable and any(d["consistency"] > CONSISTENCY_LIMIT for d in metrics["sensors"]):
        # some channel does not fit: on the record's first chunk, find out whether a unit or a sign is wrong
        first = next(record.chunks(chunk))[1]
        found = scale_check(model, sensors, forces, first, dt, model_error_cov=estimator.model_error_cov,
                            force_increment_cov=estimator.force_increment_cov, noise_cov=noise_cov)
        metrics["warnings"] = found + metrics["warnings"] + [
            "check the channel map in [measurements]: units, invert (sign) and gauge_factor of the channels named above"]
    files = {"timeseries": writer.path, "summary": os.path.join(out, "summary.csv")}
    write_csv(summary_frame(metrics), files["summary"])
    if plot:       # after the results: a figure that fails is a warning
        t = np.concatenate(kept["t"])
        title = job.get("name", "AKF estimate")
        draw(files, "figure", metrics["warnings"], plot_estimate, t, np.vstack(kept["f"]),
             [f"{n}:{d}" for n, d in forces], os.path.join(out, "estimate.png"), f"{title}: estimated forces (streamed)",
             consistency={d["channel"]: d["consistency"] for d in metrics["sensors"]},
             note=f"; every {decimate}th step drawn" if decimate > 1 else "")
        draw(files, "sensors_figure", metrics["warnings"], plot_sensors, t, np.vstack(kept["y"]), np.vstack(kept["p"]),
             sensors, os.path.join(out, "sensors.png"), f"{title}: measured vs. predicted at the sensors")
    if os.path.exists(checkpoint):
        os.remove(checkpoint)        # a link is removed, never what it points to
    return StreamResult(job, metrics, files, record.describe(), notes, start)


def _progress(on, total, start):
    if not on:
        return lambda k: None
    from tqdm.auto import tqdm

    bar = tqdm(total=total, initial=start, unit="step", unit_scale=True, desc="estimate", leave=False)
    return bar.update
