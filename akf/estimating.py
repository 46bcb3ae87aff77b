"""The estimate pipeline: one job, simulated or measured, through one
:class:`core_akf.filter.streaming.Estimator`, to one result, one set of files and one set of figures.

A simulated job is one chunk: its whole record, with the truth beside the estimate.  A measured
record is read in chunks and filtered with the state carried over (constant memory), the results
written as they come, and a checkpoint after every chunk so that an interrupted run continues
where it ended (``akf estimate JOB --resume``).  Without an output folder the whole record is
held in memory and the :class:`EstimateResult` carries the :class:`~core_akf.filter.Estimate`.

The time series go to ``timeseries.csv`` (appended) or ``timeseries.parquet`` (a folder of one
Parquet file per chunk: a dataset that ``pandas.read_parquet`` reads whole): tidy, one row per
time step and channel, with the reference of a simulated job.  The checkpoint
(``.akf-resume.npz``) holds the filter's state, the running diagnostics, how much of the output
is written and a fingerprint of the job and its files; a resumed run cuts the output back to the
checkpoint and goes on from there.
"""
from __future__ import annotations

import json
import os
import shutil
from dataclasses import dataclass, field

import numpy as np

from core_akf.checks import check_memory
from core_akf.diagnostics import CONSISTENCY_LIMIT, RunningDiagnostics, scale_check, warnings_for
from core_akf.exceptions import AKFInputError
from core_akf.forcemodels import ForceModel
from core_akf.metrics import average_strain_error, rms_error
from core_akf.outputs import atomic_path, confined, write_csv
from core_akf.simulate import MICROSTRAIN
from core_akf.statespace import strain_feedthrough
from core_akf.filter import CheckpointError, Estimator

from .job import Job
from .plots import plot_estimate, plot_sensors
from .writers import draw

#: steps per chunk at most, unless the job says ``[measurements] chunk`` (seconds)
DEFAULT_CHUNK_STEPS = 65536
#: bytes a chunk may hold (states, their transforms, channels, output rows)
CHUNK_BYTES = 256e6
#: above this many (strain output x step) rows, ``[output] strains`` left at its default writes none
MAX_STRAIN_ROWS = 2_000_000
#: points per channel kept for the figures (the record decimated to at most this)
PLOT_POINTS = 20000
CHECKPOINT = ".akf-resume.npz"
#: above this innovation consistency (innovation RMS / predicted) on any channel, a smoothed
#: estimate is reported as untrustworthy: the model disagrees with the data (S17 case 4 as shipped:
#: 2.1-3.6 on the gauges, and the smoother makes its forces 24 % worse; calibrated: 0.99-1.01)
SMOOTH_CONSISTENCY_LIMIT = 1.5

#: units of the numbers in :attr:`EstimateResult.metrics` (and the CLI's JSON)
METRIC_UNITS = {"rms_force": "N", "rms_strain": "m/m", "avg_strain_error": "m/m", "avg_strain_error_microstrain": "µε",
                "loglik": "the natural log of a probability density of the record in SI units (higher is likelier; "
                          "compare runs of one record only)",
                "forces": {"rms": "N", "peak": "N", "time_of_peak": "s"},
                "sensors": "per channel: the sensor's SI unit (m/m, m/s^2, m/s, m); consistency and whiteness "
                           "are dimensionless"}


def default_chunk(n_states, n_channels, n_outputs):
    """Steps per chunk: :data:`DEFAULT_CHUNK_STEPS`, fewer for a large model so that a chunk holds
    about :data:`CHUNK_BYTES` (about four copies of the augmented states of ``n_states``, the
    channels and a tidy output row of six columns per written channel), at least 1024."""
    per_step = 8 * (4 * n_states + 4 * n_channels + 6 * n_outputs)
    return int(min(DEFAULT_CHUNK_STEPS, max(1024, CHUNK_BYTES // per_step)))


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
               "predicted_innovation_std", "consistency", "whiteness", "lag1_autocorrelation", "loglik"]
    return pd.DataFrame(rows, columns=columns)


@dataclass
class EstimateResult:
    """What :func:`estimate_job` did.

    Attributes
    ----------
    job : Job
    metrics : dict
        ``detectable``, ``n_steps``, ``units`` (:data:`METRIC_UNITS`), ``calibration`` (with
        ``[filter] calibrate``: :func:`calibrate_job`), ``loglik`` (the Gaussian
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
        index = list(range(self.estimate.structure.n_strain)) if strains == "all" else \
            self.estimate.structure.strain_label_index(strains)
        return TidyRows(self.estimate.structure, self.estimate.force_locations, index).frame(self.estimate,
                                                                                             self.simulation)


class TidyRows:
    """The tidy rows of a chunk: forces, then the strain outputs at ``strain_index`` (their rows of
    the model's strain operator, with the static correction of a reduced model), with the
    reference of a simulated record and the standard deviation of a smoothed estimate
    (``std``).  Text columns are categoricals: the same rows, built and written ten times faster
    than strings."""

    def __init__(self, model, forces, strain_index):
        self.index = list(strain_index)
        self.labels = [f"{node}:{d}" for node, d in forces] + [model.strain_labels[i] for i in self.index]
        self.rows = model.strain_operator[self.index] if self.index else None
        extra = strain_feedthrough(model, forces) if self.index else None
        self.extra = None if extra is None else extra[self.index]

    def frame(self, est, simulation=None, start=0):
        """Rows of the chunk ``est``; ``simulation``: the truth, of which the chunk holds steps
        ``start`` onwards."""
        import pandas as pd

        n = est.time.size
        blocks = [est.forces]
        if self.index:
            strains = est.states[:, :est.structure.n] @ self.rows.T
            blocks.append(strains if self.extra is None else strains + est.forces @ self.extra.T)
        values = np.hstack(blocks)
        if simulation is not None:
            ref = [simulation.loads[start:start + n]] + ([simulation.strains[start:start + n, self.index]]
                                                           if self.index else [])
            reference = np.hstack(ref).T.reshape(-1)
        else:
            reference = np.full(n * len(self.labels), np.nan)
        n_forces = len(est.force_locations)
        if est.smoothed:
            std = np.hstack([est.force_std] + ([est.strain_std[:, self.index]] if self.index else [])).T.reshape(-1)
        else:
            std = np.full(n * len(self.labels), np.nan)
        is_strain = np.repeat(np.arange(len(self.labels)) >= n_forces, n).astype(np.int8)

        def column(codes, categories):
            return pd.Categorical.from_codes(codes, categories=categories)
        return pd.DataFrame({"time": np.tile(est.time, len(self.labels)),
                             "quantity": column(is_strain, ["force", "strain"]),
                             "channel": column(np.repeat(np.arange(len(self.labels)), n), self.labels),
                             "unit": column(is_strain, ["N", "m/m"]),
                             "estimated": values.T.reshape(-1), "reference": reference, "std": std})


def strain_outputs(job, structure, n_steps, notes):
    """Indices of the strain outputs whose histories are written: ``[output] strains``, or all of
    them unless that is more than :data:`MAX_STRAIN_ROWS` rows (then none, with a note) when the
    job leaves it at its default."""
    wanted = job.spec.output.strains if job.spec.output is not None else None
    if wanted is None:
        if structure.n_strain * n_steps <= MAX_STRAIN_ROWS:
            return list(range(structure.n_strain))
        notes.append(f"strain histories not written ({structure.n_strain} channels x {n_steps} steps); list the "
                     "channels you want in [output] strains (summary.csv has every RMS error of a simulated job)")
        return []
    if wanted == "all":
        return list(range(structure.n_strain))
    return structure.strain_label_index(wanted)


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
                    fh.write("time,quantity,channel,unit,estimated,reference,std\n")
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

    def append_part(self, part, index):
        """Move a part written elsewhere (a task of a time-parallel run) to the end of the output."""
        confined(self.path)
        if self.fmt == "csv":
            with open(self.path, "ab") as fh, open(part, "rb") as src:
                shutil.copyfileobj(src, fh)
            os.remove(part)
            self.position = os.path.getsize(self.path)
        else:
            os.replace(part, os.path.join(self.path, f"part-{self.position:05d}.parquet"))
            self.position += 1

    def write(self, frame):
        confined(self.path)
        if self.fmt == "csv":
            with open(self.path, "ab") as fh:
                write_rows(frame, fh)
                fh.flush()
                os.fsync(fh.fileno())
            self.position = os.path.getsize(self.path)
        else:
            with atomic_path(os.path.join(self.path, f"part-{self.position:05d}.parquet")) as tmp:
                frame.to_parquet(tmp, index=False)
            self.position += 1


def write_rows(frame, fh):
    """Append the rows of a tidy frame to a CSV file open in binary mode, without a header.

    pyarrow writes them, 10x faster than pandas with ``%.17g``, and every float in its shortest
    form that reads back to the same bits; the labels are written unquoted (they hold no comma)."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    pacsv.write_csv(pa.Table.from_pandas(frame, preserve_index=False), fh,
                    pacsv.WriteOptions(include_header=False, quoting_style="none"))


def _fingerprint(job, record):
    """What shapes a run's outputs, for its checkpoint: ``(spec, files)`` as canonical JSON -- the
    job's keys as set (overrides such as ``--filter`` included), without its free-text description,
    and the record's files (names, sizes, times of change)."""
    spec = job.to_dict()
    spec.pop("description", None)
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


#: what a checkpoint of :func:`estimate_job` holds besides the filter's and the diagnostics' state
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


def estimate_job(job: Job, out: str | os.PathLike | None = None, *, resume: bool = False, overwrite: bool = False,
                 plot: bool = True, progress: bool = False, stop_after: int | None = None,
                 on_result=None, n_jobs: int | None = None) -> EstimateResult:
    """Estimate the forces and strains of an estimate :class:`~akf.job.Job`: its simulated record
    (``[simulation]``, one chunk, with the truth) or its measured one (``[measurements]``, in
    chunks of ``[measurements] chunk`` when written to ``out``).

    Parameters
    ----------
    job : Job
        A job of ``akf estimate`` (:func:`akf.job.load_job`, :func:`akf.examples.example`).
    out : str or None
        Output folder: ``timeseries.csv`` (or ``.parquet``), ``summary.csv``, ``estimate.png``,
        ``sensors.png``.  None: nothing is written and the whole record is filtered in memory
        (:attr:`EstimateResult.estimate`).
    resume : bool
        Continue an interrupted measured run from its checkpoint in ``out``; it must have been
        written for the same job and data files (else a :class:`CheckpointError` names what
        changed).
    overwrite : bool
        Start anew over an interrupted run's checkpoint in ``out`` (refused without it or
        ``resume``; a finished run leaves no checkpoint).
    plot : bool
        Draw the figures (after the results are written: a figure that fails is a warning).
    progress : bool
        A progress bar over the record's steps.
    stop_after : int or None
        Stop after this many chunks, as if interrupted (for tests and for splitting work).
    on_result : callable or None
        Called with the :class:`EstimateResult` once its files are written and before the figures
        are drawn (to print the results first: a figure that fails loses nothing).
    n_jobs : int or None
        Filter a measured record of many files time-parallel, a file per task on this many joblib
        workers (-1: all; a dask cluster inside :func:`akf.parallel.scheduler`): the steady-state
        filter's pieces at the same time (:func:`core_akf.filter.parallel.estimate_in_parallel`), each
        worker reading, filtering and writing its file.  The results equal the sequential run's
        (forces to round-off, fatigue counts exactly).  None: sequential.

    Returns
    -------
    EstimateResult
    """
    if not isinstance(job, Job):
        raise TypeError(f"estimate_job takes an akf.job.Job (akf.job.load_job, Job.from_dict), got {type(job).__name__}")
    if job.command != "estimate":
        raise AKFInputError(f"the job was read for akf {job.command}, not for akf estimate")
    spec = job.spec
    if spec.simulation is None and spec.measurements is None:
        raise AKFInputError("the job needs a [simulation] or a [measurements] section")
    if resume and overwrite:
        raise AKFInputError("--resume continues a run and --overwrite starts anew: give one of them")
    if resume and spec.measurements is None:
        raise AKFInputError("--resume continues an interrupted run of measured data; this job simulates its data")
    dt, structure, sensors, forces = job.dt, job.structure, job.sensors, job.forces
    model = job.filter_model()
    n_a = 2 * model.n + job.force_model.n_states(len(forces))
    sim = record = None
    if spec.measurements is not None:
        record = job.open_record()
        n_total, t0 = record.n_steps, record.start
        noise_cov = job.noise_cov()
        if out is None:           # in memory: the record is one chunk
            check_memory(n_total, 4 * n_a + 3 * structure.n_strain + 4 * len(sensors),
                         f"the record of {n_total} steps", "give an output folder (akf estimate streams measured "
                         "records in chunks) or use core_akf.filter.streaming.Estimator")
    else:
        # float64 values held per time step: simulated states, filter states and their products
        # (about 4 copies of the augmented state), strains of the truth and the estimate, channels
        sim = job.simulate(4 * n_a + 2 * 2 * structure.n + 3 * structure.n_strain + 4 * len(sensors))
        n_total, t0 = sim.measurements.shape[0], 0.0
        noise_cov = job.noise_cov(sim)
    Q, fm = job.model_error_cov, job.force_model
    calibration = None
    if job.calibrate:        # learn the model and the covariances from the record first
        Y_cal = sim.measurements if sim is not None else calibration_record(job, record)
        model, Q, fm, noise_cov, calibration = calibrate_job(job, model, sensors, forces, Y_cal, noise_cov)
    notes = []
    tidy = TidyRows(model, forces, strain_outputs(job, structure, n_total, notes) if out is not None else [])
    if record is None or out is None:
        chunk = n_total
    elif spec.measurements.chunk is not None:
        chunk = max(1, int(round(spec.measurements.chunk / dt)))
    else:
        chunk = default_chunk(n_a, len(sensors), len(tidy.labels))
    if n_jobs is not None and record is not None and len(record.files) > 1:
        return _estimate_in_pieces(job, out, record, model, Q, fm, noise_cov, tidy, calibration, notes, n_jobs,
                                   dict(resume=resume, overwrite=overwrite, plot=plot, stop_after=stop_after,
                                        on_result=on_result, n_total=n_total, t0=t0))
    # smoothing: with the whole record when it is one piece, else (or when asked) with a fixed lag
    lag = None
    if job.smooth and (job.smooth_lag is not None or chunk < n_total):
        lag = "auto" if job.smooth_lag in (None, "auto") else max(1, int(round(job.smooth_lag / dt)))
    estimator = Estimator(model, sensors, forces, dt, steady=job.steady, allow_undetectable=job.allow_undetectable,
                          model_error_cov=Q, force_model=fm, noise_cov=noise_cov, t0=t0, smooth_lag=lag,
                          dummy=job.dummy)
    fatigue = None
    if spec.output is not None and spec.output.fatigue is not None:
        from .fatigue import FatigueRun

        fatigue = FatigueRun(job, simulated=sim is not None)
    run = _Run(job, out, record, n_total, chunk, resume, overwrite) if out is not None else None
    start = run.start(estimator) if run is not None else 0
    if fatigue is not None and start:
        fatigue.restore(run.saved)
    diag = RunningDiagnostics(n_total)
    progress_bar = _progress(progress, n_total, start)
    chunks = record.chunks(chunk, start) if record is not None else [(0, sim.measurements)]
    first_chunk = last = None
    done = 0
    parts = []                                # a record in one piece smoothed with a lag: its estimate in two parts
    restored = run is not None and start > 0

    def take(est):
        nonlocal last, restored
        if restored:
            run.restore_diagnostics(diag, est)
            restored = False
        diag.update(est)
        last = est
        if fatigue is not None:
            fatigue.update(est, sim, estimator.n_returned - est.forces.shape[0])
        if run is not None:
            run.write(est, tidy, sim, estimator.n_returned - est.forces.shape[0])
        if lag is not None and chunk >= n_total:
            parts.append(est)
    for step, Y in chunks:
        est = estimator.update(Y)
        first_chunk = Y if first_chunk is None and step == 0 else first_chunk
        done += 1
        progress_bar(Y.shape[0])
        if job.smooth and lag is None:        # one piece: the smoothed estimate replaces the filtered one
            est = estimator.smooth(est, Y)
        take(est)
        if run is not None and step + Y.shape[0] < n_total:     # after the last chunk the summary follows
            run.checkpoint(estimator, diag, step + Y.shape[0], {} if fatigue is None else fatigue.state())
            if stop_after is not None and done >= stop_after:
                notes.append(f"stopped after {done} chunk(s) at step {step + Y.shape[0]} of {n_total}; continue "
                             "with --resume")
                return EstimateResult(job, {}, run.partial_files(), record.describe(), notes, start, complete=False)
    if lag is not None:                        # the steps the fixed-lag smoother still holds
        take(estimator.finish())
        notes.append(f"smoothed with a fixed lag of {estimator.lagged.lag} steps ({estimator.lagged.lag * dt:.6g} s)")
    if parts:
        last = _joined(parts)
        done = 1
    whole = last if done == 1 and start == 0 else None
    metrics = _metrics(job, estimator, diag, last, n_total, t0, whole, sim, model, sensors, forces, noise_cov,
                       lambda: first_chunk if first_chunk is not None else next(iter(record.chunks(chunk)))[1])
    if job.smooth:
        metrics["smoothed"] = True
        worst = max(d["consistency"] for d in metrics["sensors"])
        if worst > SMOOTH_CONSISTENCY_LIMIT:
            metrics["warnings"].insert(0, f"the estimate was smoothed although the data disagree with the model "
                                          f"(consistency up to {worst:.3g}): smoothing a wrong model makes the forces "
                                          "worse and its bands too narrow; calibrate first ([filter] calibrate)")
    if fatigue is not None:
        metrics["fatigue"] = fatigue.metrics(dt)
    if calibration is not None:
        metrics["calibration"] = calibration
        metrics["warnings"] = [f"calibration: {w}" for w in calibration["warnings"]] + metrics["warnings"]
    result = EstimateResult(job, metrics, {}, record.describe() if record is not None else [], notes, start,
                            estimate=whole, simulation=sim)
    if run is not None:
        result.files = run.write_summary(metrics, fatigue)
    if on_result is not None:
        on_result(result)
    if run is not None:
        run.finish(result.files, metrics, plot, whole, forces, sensors)
    return result


def _estimate_in_pieces(job, out, record, model, Q, fm, noise_cov, tidy, calibration, notes, n_jobs, opts):
    """:func:`estimate_job` of a measured record of many files, time-parallel: a file per task."""
    import joblib

    from core_akf.filter import estimate_in_parallel

    if out is None:
        raise AKFInputError("a time-parallel run writes each file's results where it is filtered: give an output folder")
    if job.smooth:
        raise AKFInputError("the time-parallel run filters; smoothing needs the record after each step in the same "
                            "task: leave smooth off, or run without n_jobs (--n-jobs, --scheduler)")
    if job.steady is False:
        raise AKFInputError("the time-parallel run needs the steady-state filter ([filter] steady = true or unset)")
    if opts["resume"] or opts["stop_after"] is not None:
        raise AKFInputError("a time-parallel run is not resumed: its files run at once; run it again")
    estimator = Estimator(model, job.sensors, job.forces, job.dt, steady=True, allow_undetectable=job.allow_undetectable,
                          model_error_cov=Q, force_model=fm, noise_cov=noise_cov, t0=opts["t0"], dummy=job.dummy)
    fatigue = None
    if job.spec.output is not None and job.spec.output.fatigue is not None:
        from .fatigue import FatigueRun

        fatigue = FatigueRun(job, simulated=False)
    n_total = opts["n_total"]
    run = _Run(job, out, record, n_total, n_total, False, opts["overwrite"])
    run.start(estimator)
    record.channel_offsets()                           # once, here: every worker subtracts the same offsets
    firsts = np.cumsum([0] + [t.n_steps for t in record.timings])[:-1]
    folder = os.path.join(run.out, ".pieces")
    os.makedirs(confined(folder), exist_ok=True)
    piece = _PieceOutputs(tidy, fatigue, n_total, folder, run.writer.fmt, [int(f) for f in firsts], run.decimate)

    def map_pieces(f, items):
        return joblib.Parallel(n_jobs=n_jobs)(joblib.delayed(f)(x) for x in items)
    results = estimate_in_parallel(estimator, [_FilePiece(record, i) for i in range(len(record.files))], map_pieces,
                                   piece)
    diag = None
    for i, r in enumerate(results):                   # in record order: the outputs, the counts, the figures' samples
        run.writer.append_part(r["part"], i)
        diag = r["diag"] if diag is None else diag.merge(r["diag"])
        if fatigue is not None:
            fatigue.estimated = r["fatigue"] if i == 0 else fatigue.estimated.merge(r["fatigue"])
            fatigue.steps += r["steps"]
        for k in ("t", "f", "y", "p"):
            run.kept[k].append(r["kept"][k])
    os.rmdir(folder)
    notes.append(f"filtered time-parallel: {len(results)} files as one task each")
    metrics = _metrics(job, estimator, diag, diag.last, n_total, opts["t0"], None, None, model, job.sensors, job.forces,
                       noise_cov, lambda: next(iter(record.chunks(DEFAULT_CHUNK_STEPS)))[1])
    if fatigue is not None:
        metrics["fatigue"] = fatigue.metrics(job.dt)
    if calibration is not None:
        metrics["calibration"] = calibration
        metrics["warnings"] = [f"calibration: {w}" for w in calibration["warnings"]] + metrics["warnings"]
    result = EstimateResult(job, metrics, {}, record.describe(), notes, 0)
    result.files = run.write_summary(metrics, fatigue)
    if opts["on_result"] is not None:
        opts["on_result"](result)
    run.finish(result.files, metrics, opts["plot"], None, job.forces, job.sensors)
    return result


class _FilePiece:
    """A file of a record, read where its task runs."""

    def __init__(self, record, index):
        self.record, self.index = record, index

    def __call__(self):
        return self.record.read_file(self.index)


class _PieceOutputs:
    """What a task of a time-parallel run makes of its file's estimate, where it runs: the tidy rows
    (a part file), its diagnostics and fatigue counts, the samples the figures draw.  Only those
    travel back."""

    def __init__(self, tidy, fatigue, n_total, folder, fmt, firsts, decimate):
        self.tidy, self.n_total, self.folder, self.fmt = tidy, n_total, folder, fmt
        self.firsts, self.decimate = firsts, decimate
        self.fatigue = None if fatigue is None else (fatigue.W, fatigue.curve, fatigue.m, fatigue.n_eq)

    def __call__(self, est, i):
        from dataclasses import replace

        from core_akf.fatigue import FatigueAccumulator

        step = self.firsts[i]
        path = os.path.join(self.folder, f"part-{i:05d}.{self.fmt}")
        frame = self.tidy.frame(est, None, step)
        if self.fmt == "csv":
            with open(path, "wb") as fh:
                write_rows(frame, fh)
        else:
            frame.to_parquet(path, index=False)
        diag = RunningDiagnostics(self.n_total).starting_at(step)
        diag.update(est)
        n = est.forces.shape[0]
        diag.last = replace(est, states=est.states[-1:], forces=est.forces[-1:], innovations=est.innovations[-1:],
                            measurements=est.measurements[-1:], loglik_terms=est.loglik_terms[-1:],
                            t0=est.t0 + (n - 1) * est.dt)          # what the summary reads, not the whole piece
        counts = None
        if self.fatigue is not None:
            W, curve, m, n_eq = self.fatigue
            counts = FatigueAccumulator(W.shape[0], curve, m, n_eq)
            counts.update(est.strains @ W.T)
        sel = np.arange((-step) % self.decimate, n, self.decimate)
        kept = {"t": est.time[sel], "f": est.forces[sel], "y": est.measurements[sel], "p": est.predicted[sel]}
        return {"part": path, "diag": diag, "fatigue": counts, "steps": n, "kept": kept}


def _joined(parts):
    """One estimate of consecutive ones (a record smoothed with a lag comes in parts)."""
    from dataclasses import replace

    parts = [p for p in parts if p.forces.shape[0]] or parts[:1]
    cat = {name: np.concatenate([getattr(p, name) for p in parts]) for name in
           ("states", "forces", "innovations", "measurements", "loglik_terms", "force_std", "strain_std")}
    return replace(parts[0], **cat)


def _metrics(job, estimator, diag, last, n_total, t0, whole, sim, model, sensors, forces, noise_cov, first_chunk):
    """The metrics of a finished run (see :class:`EstimateResult`); ``first_chunk()`` gives the
    record's first chunk, for the scale check of a channel that does not fit."""
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


def calibration_record(job, record):
    """The part of a measured record that calibrates the filter: its first ``[filter]
    calibrate_window`` seconds, or the whole record up to :data:`DEFAULT_CHUNK_STEPS` steps."""
    steps = DEFAULT_CHUNK_STEPS if job.calibrate_window is None else max(2, int(round(job.calibrate_window / job.dt)))
    return next(iter(record.chunks(min(steps, record.n_steps))))[1]


def calibrate_job(job, model, sensors, forces, Y, noise_cov):
    """Fit ``[filter] calibrate`` of a job on the record ``Y`` (:func:`core_akf.calibration.calibrate`).

    Returns the fitted ``(model, Q, force_model, R)`` and the report of the fit (the ``calibration`` object of
    the metrics): the fitted values under their ``[filter]`` names (``stiffness_factor`` relative to
    ``[structure]``; ``noise_cov`` per sensor kind when the job gives it so, else per channel), the
    log-likelihood and the consistency per channel before and after, the standard errors
    (relative) and the warnings of the fit."""
    from core_akf.calibration import calibrate
    from core_akf.diagnostics import sensor_diagnostics
    from core_akf.filter import estimate

    Q, fm = job.model_error_cov, job.force_model
    fit = calibrate(model, sensors, forces, Y, job.dt, parameters=job.calibrate, model_error_cov=Q,
                    force_model=fm, noise_cov=noise_cov, modes=job.calibrate_modes, dummy=job.dummy)
    fitted = list(fit.apply(model, sensors, Q, fm.increment_cov, noise_cov))
    fitted[2] = fit.force_model if fm.stationary else ForceModel("random_walk", increment_cov=fitted[2])

    def consistency(m, q, f, r):
        est = estimate(m, sensors, forces, Y, job.dt, model_error_cov=q, force_model=f, noise_cov=r, dummy=job.dummy)
        return {d["channel"]: d["consistency"] for d in sensor_diagnostics(est)}
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
    report |= {"multipliers": m, "std_errors": fit.std_errors, "loglik_before": fit.loglik_before,
               "loglik_after": fit.loglik_after, "consistency_before": consistency(model, Q, fm, noise_cov),
               "consistency_after": consistency(*fitted), "warnings": list(fit.warnings),
               "evaluations": fit.evaluations, "seconds": fit.seconds}
    return (*fitted, report)


class _Run:
    """The files of one run in an output folder: the tidy writer, the checkpoint and the decimated
    record kept for the figures."""

    def __init__(self, job, out, record, n_total, chunk, resume, overwrite):
        self.job, self.out, self.record, self.chunk = job, os.fspath(out), record, chunk
        self.resume, self.overwrite = resume, overwrite
        os.makedirs(confined(self.out), exist_ok=True)
        fmt = (job.spec.output.format if job.spec.output is not None else None) or "csv"
        self.writer = _Writer(self.out, fmt)
        self.path = os.path.join(self.out, CHECKPOINT)
        self.decimate = max(1, -(-n_total // PLOT_POINTS))
        self.kept = {"t": [], "f": [], "y": [], "p": []}
        self.reference = []           # the decimated true forces of a simulated record
        self.saved = None
        self.fatigue = None           # the FatigueRun whose figure finish() draws

    def start(self, estimator):
        """The step the run starts from: 0, or a checkpoint's (its state restored into ``estimator``)."""
        path, out = self.path, self.out
        if not self.resume and os.path.lexists(path) and not self.overwrite:
            raise AKFInputError(f"{out} holds an interrupted run (its checkpoint {CHECKPOINT} and partial output): "
                                "continue it with --resume, or start anew with --overwrite")
        if self.record is not None:
            self.spec, self.data_files = _fingerprint(self.job, self.record)
        if not self.resume:
            self.writer.start(0)
            return 0
        if not os.path.exists(path):
            raise AKFInputError(f"nothing to resume in {out}: no checkpoint {CHECKPOINT} (run without --resume)")
        saved = _load_checkpoint(path)
        if str(saved["job"]) != self.spec:
            raise CheckpointError(f"the job changed since the checkpoint in {out} was written ("
                                  + ", ".join(_changed_keys(str(saved["job"]), self.spec)) + "); resuming would mix "
                                  "two runs in one output: start anew with --overwrite, or undo the change")
        if str(saved["files"]) != self.data_files:
            raise CheckpointError(f"the data files changed since the checkpoint in {out} was written (names, sizes or "
                                  "times of change); start anew with --overwrite")
        if int(saved["chunk"]) != self.chunk:
            raise CheckpointError("the checkpoint was written with another chunk length; start anew with --overwrite")
        estimator.restore(saved)
        self.writer.start(int(saved["position"]))
        self.kept = {k: [saved[f"plot_{k}"]] for k in ("t", "f", "y", "p", "s") if f"plot_{k}" in saved}
        self.saved = saved
        return int(saved["next_step"])

    def restore_diagnostics(self, diag, est):
        try:
            diag.restore(self.saved, est)
        except (KeyError, ValueError) as exc:
            raise CheckpointError(f"the checkpoint {self.path} lacks the running diagnostics ({exc}); start anew "
                                  "with --overwrite") from None

    def write(self, est, tidy, sim, step):
        """Append a chunk's rows and keep its decimated signals for the figures."""
        self.writer.write(tidy.frame(est, sim, step))
        sel = np.arange((-step) % self.decimate, est.forces.shape[0], self.decimate)
        self.kept["t"].append(est.time[sel])
        self.kept["f"].append(est.forces[sel])
        self.kept["y"].append(est.measurements[sel])
        self.kept["p"].append(est.predicted[sel])
        if sim is not None:
            self.reference.append(sim.loads[step + sel])
        if est.smoothed:
            self.kept.setdefault("s", []).append(est.force_std[sel])

    def checkpoint(self, estimator, diag, next_step, extra):
        state = estimator.state() | diag.state() | extra | {
            "next_step": np.array(next_step), "position": np.array(self.writer.position),
            "job": np.array(self.spec), "files": np.array(self.data_files), "chunk": np.array(self.chunk)} | {
            f"plot_{k}": np.concatenate(v) if k == "t" else np.vstack(v) for k, v in self.kept.items()}
        with atomic_path(self.path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, **state)

    def partial_files(self):
        return {"timeseries": self.writer.path, "checkpoint": self.path}

    def write_summary(self, metrics, fatigue=None):
        """Write ``summary.csv`` (and ``fatigue.csv``); returns the files written."""
        files = {"timeseries": self.writer.path, "summary": os.path.join(self.out, "summary.csv")}
        write_csv(summary_frame(metrics), files["summary"])
        if fatigue is not None:
            files["fatigue"] = os.path.join(self.out, "fatigue.csv")
            write_csv(fatigue.frame(self.job.dt), files["fatigue"])
        self.fatigue = fatigue
        return files

    def finish(self, files, metrics, plot, whole, forces, sensors):
        """Draw the figures (into ``files``; a failure is a warning) and remove the checkpoint."""
        if plot:       # after the results: a figure that fails is a warning
            t = np.concatenate(self.kept["t"])
            title = self.job.name
            step = f"; every {self.decimate}th step drawn" if self.decimate > 1 else ""
            draw(files, "figure", metrics["warnings"], plot_estimate, t, np.vstack(self.kept["f"]),
                 [f"{n}:{d}" for n, d in forces], os.path.join(self.out, "estimate.png"),
                 f"{title}: estimated forces" + (" (streamed)" if whole is None else ""),
                 reference=np.vstack(self.reference) if self.reference else None, strain_errors=metrics.get("rms_strain"),
                 force_std=np.vstack(self.kept["s"]) if "s" in self.kept else None,
                 consistency={d["channel"]: d["consistency"] for d in metrics["sensors"]}, note=step)
            draw(files, "sensors_figure", metrics["warnings"], plot_sensors, t, np.vstack(self.kept["y"]),
                 np.vstack(self.kept["p"]), sensors, os.path.join(self.out, "sensors.png"),
                 f"{title}: measured vs. predicted at the sensors")
            if self.fatigue is not None:
                from .plots import plot_fatigue

                frame = self.fatigue.frame(self.job.dt)
                damaged = bool((frame["damage"] > 0).any())       # else every range is below the cut-off: the DEL
                draw(files, "fatigue_figure", metrics["warnings"], plot_fatigue, self.job.structure, frame["channel"],
                     (frame["damage"] if damaged else frame["del"] / 1e6).to_numpy(),
                     os.path.join(self.out, "fatigue.png"),
                     f"{title}: fatigue of the estimated stresses ({self.fatigue.curve.name}"
                     + ("" if damaged else "; every range below its cut-off: no damage") + ")", sensors,
                     "Miner's damage" if damaged else f"DEL (MPa, m = {self.fatigue.m:g})")
        if os.path.exists(self.path):
            os.remove(self.path)        # a link is removed, never what it points to


def _progress(on, total, start):
    if not on:
        return lambda k: None
    from tqdm.auto import tqdm

    bar = tqdm(total=total, initial=start, unit="step", unit_scale=True, desc="estimate", leave=False)
    return bar.update
