"""The files of an estimate run in its output folder: the tidy time series (CSV appended, or
Parquet parts), the checkpoint a resumed run continues from, and the figures drawn at the end.

The time series go to ``timeseries.csv`` (appended) or ``timeseries.parquet`` (a folder of one
Parquet file per chunk: a dataset that ``pandas.read_parquet`` reads whole): tidy, one row per
time step and channel (:meth:`core_akf.filter.Estimate.to_frame`), with the reference of a
simulated job.  The checkpoint (``.akf-resume.npz``) holds the filter's state, the running
diagnostics, how much of the output is written and a fingerprint of the job and its files; a
resumed run cuts the output back to the checkpoint and goes on from there.
"""
from __future__ import annotations

import contextlib
import hashlib
import io
import json
import logging
import os
import shutil
import zlib

import numpy as np

from core_akf.checks import AKFInputError, distinct_labels
from core_akf.filter import CheckpointError
from core_akf.outputs import atomic_path, confined, ours, write_csv

from ..figures import draw, plot_estimate, plot_sensors
from .metrics import summary_frame

#: steps per chunk at most, unless the job says ``[measurements] chunk`` (seconds)
DEFAULT_CHUNK_STEPS = 65536
#: bytes a chunk may hold (states, their transforms, channels, output rows)
CHUNK_BYTES = 256e6
#: above this many (strain output x step) rows, ``[output] strains`` left at its default writes none
MAX_STRAIN_ROWS = 2_000_000
#: bytes per tidy row of the time series (time, quantity, channel, unit, estimate, reference, std)
BYTES_PER_ROW = {"csv": 80, "parquet": 25}
#: a time series larger than this is announced before the run
LARGE_OUTPUT_BYTES = 200e6
#: points per channel kept for the figures (the record decimated to at most this)
PLOT_POINTS = 20000
CHECKPOINT = ".akf-resume.npz"


def default_chunk(n_states, n_channels, n_outputs):
    """Steps per chunk: :data:`DEFAULT_CHUNK_STEPS`, fewer for a large model so that a chunk holds
    about :data:`CHUNK_BYTES` (about four copies of the augmented states of ``n_states``, the
    channels and a tidy output row of six columns per written channel), at least 1024."""
    per_step = 8 * (4 * n_states + 4 * n_channels + 6 * n_outputs)
    return int(min(DEFAULT_CHUNK_STEPS, max(1024, CHUNK_BYTES // per_step)))


def listed_strain_outputs(job, structure):
    """Indices of the strain outputs that ``[output] strains`` lists (None where it lists none or
    says "all"), each checked to be an output of ``structure`` and listed once.

    Parameters
    ----------
    job : Job
    structure : Structure

    Returns
    -------
    list of int or None
    """
    wanted = job.spec.output.strains if job.spec.output is not None else None
    if wanted is None or wanted == "all":
        return None
    return structure.strain_label_index(distinct_labels(wanted, structure.n_strain, "[output] strains",
                                                        "strain outputs"))


def strain_outputs(job, structure, n_steps, notes, warnings=None, out=None):
    """Indices of the strain outputs whose histories are written: ``[output] strains``, or all of
    them unless that is more than :data:`MAX_STRAIN_ROWS` rows (then none, with a note) when the
    job leaves it at its default.  A time series that will be larger than
    :data:`LARGE_OUTPUT_BYTES` is announced before the run (logged and added to ``warnings``); one
    more than twice the free space of the disk of ``out`` is refused (:func:`check_free_space`)."""
    wanted = job.spec.output.strains if job.spec.output is not None else None
    if wanted is None:
        if structure.n_strain * n_steps <= MAX_STRAIN_ROWS:
            index = list(range(structure.n_strain))
        else:
            notes.append(f"strain histories not written ({structure.n_strain} channels x {n_steps} steps); list the "
                         "channels you want in [output] strains (summary.csv has every RMS error of a simulated job)")
            index = []
    elif wanted == "all":
        index = list(range(structure.n_strain))
    else:
        index = listed_strain_outputs(job, structure)
    fmt = job.spec.output.format if job.spec.output is not None and job.spec.output.format else "csv"
    size = n_steps * (len(job.forces) + len(index)) * BYTES_PER_ROW[fmt]
    if size > LARGE_OUTPUT_BYTES and warnings is not None:
        text = (f"timeseries.{fmt} will hold about {size / 1e6:.0f} MB ({len(index)} strain outputs and "
                f"{len(job.forces)} forces x {n_steps} steps): list the channels you need in [output] strains"
                + (", or write format = \"parquet\" (about a third of the size)" if fmt == "csv" else ""))
        if out is not None:
            check_free_space(out, size, text.split(":")[0])
        logging.getLogger("akf").warning("akf: warning: " + text)
        warnings.append(text)
    return index


def check_free_space(out, size, what):
    """Refuse a run whose output (``size`` bytes, an estimate within a factor of about 1.5) is more
    than twice the free space of the disk that holds the folder ``out``: it would fill the disk.

    Parameters
    ----------
    out : str
        The output folder (it need not exist yet: its nearest existing parent is asked).
    size : float
        Estimated bytes to be written.
    what : str
        What will be written, for the message.
    """
    where = os.path.abspath(out)
    while not os.path.isdir(where) and os.path.dirname(where) != where:
        where = os.path.dirname(where)
    try:
        free = shutil.disk_usage(where).free
    except OSError:
        return
    if size > 2 * free:
        raise AKFInputError(f"{what}, but the disk of {out} has {free / 1e6:.0f} MB free: list fewer channels in "
                            "[output] strains, write format = \"parquet\", or write elsewhere with --out")


class TimeseriesWriter:
    """Tidy rows appended chunk by chunk, to CSV or to Parquet parts; cut back on resume."""

    def __init__(self, out, fmt):
        self.fmt = fmt
        self.path = os.path.join(out, "timeseries.csv" if fmt == "csv" else "timeseries.parquet")
        self.position = 0        # CSV: bytes written; Parquet: parts written
        self.crc = 0             # CRC-32 of everything written, in order (checked on resume)

    def start(self, position=0, crc=None):
        """Begin anew (0) or cut the output back to a checkpoint's ``position``, whose contents must
        have the CRC-32 ``crc`` the checkpoint recorded (an output edited or cut since is refused).
        Nothing is written or deleted through a symbolic link that leads out of the output folder,
        and a file with other hard links (a backup made with ``cp -al``) is replaced, never changed."""
        confined(self.path)
        if self.fmt == "csv":
            if position == 0:
                header = b"time,quantity,channel,unit,estimated,reference,std\n"
                with atomic_path(self.path) as tmp:          # a new file: a hard-linked old one keeps its content
                    with open(tmp, "wb") as fh:
                        fh.write(header)
                position, self.crc = len(header), zlib.crc32(header)
            else:
                if not os.path.exists(self.path) or os.path.getsize(self.path) < position:
                    raise CheckpointError(f"{self.path} is shorter than the checkpoint says: start the run anew")
                self._check(_crc_of_files([self.path], position), crc)
                _own_copy(self.path)
                with open(self.path, "r+b") as fh:
                    fh.truncate(position)
        else:
            if os.path.isfile(self.path):
                os.remove(self.path)
            os.makedirs(self.path, exist_ok=True)
            for name in os.listdir(self.path):
                if name.startswith("part-") and (position == 0 or int(name[5:10]) >= position):
                    os.remove(os.path.join(self.path, name))
            parts = [self._part(i) for i in range(position)]
            if position and not all(os.path.exists(p) for p in parts):
                raise CheckpointError(f"{self.path} lacks parts the checkpoint says were written: start the run anew")
            self.crc = 0 if not position else self._check(_crc_of_files(parts), crc)
        self.position = position

    def _check(self, found, crc):
        """``found``, the CRC-32 of the output up to the checkpoint, if it is the recorded ``crc``."""
        if crc is not None and found != int(crc):
            raise CheckpointError(f"{self.path} was changed after the checkpoint was written (what it holds up to the "
                                  "checkpoint is not what the run wrote): resuming would mix it into the result; start "
                                  "anew with --overwrite")
        self.crc = found
        return found

    def _part(self, index):
        return os.path.join(self.path, f"part-{index:05d}.parquet")

    def append_part(self, part, index):
        """Move a part written elsewhere (a task of a time-parallel run) to the end of the output."""
        confined(self.path)
        if self.fmt == "csv":
            _own_copy(self.path)
            with open(self.path, "ab") as fh, open(part, "rb") as src:
                while block := src.read(1 << 20):
                    fh.write(block)
                    self.crc = zlib.crc32(block, self.crc)
            os.remove(part)
            self.position = os.path.getsize(self.path)
        else:
            os.replace(part, self._part(self.position))
            self.crc = _crc_of_files([self._part(self.position)], crc=self.crc)
            self.position += 1

    def write(self, frame):
        confined(self.path)
        if self.fmt == "csv":
            buffer = io.BytesIO()
            write_rows(frame, buffer)
            data = buffer.getvalue()
            _own_copy(self.path)
            with open(self.path, "ab") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
            self.crc = zlib.crc32(data, self.crc)
            self.position = os.path.getsize(self.path)
        else:
            with atomic_path(self._part(self.position)) as tmp:
                frame.to_parquet(tmp, index=False)
            self.crc = _crc_of_files([self._part(self.position)], crc=self.crc)
            self.position += 1


def _own_copy(path):
    """Make ``path`` a file of its own before it is changed in place: a file with other hard links
    (an rsnapshot or ``cp -al`` backup) is copied and the copy renamed over it, so the links keep
    the old content."""
    if os.path.exists(path) and os.stat(path).st_nlink > 1:
        with atomic_path(path) as tmp:
            shutil.copyfile(path, tmp)


def _crc_of_files(paths, size=None, crc=0):
    """CRC-32 of the files' bytes in order (the first ``size`` bytes of a single file)."""
    for path in paths:
        left = size
        with open(path, "rb") as fh:
            while left is None or left > 0:
                block = fh.read(1 << 20 if left is None else min(1 << 20, left))
                if not block:
                    break
                crc = zlib.crc32(block, crc)
                if left is not None:
                    left -= len(block)
    return crc


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
_CHECKPOINT_KEYS = ("job", "files", "next_step", "position", "output_crc", "chunk", "plot_t", "plot_f", "plot_y",
                    "plot_p", "checksum")


def _checksum(arrays):
    """SHA-256 over a checkpoint's arrays (names, types, shapes and bytes, in name order)."""
    h = hashlib.sha256()
    for name in sorted(k for k in arrays if k != "checksum"):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


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
    if str(saved["checksum"]) != _checksum(saved):
        raise CheckpointError(f"the checkpoint {path} was changed after it was written (its checksum does not match "
                              "its contents): it cannot be continued; start anew with --overwrite")
    for k, v in saved.items():
        if v.dtype.kind != "f" or (k == "z" and not bool(saved.get("started", True))):   # z: NaN before the first step
            continue
        # measurements and what is carried with them may hold missing samples (NaN), never inf
        if k.startswith("fault_"):          # the fault tests' bookkeeping (the extremes start at +-inf)
            continue
        bad = np.isinf(v) if k in ("plot_y", "plot_p") or k.startswith("lag_held_") else ~np.isfinite(v)
        if bad.any():
            raise CheckpointError(f"the checkpoint {path} holds NaN or infinite values in {k!r}: it cannot be "
                                  "continued; start anew with --overwrite")
    return saved


class RunFiles:
    """The files of one run in an output folder: the tidy writer, the checkpoint and the decimated
    record kept for the figures."""

    def __init__(self, job, out, record, n_total, chunk, resume, overwrite):
        self.job, self.out, self.record, self.chunk = job, os.fspath(out), record, chunk
        self.resume, self.overwrite = resume, overwrite
        os.makedirs(confined(self.out), exist_ok=True)
        fmt = (job.spec.output.format if job.spec.output is not None else None) or "csv"
        self.writer = TimeseriesWriter(self.out, fmt)
        self.path = os.path.join(self.out, CHECKPOINT)
        for name in (os.path.basename(self.writer.path), CHECKPOINT, "summary.csv", "fatigue.csv", "data_quality.csv"):
            ours(confined(os.path.join(self.out, name)))   # before the work, not after it: a file of the user's is kept
        self.decimate = max(1, -(-n_total // PLOT_POINTS))
        self.kept = {"t": [], "f": [], "y": [], "p": []}
        self.reference = []           # the decimated true forces of a simulated record
        self.saved = None
        self.fatigue = None           # the FatigueRun whose figure finish() draws
        self.checkpointed = 0         # the step the last checkpoint continues from (0: none yet)

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
        other = json.loads(str(saved["job"])).get("name")
        if other != self.job.name:
            raise CheckpointError(f"the checkpoint in {out} was written by another job ({other!r}, not "
                                  f"{self.job.name!r}): give this job an output folder of its own, or start anew there "
                                  "with --overwrite")
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
        self.writer.start(int(saved["position"]), int(saved["output_crc"]))
        self.kept = {k: [saved[f"plot_{k}"]] for k in ("t", "f", "y", "p", "s") if f"plot_{k}" in saved}
        self.saved = saved
        self.checkpointed = int(saved["next_step"])
        return self.checkpointed

    def restore_diagnostics(self, diag, est):
        try:
            diag.restore(self.saved, est)
        except (KeyError, ValueError) as exc:
            raise CheckpointError(f"the checkpoint {self.path} lacks the running diagnostics ({exc}); start anew "
                                  "with --overwrite") from None

    def write(self, est, strains, sim, step):
        """Append a chunk's rows (the strain outputs ``strains``, with the truth ``sim`` from
        ``step``) and keep its decimated signals for the figures."""
        self.writer.write(est.to_frame(strains=strains, reference=sim, start=step))
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
        """Save the run's state after step ``next_step`` (its output written up to there)."""
        state = estimator.state() | diag.state() | extra | {
            "next_step": np.array(next_step), "position": np.array(self.writer.position),
            "output_crc": np.array(self.writer.crc, dtype=np.int64),
            "job": np.array(self.spec), "files": np.array(self.data_files), "chunk": np.array(self.chunk)} | {
            f"plot_{k}": np.concatenate(v) if k == "t" else np.vstack(v) for k, v in self.kept.items()}
        state["checksum"] = np.array(_checksum(state))
        with atomic_path(self.path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, **state)
        self.checkpointed = int(next_step)

    def after_disk_full(self, exc, n_total):
        """What a run that filled the disk leaves: its partial time series and checkpoint when a
        checkpoint lets ``--resume`` go on from them, else nothing (both removed).  Returns the
        message that says which."""
        where = os.path.basename(self.writer.path)
        if self.checkpointed:
            return (f"the disk is full ({exc.strerror or exc}; writing into {self.out}): {where} (partial) and the "
                    f"checkpoint {CHECKPOINT} are kept, so that --resume goes on from step {self.checkpointed} of "
                    f"{n_total} once there is space; the other files of this run were not written")
        removed = []
        for path in (self.writer.path, self.path):
            if os.path.isdir(path):
                shutil.rmtree(path, ignore_errors=True)
                removed.append(os.path.basename(path))
            elif os.path.lexists(path):
                with contextlib.suppress(OSError):
                    os.remove(path)
                    removed.append(os.path.basename(path))
        return (f"the disk is full ({exc.strerror or exc}; writing into {self.out}) before the run's first checkpoint: "
                f"the partial files it started were removed ({', '.join(removed) or 'none'}); free space and run again")

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

    def write_table(self, name, frame):
        """Write a table of the run (CSV) into the output folder; returns its path."""
        path = os.path.join(self.out, name)
        write_csv(frame, path)
        return path

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
                from ..figures import plot_fatigue

                frame = self.fatigue.frame(self.job.dt)
                damaged = bool((frame["damage"] > 0).any())       # else every range is below the cut-off: the DEL
                draw(files, "fatigue_figure", metrics["warnings"], plot_fatigue, self.job.structure, frame["channel"],
                     (frame["damage"] if damaged else frame["del_MPa"]).to_numpy(),
                     os.path.join(self.out, "fatigue.png"),
                     f"{title}: fatigue of the estimated stresses ({self.fatigue.curve.name}"
                     + ("" if damaged else "; every range below its cut-off: no damage") + ")", sensors,
                     "Miner's damage" if damaged else f"DEL (MPa, m = {self.fatigue.m:g})")
        if os.path.exists(self.path):
            os.remove(self.path)        # a link is removed, never what it points to
