"""A measured record of many files filtered time-parallel: a file per task, each worker reading,
filtering and writing its file (:func:`core_akf.filter.estimate_in_parallel`); the results equal
the sequential run's (forces to round-off, fatigue counts exactly)."""
from __future__ import annotations

import os
from dataclasses import replace

import numpy as np

from core_akf.checks import AKFInputError
from core_akf.diagnostics import RunningDiagnostics
from core_akf.outputs import confined

from ..parallel import at_most
from .files import DEFAULT_CHUNK_STEPS, RunFiles, write_rows
from .metrics import EstimateResult, run_metrics


def estimate_in_pieces(setup, n_jobs, *, overwrite=False, plot=True, on_result=None):
    """:func:`akf.estimate.estimate_job` of a measured record of many files, time-parallel: a file per task.

    Parameters
    ----------
    setup : akf.estimate.pipeline.Setup
        The run's record, model and covariances.
    n_jobs : int
        joblib workers (-1: all).
    overwrite, plot, on_result
        As :func:`akf.estimate.estimate_job`.

    Returns
    -------
    EstimateResult
    """
    from core_akf.filter import estimate_in_parallel
    from core_akf.tasks import run_tasks

    job, record, n_total = setup.job, setup.record, setup.n_total
    if setup.out is None:
        raise AKFInputError("a time-parallel run writes each file's results where it is filtered: give an output folder")
    if job.smooth:
        raise AKFInputError("the time-parallel run filters; smoothing needs the record after each step in the same "
                            "task: leave smooth off, or run without n_jobs (--n-jobs, --scheduler)")
    if job.steady is False:
        raise AKFInputError("the time-parallel run needs the steady-state filter ([filter] steady = true or unset)")
    estimator = setup.estimator(steady=True)
    fatigue = setup.fatigue()
    run = RunFiles(job, setup.out, record, n_total, n_total, False, overwrite)
    run.start(estimator)
    record.channel_offsets()                           # once, here: every worker subtracts the same offsets
    firsts = np.cumsum([0] + [t.n_steps for t in record.timings])[:-1]
    folder = os.path.join(run.out, ".pieces")
    os.makedirs(confined(folder), exist_ok=True)
    piece = PieceOutputs(setup.strains, fatigue, n_total, folder, run.writer.fmt, [int(f) for f in firsts],
                         run.decimate)

    def map_pieces(f, items):
        items = list(items)
        return run_tasks(f, items, at_most(n_jobs, len(items)))
    results = estimate_in_parallel(estimator, [FilePiece(record, i) for i in range(len(record.files))], map_pieces,
                                   piece)
    diag = merged(results, run, fatigue)
    os.rmdir(folder)
    setup.notes.append(f"filtered time-parallel: {len(results)} files as one task each")
    metrics = run_metrics(job, estimator, diag, diag.last, n_total, setup.t0, None, None, setup.model, setup.noise_cov,
                          lambda: setup.first_chunk(DEFAULT_CHUNK_STEPS))
    if fatigue is not None:
        metrics["fatigue"] = fatigue.metrics(job.dt)
    result = EstimateResult(job, setup.finished(metrics), {}, record.describe(), setup.notes, 0)
    result.files = run.write_summary(metrics, fatigue)
    if on_result is not None:
        on_result(result)
    run.finish(result.files, metrics, plot, None, job.forces, job.sensors)
    return result


def merged(results, run, fatigue):
    """The pieces' outputs joined in record order: their rows appended to the run's output, their
    diagnostics and fatigue counts merged, the figures' samples kept; the merged diagnostics."""
    diag = None
    for i, r in enumerate(results):
        run.writer.append_part(r["part"], i)
        diag = r["diag"] if diag is None else diag.merge(r["diag"])
        if fatigue is not None:
            fatigue.merge(r["fatigue"], r["steps"])
        for k in ("t", "f", "y", "p"):
            run.kept[k].append(r["kept"][k])
    return diag


class FilePiece:
    """A file of a record, read where its task runs."""

    def __init__(self, record, index):
        self.record, self.index = record, index

    def __call__(self):
        return self.record.read_file(self.index)


class PieceOutputs:
    """What a task of a time-parallel run makes of its file's estimate, where it runs: the tidy rows
    (a part file), its diagnostics and fatigue counts, the samples the figures draw.  Only those
    travel back."""

    def __init__(self, strains, fatigue, n_total, folder, fmt, firsts, decimate):
        self.strains, self.n_total, self.folder, self.fmt = strains, n_total, folder, fmt
        self.firsts, self.decimate = firsts, decimate
        self.fatigue = None if fatigue is None else (fatigue.W, fatigue.curve, fatigue.m, fatigue.n_eq)

    def __call__(self, est, i):
        from core_akf.fatigue import FatigueAccumulator

        step = self.firsts[i]
        path = os.path.join(self.folder, f"part-{i:05d}.{self.fmt}")
        frame = est.to_frame(strains=self.strains)
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


