"""The estimate pipeline: one job, simulated or measured, through one
:class:`core_akf.filter.Estimator`, to one result, one set of files and one set of figures.

A simulated job is one chunk: its whole record, with the truth beside the estimate.  A measured
record is read in chunks and filtered with the state carried over (constant memory), the results
written as they come (:mod:`akf.estimate.files`), and a checkpoint after every chunk so that an
interrupted run continues where it ended (``akf estimate JOB --resume``).  Without an output
folder the whole record is held in memory and the :class:`~akf.estimate.metrics.EstimateResult`
carries the :class:`~core_akf.filter.Estimate`.  A record of many files may instead be filtered
time-parallel (:mod:`akf.estimate.pieces`).
"""
from __future__ import annotations

import errno
import os
import sys
from dataclasses import dataclass, field

from core_akf.checks import AKFInputError, check_memory
from core_akf.diagnostics import RunningDiagnostics
from core_akf.filter import Estimator
from core_akf.outputs import confine_writes
from core_akf.quality import LIVE_SET_MIN_S, LiveSets

from ..calibrating import calibrate_job, calibration_record
from ..job import Job
from ..outputs import Interrupted
from .faults import NO_FAULT_CHECK, FaultCheck
from .files import RunFiles, default_chunk, strain_outputs
from .metrics import SMOOTH_CONSISTENCY_LIMIT, EstimateResult, joined, run_metrics
from .pieces import estimate_in_pieces


@dataclass
class Setup:
    """What a job's run filters, decided once: the record (measured) or the simulation, the
    filter's model and covariances (calibrated if the job asks), the strain outputs written and
    the chunk length.

    Attributes
    ----------
    job : Job
    out : str or None
        The output folder.
    sim : core_akf.simulate.Simulation or None
        The simulated record and its truth.
    record : Record or None
        The measured record.
    n_total : int
        Steps of the record.
    t0 : float
        Time of its first step (s).
    model : Structure
        The filter's model.
    Q, force_model, noise_cov
        The filter's covariances and force model.
    calibration : dict or None
        The report of ``[filter] calibrate`` (:func:`akf.calibrating.calibrate_job`).
    strains : list of int
        The strain outputs whose histories are written.
    chunk : int
        Steps per chunk.
    notes : list of str
    warnings : list of str
        What the record made of the job (a dead channel dropped), for the run's warnings.
    """

    job: Job
    out: str | None
    sim: object
    record: object
    n_total: int
    t0: float
    model: object
    Q: object
    force_model: object
    noise_cov: object
    calibration: dict | None = None
    strains: list = field(default_factory=list)
    chunk: int = 0
    notes: list = field(default_factory=list)
    warnings: list = field(default_factory=list)

    @classmethod
    def of(cls, job, out):
        """The set-up of ``job`` written to ``out`` (None: in memory)."""
        spec, structure, sensors = job.spec, job.structure, job.sensors
        model = job.filter_model()
        n_a = 2 * model.n + job.force_model.n_states(len(job.forces))
        sim = record = None
        notes = []
        if spec.measurements is not None:
            record, job, notes = job.open_live_record()       # without channels that are never observed
            spec, sensors = job.spec, job.sensors
            n_total, t0 = record.n_steps, record.start
            noise_cov = job.noise_cov()
            if out is None:           # in memory: the record is one chunk
                check_memory(record.n_filtered, 4 * n_a + 3 * structure.n_strain + 4 * len(sensors),
                             f"the record of {n_total} steps", "give an output folder (akf estimate streams measured "
                             "records in chunks) or use core_akf.filter.Estimator")
        else:
            # float64 values held per time step: simulated states, filter states and their products
            # (about 4 copies of the augmented state), strains of the truth and the estimate, channels
            sim = job.simulate(4 * n_a + 2 * 2 * structure.n + 3 * structure.n_strain + 4 * len(sensors))
            n_total, t0 = sim.measurements.shape[0], 0.0
            noise_cov = job.noise_cov(sim)
        setup = cls(job, out, sim, record, n_total, t0, model, job.model_error_cov, job.force_model, noise_cov,
                    warnings=notes, notes=[] if record is None else record.gap_notes())
        if job.calibrate:        # learn the model and the covariances from the record first
            Y_cal = sim.measurements if sim is not None else calibration_record(job, record, model)
            setup.model, setup.Q, setup.force_model, setup.noise_cov, setup.calibration = calibrate_job(
                job, model, sensors, job.forces, Y_cal, noise_cov, None if record is None else record.n_steps)
        n_rows = n_total if record is None else record.n_filtered        # the rows written: no restart gap
        setup.strains = strain_outputs(job, structure, n_rows, setup.notes, setup.warnings, out) if out is not None else []
        setup.chunk = setup.chunk_length(n_a)
        return setup

    def chunk_length(self, n_a):
        """Steps per chunk: the whole record in memory or simulated, else ``[measurements] chunk``
        or :func:`~akf.estimate.files.default_chunk`."""
        if self.record is None or self.out is None:
            return self.n_total
        if self.job.spec.measurements.chunk is not None:
            return max(1, int(round(self.job.spec.measurements.chunk / self.job.dt)))
        n_outputs = len(self.job.forces) + len(self.strains)
        return default_chunk(n_a, len(self.job.sensors), n_outputs)

    def estimator(self, **kw):
        """The job's :class:`~core_akf.filter.Estimator` on this set-up's model and covariances."""
        job = self.job
        return Estimator(self.model, job.sensors, job.forces, job.dt, allow_undetectable=job.allow_undetectable,
                         model_error_cov=self.Q, force_model=self.force_model, noise_cov=self.noise_cov, t0=self.t0,
                         dummy=job.dummy, **kw)

    def fatigue(self):
        """The job's :class:`~akf.fatigue.FatigueRun` (None without ``[output.fatigue]``)."""
        if self.job.spec.output is None or self.job.spec.output.fatigue is None:
            return None
        from ..fatigue import FatigueRun

        return FatigueRun(self.job, simulated=self.sim is not None)

    def first_chunk(self, steps=None):
        """The record's first chunk of ``steps`` (default the chunk length), for the scale check of a
        channel that does not fit."""
        if self.sim is not None:
            return self.sim.measurements
        return next(iter(self.record.chunks(steps or self.chunk)))[1]

    def finished(self, metrics):
        """``metrics`` with the record's and the calibration's warnings, and the calibration's report."""
        metrics["warnings"] = self.warnings + metrics["warnings"]
        if self.calibration is not None:
            metrics["calibration"] = self.calibration
            metrics["warnings"] = [f"calibration: {w}" for w in self.calibration["warnings"]] + metrics["warnings"]
        return metrics


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
    _check_request(job, resume, overwrite)
    if out is None:
        return _estimate(job, None, resume, overwrite, progress, stop_after, plot, on_result, n_jobs)
    with confine_writes(os.fspath(out)):       # what it writes is listed in the folder's .akf-files (ours, later)
        return _estimate(job, os.fspath(out), resume, overwrite, progress, stop_after, plot, on_result, n_jobs)


def _estimate(job, out, resume, overwrite, progress, stop_after, plot, on_result, n_jobs):
    """:func:`estimate_job` after its checks, inside its output folder."""
    setup = Setup.of(job, out)
    if n_jobs is not None and setup.record is not None and len(setup.record.files) > 1:
        if resume or stop_after is not None:
            raise AKFInputError("a time-parallel run is not resumed: its files run at once; run it again")
        holes = setup.record.gaps or not setup.record.observed_counts().sum() == setup.record.n_steps * len(job.sensors)
        if not holes:
            return estimate_in_pieces(setup, n_jobs, overwrite=overwrite, plot=plot, on_result=on_result)
        setup.notes.append("the record has missing samples or gaps between its files: it was filtered sequentially "
                           "(the time-parallel filter needs complete files that join step by step)")
    elif n_jobs is not None and n_jobs != 1:
        what = "a simulated record" if setup.record is None else "a record of one file"
        setup.notes.append(f"--n-jobs {n_jobs} not used: {what} is filtered sequentially (the time-parallel filter "
                           "runs the files of a record of many files at once)")
    return Pipeline(setup, resume, overwrite, progress).run(stop_after, plot, on_result)


def _check_request(job, resume, overwrite):
    """The job is an estimate job with a record, and the run's flags agree."""
    if not isinstance(job, Job):
        raise TypeError(f"estimate_job takes an akf.job.Job (akf.job.load_job, Job.from_dict), got {type(job).__name__}")
    if job.command != "estimate":
        raise AKFInputError(f"the job was read for akf {job.command}, not for akf estimate")
    if job.spec.simulation is None and job.spec.measurements is None:
        raise AKFInputError("the job needs a [simulation] or a [measurements] section")
    if resume and overwrite:
        raise AKFInputError("--resume continues a run and --overwrite starts anew: give one of them")
    if resume and job.spec.measurements is None:
        raise AKFInputError("--resume continues an interrupted run of measured data; this job simulates its data")


#: the errors of a full disk or an exhausted quota
DISK_FULL = (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC))


class Pipeline:
    """One sequential run of a set-up: the record chunk by chunk through one estimator, each
    chunk's estimate into the diagnostics, the fatigue counts and the files, then the metrics.

    Smoothing: with the whole record when it is one chunk, else (or when the job gives
    ``smooth_lag``) with a fixed lag; a record in one chunk smoothed with a lag comes out in two
    parts, joined at the end.

    Parameters
    ----------
    setup : Setup
    resume, overwrite : bool
        As :func:`estimate_job`.
    progress : bool
        A progress bar over the record's steps.
    """

    def __init__(self, setup, resume=False, overwrite=False, progress=False):
        job = setup.job
        self.setup = setup
        self.lag = None
        self.filtered = False          # every step filtered and written to the time series
        record_s = setup.n_total * job.dt
        if job.smooth_lag not in (None, "auto") and not job.smooth_lag <= record_s:
            raise AKFInputError(f"[filter] smooth_lag = {job.smooth_lag:.4g} s is longer than the record ({record_s:.4g} "
                                "s): the smoother would wait for steps that never come; give a lag of a few filter time "
                                "constants (\"auto\" finds one), or leave it out to smooth the whole record")
        if job.smooth and (job.smooth_lag is not None or setup.chunk < setup.n_total):
            self.lag = "auto" if job.smooth_lag in (None, "auto") else max(1, int(round(job.smooth_lag / job.dt)))
        self.estimator = setup.estimator(steady=job.steady, smooth_lag=self.lag)
        self.fatigue = setup.fatigue()
        self.files = None if setup.out is None else RunFiles(job, setup.out, setup.record, setup.n_total, setup.chunk,
                                                             resume, overwrite)
        self.start = self.files.start(self.estimator) if self.files is not None else 0
        if self.fatigue is not None and self.start:
            self.fatigue.restore(self.files.saved)
        self.n_filtered = setup.n_total if setup.record is None else setup.record.n_filtered
        self.diag = RunningDiagnostics(self.n_filtered)
        self.live = LiveSets([s.label for s in job.sensors], round(LIVE_SET_MIN_S / job.dt))
        self.faults = FaultCheck(job, [s.label for s in job.sensors]) if setup.record is not None else NO_FAULT_CHECK
        if self.start:
            self.live.restore(self.files.saved)
            self.faults.restore(self.files.saved)
        self.restored = self.files is not None and self.start > 0     # the diagnostics come back with the first chunk
        self.progress = _progress(progress, setup.n_total, self.start)
        self.parts, self.last, self.first_chunk, self.done = [], None, None, 0

    def chunks(self):
        """``(first step, measurements)`` of every chunk still to filter."""
        s = self.setup
        return s.record.chunks(s.chunk, self.start) if s.record is not None else [(0, s.sim.measurements)]

    def take(self, est):
        """One chunk's estimate into the diagnostics, the fatigue counts and the files."""
        if self.restored:
            self.files.restore_diagnostics(self.diag, est)
            self.restored = False
        self.diag.update(est)
        self.last = est
        step = self.estimator.n_returned - est.forces.shape[0]
        self.live.update(est.measurements, step)
        if self.fatigue is not None:
            self.fatigue.update(est, self.setup.sim, step)
        if self.files is not None:
            self.files.write(est, self.setup.strains, self.setup.sim, step)
        if self.lag is not None and self.setup.chunk >= self.setup.n_total:
            self.parts.append(est)

    def run(self, stop_after=None, plot=True, on_result=None):
        """Filter, report and write; the :class:`EstimateResult` (a partial one when stopped).
        Ctrl-C while the record streams into a folder raises :class:`~akf.outputs.Interrupted`,
        which names the partial files kept for ``--resume``."""
        try:
            return self._run(stop_after, plot, on_result)
        except OSError as exc:
            if self.files is None or exc.errno not in DISK_FULL:
                raise
            raise AKFInputError(self.files.after_disk_full(exc, self.setup.n_total)) from None
        except KeyboardInterrupt:
            if self.files is None or isinstance(sys.exc_info()[1], Interrupted):
                raise
            kept = self.files.checkpointed
            where = self.files.writer.path
            if self.filtered:
                raise Interrupted(f"interrupted after the whole record was filtered: {os.path.basename(where)} is "
                                  "complete; the files that follow it (summary.csv, the figures) were not written: run "
                                  "the command again" + (" with --resume" if kept else "")) from None
            if kept:
                raise Interrupted(f"interrupted: {os.path.basename(where)} is partial and kept with the checkpoint "
                                  f"for --resume, which goes on from step {kept} of {self.setup.n_total} (run the same "
                                  "command with --resume); the other files of this run were not written") from None
            raise Interrupted(f"interrupted before the first checkpoint: {os.path.basename(where)} is partial and "
                              "cannot be resumed; run the command again") from None

    def _run(self, stop_after, plot, on_result):
        s = self.setup
        for step, Y in self.chunks():
            if step != self.estimator.n_steps:            # a gap longer than max_gap: start again from the prior
                self.restart(step)
            if self.faults.on:
                saved = self.estimator.state()
                Y = self.faults.before(Y, step)
                est = self.faults.after(self.estimator, self.estimator.update(Y), Y, saved)
            else:
                est = self.estimator.update(Y)
            if self.first_chunk is None and step == 0:
                self.first_chunk = Y
            self.done += 1
            self.progress(Y.shape[0])
            if s.job.smooth and self.lag is None:        # one piece: the smoothed estimate replaces the filtered one
                est = self.estimator.smooth(est, Y)
            self.take(est)
            end = step + Y.shape[0]
            if self.files is not None and end < s.n_total:     # after the last chunk the summary follows
                self.files.checkpoint(self.estimator, self.diag, end, self.live.state() | self.faults.state() |
                                      ({} if self.fatigue is None else self.fatigue.state()))
                if stop_after is not None and self.done >= stop_after:
                    s.notes.append(f"stopped after {self.done} chunk(s) at step {end} of {s.n_total}; continue with "
                                   "--resume")
                    return EstimateResult(s.job, {}, self.files.partial_files(), s.record.describe(), s.notes, self.start,
                                          complete=False)
        self.filtered = self.lag is None
        if self.lag is not None:                        # the steps the fixed-lag smoother still holds
            self.take(self.estimator.finish())
            self.filtered = True
            lag = self.estimator.lagged.lag
            s.notes.append(f"smoothed with a fixed lag of {lag} steps ({lag * s.job.dt:.6g} s)")
        if self.parts:
            self.last, self.done = joined(self.parts), 1
        return self.report(plot, on_result)

    def restart(self, step):
        """The filter from its prior at record step ``step`` (after a long gap); a fixed-lag
        smoother first gives the steps it holds."""
        if self.lag is not None:
            self.take(self.estimator.finish())
        self.estimator = self.estimator.restarted_at(step)

    def report(self, plot, on_result):
        """The metrics and the result of the finished run; its files written, then the figures drawn."""
        s = self.setup
        whole = self.last if self.done == 1 and self.start == 0 else None
        first = self.first_chunk
        metrics = run_metrics(s.job, self.estimator, self.diag, self.last, self.n_filtered, s.t0, whole, s.sim, s.model,
                              s.noise_cov, (lambda: first) if first is not None else s.first_chunk)
        if s.job.smooth:
            metrics["smoothed"] = True
            worst = max(d["consistency"] for d in metrics["sensors"])
            if worst > SMOOTH_CONSISTENCY_LIMIT:
                metrics["warnings"].insert(0, f"the estimate was smoothed although the data disagree with the model "
                                              f"(consistency up to {worst:.3g}): smoothing a wrong model makes the "
                                              "forces worse and its bands too narrow; calibrate first ([filter] "
                                              "calibrate)")
        if self.fatigue is not None:
            metrics["fatigue"] = self.fatigue.metrics(s.job.dt)
        metrics["warnings"] += self.live.undetectable(self.estimator.filter.report_of, self.estimator.n_steps,
                                                      s.job.dt, s.t0)
        if self.faults.on:
            metrics["faults"] = self.faults.rows(s.t0)
            metrics["warnings"] += self.faults.warnings(s.t0)
        metrics = s.finished(metrics)
        result = EstimateResult(s.job, metrics, {}, s.record.describe() if s.record is not None else [], s.notes,
                                self.start, estimate=whole, simulation=s.sim)
        if self.files is not None:
            result.files = self.files.write_summary(metrics, self.fatigue)
            if self.faults.on:
                result.files["data_quality"] = self.files.write_table("data_quality.csv", self.faults.frame(s.t0))
        if on_result is not None:
            on_result(result)
        if self.files is not None:
            self.files.finish(result.files, metrics, plot, whole, s.job.forces, s.job.sensors)
        return result


def _progress(on, total, start):
    """A progress bar's ``update(steps)`` (a no-op without one)."""
    if not on:
        return lambda k: None
    from tqdm.auto import tqdm

    bar = tqdm(total=total, initial=start, unit="step", unit_scale=True, desc="estimate", leave=False)
    return bar.update
