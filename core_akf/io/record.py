"""A measured record: one file or many (a folder, a glob pattern, a list), its channels mapped to
sensors and converted to SI, delivered in chunks of a fixed number of steps.

>>> rec = Record("run-*.tdms", ["strain:13", "acc:8:y"],                    # doctest: +SKIP
...              channels={"SG13": "strain:13", "ACC_8Y": "acc:8:y"},
...              units={"SG13": "microstrain", "ACC_8Y": "g"}, invert=["ACC_8Y"], remove_offset=1.0)
>>> for first_step, Y in rec.chunks(65536):                                 # doctest: +SKIP
...     ...                                                                 # Y (k, 2) in m/m, m/s^2

The files are put in time order and checked to join: the same time step, each file starting a
whole number of steps after the previous one ends (an overlap or a gap off the grid is an error
naming both files; a gap on it is missing samples, up to ``max_gap``).  The
chunks are cut from the joined record, so a record split over many files gives the same chunks
as the joined file.
"""
from __future__ import annotations

import glob
import os
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..checks import AKFInputError, FloatArray, Layout, Time, is_real
from ..sensors import MAX_READABLE, SENSOR_NAMES, UNITS, as_layout, readable_limits
from .readers import TIME_GRID_RTOL, EmptyFileError, formats, open_file, reader_class
from .units import conversion, is_bridge_unit, is_unset

#: a strain channel whose RMS exceeds this (m/m) is not in SI units: 1 % is five times the yield
#: strain of structural steel, far beyond the elastic range every model here assumes
MAX_PLAUSIBLE_STRAIN = 0.01
#: a channel exactly constant over a chunk this long is disconnected or saturated
_CONSTANT_MIN_STEPS = 16


def record_files(spec: str | os.PathLike | Sequence[str | os.PathLike]) -> list[str]:
    """The files of a record.

    Parameters
    ----------
    spec : str, os.PathLike or list of those
        A path, a glob pattern, a folder (every file of a registered format in it) or a list of
        those.

    Returns
    -------
    list of str
        Sorted by name (:class:`Record` orders them by time).

    Examples
    --------
    >>> import os, tempfile
    >>> folder = tempfile.mkdtemp()
    >>> for name in ("b.csv", "a.csv", "notes.md"):
    ...     open(os.path.join(folder, name), "w").close()
    >>> [os.path.basename(f) for f in record_files(folder)]      # files of a registered format, by name
    ['a.csv', 'b.csv']
    """
    if not isinstance(spec, (str, os.PathLike, list, tuple)):
        raise AKFInputError(f"the record's files must be a path, a glob pattern, a folder or a list of those; got "
                            f"{type(spec).__name__}")
    specs = [spec] if isinstance(spec, (str, os.PathLike)) else list(spec)
    if not specs:
        raise AKFInputError("no measurement files given")
    out = []
    known = tuple(e for exts in formats().values() for e in exts)
    for s in specs:
        s = os.fspath(s)
        if os.path.isdir(s):
            found = sorted(os.path.join(s, f) for f in os.listdir(s) if f.lower().endswith(known))
            if not found:
                raise AKFInputError(f"measurement folder {s!r} has no data files ({', '.join(known)})")
        elif glob.has_magic(s):
            found = sorted(f for f in glob.glob(s) if os.path.isfile(f))
            if not found:
                raise AKFInputError(f"no measurement files match {s!r}")
        else:
            if not os.path.exists(s):
                raise AKFInputError(f"measurement file {s!r} not found")
            found = [s]
        out += found
    if len(set(out)) != len(out):
        raise AKFInputError("a measurement file is listed twice: " + ", ".join(sorted({f for f in out if out.count(f) > 1})))
    return out


@dataclass(frozen=True)
class Channel:
    """One sensor's source.

    Attributes
    ----------
    sensor : str
        The sensor label ("strain:13").
    name : str
        The file channel.
    unit : str
        The unit the channel is recorded in.
    convert : Conversion
        Its conversion to SI.
    sign : float
        +1, or -1 for an inverted channel.
    stated : str or None
        The unit the file states for the channel (None: it states none); ``unit`` is the one given
        instead, if any.
    """

    sensor: str
    name: str
    unit: str
    convert: object
    sign: float
    stated: str | None = None


def _si(block, sources):
    """A block of raw samples in SI: each channel converted and signed."""
    si = np.empty(block.shape)
    for j, s in enumerate(sources):
        si[:, j] = s.sign * s.convert(block[:, j])
    return si


#: the longest gap between a record's files the filter predicts through (s)
MAX_GAP = 60.0


@dataclass(frozen=True)
class Gap:
    """Steps missing between two files of a record.

    Attributes
    ----------
    file : int
        The file after the gap (0-based, time order).
    start : float
        Time of the first missing step (s).
    steps : int
        Steps missing.
    restart : bool
        Longer than the record's ``max_gap``: the filter restarts after it.
    """

    file: int
    start: float
    steps: int
    restart: bool


def _aligned(blocks, size):
    """Blocks ``(step, rows)`` joined into chunks cut at the steps that are multiples of ``size``;
    a jump in the steps ends a chunk early."""
    pending, held, first = [], 0, None
    for step, block in blocks:
        if first is not None and step != first + held:
            if held:
                yield first, np.vstack(pending)
            pending, held, first = [], 0, None
        if first is None:
            first = step
        pending.append(block)
        held += block.shape[0]
        while held and first + held >= (first // size + 1) * size:
            cut = (first // size + 1) * size - first
            joined = np.vstack(pending) if len(pending) > 1 else pending[0]
            yield first, joined[:cut]
            rest = joined[cut:]
            first += cut
            pending, held = ([rest] if rest.shape[0] else []), rest.shape[0]
    if held:
        yield first, np.vstack(pending)


class Record:
    """A measured record for a sensor layout, from one file or many.

    Parameters
    ----------
    files : str, os.PathLike or list of those
        A path, glob pattern, folder or list of those (:func:`record_files`).
    sensors : sequence of sensor specs
        The layout (labels such as ``"strain:13"``): the columns of every chunk, in order.
    channels : dict, optional
        File channel -> sensor label; default: each sensor's channel is named like the sensor.
    units : dict, optional
        File channel -> unit (``"microstrain"``, ``"g"``, ``"mV/V"``, ...); default the unit the
        file records, else SI.  A channel without a unit in one file where another file states one
        is an error; files that state different units are each converted by their own and named in
        ``unit_warnings`` (a list of str).  A file without a data row among others is skipped
        and named in :attr:`warnings`.
    gauge_factor : float or dict, optional
        Gauge factor of bridge outputs (mV/V), one for all or per channel.
    bridge : str or dict, optional
        "quarter" (default), "half" or "full", one for all or per channel.
    invert : sequence of str
        Channels whose sign is flipped.
    remove_offset : bool or float
        False; True (subtract each channel's mean over the record: one extra pass); or a time in
        s (subtract the mean over the record's first that many seconds: zero drift of gauges
        measured at rest).
    format : str, optional
        The file format (default from the extension).
    time_column : str
        The time column or channel.
    group : str, optional
        TDMS or HDF5 group holding the channels.
    max_gap : float
        The longest gap between two files (s) the filter predicts through (its steps come as
        missing samples); after a longer one it restarts from its prior (:attr:`gaps`).

    Examples
    --------
    A CSV record with its own channel names and units:

    >>> import os, tempfile
    >>> import numpy as np, pandas as pd
    >>> folder = tempfile.mkdtemp()
    >>> t = np.arange(100) * 1e-3
    >>> pd.DataFrame({"time": t, "SG13": 5.0 * np.sin(20 * t), "ACC8": 0.1 * np.cos(20 * t)}).to_csv(
    ...     os.path.join(folder, "run1.csv"), index=False)
    >>> rec = Record(os.path.join(folder, "*.csv"), ["strain:13", "acc:8:y"],
    ...              channels={"SG13": "strain:13", "ACC8": "acc:8:y"}, units={"SG13": "microstrain", "ACC8": "g"})
    >>> rec.describe()
    ['strain:13 <- SG13 [microstrain]', 'acc:8:y <- ACC8 [g]']
    >>> t, Y = rec.read()                       # SI: m/m and m/s^2
    >>> Y.shape, round(float(Y[0, 1]), 5)
    ((100, 2), 0.98067)
    """

    def __init__(self, files: str | os.PathLike | Sequence[str | os.PathLike], sensors: Layout, *,
                 channels: Mapping[str, str] | None = None, units: Mapping[str, str] | None = None,
                 gauge_factor: float | Mapping[str, float] | None = None, bridge: str | Mapping[str, str] | None = None,
                 invert: Sequence[str] = (), remove_offset: bool | float = False, format: str | None = None,
                 time_column: str = "time", group: str | None = None, max_gap: float = MAX_GAP):
        self.layout = as_layout(sensors)
        self._limits = readable_limits(self.layout)
        self.labels = [s.label for s in self.layout]
        paths = record_files(files)
        classes = {reader_class(p, format) for p in paths}
        if len(classes) > 1:
            raise AKFInputError("the record's files have different formats (" + ", ".join(sorted(c.format for c in classes))
                                + "); give files of one format")
        self.channels_map = self._channel_map(channels)
        self._open = lambda p: _reader_of(open_file(p, format, time_column, group), self.channels_map)
        if units is not None and not isinstance(units, Mapping):
            raise AKFInputError(f"units must map file channels to units, e.g. {{'SG13': 'microstrain'}}; got "
                                f"{type(units).__name__}")
        self.units_given = dict(units or {})
        factors = ({f"gauge_factor[{k!r}]": v for k, v in gauge_factor.items()} if isinstance(gauge_factor, dict)
                   else {"gauge_factor": gauge_factor})
        for name, value in factors.items():
            if value is not None and not is_real(value):
                raise AKFInputError(f"{name} must be a number (a gauge factor, about 2), got {value!r}")
        self.gauge_factor, self.bridge = gauge_factor, bridge
        self.invert = [invert] if isinstance(invert, str) else list(invert or ())      # one channel, or several
        unknown = [c for c in [*self.units_given, *self.invert] if c not in self.channels_map]
        if isinstance(gauge_factor, dict):
            unknown += [c for c in gauge_factor if c not in self.channels_map]
        if isinstance(bridge, dict):
            unknown += [c for c in bridge if c not in self.channels_map]
        if unknown:
            raise AKFInputError(f"units/invert/gauge_factor/bridge name channel(s) {sorted(set(unknown))} that are not "
                                f"mapped to a sensor; mapped: {sorted(self.channels_map)}")
        if isinstance(remove_offset, bool) or remove_offset is None:
            self.remove_offset = bool(remove_offset)
        elif not (is_real(remove_offset) and np.isfinite(remove_offset) and remove_offset > 0):
            raise AKFInputError(f"remove_offset must be true, false or a positive time (s), got {remove_offset!r}")
        else:
            self.remove_offset = float(remove_offset)
        if not (is_real(max_gap) and not np.isnan(max_gap) and max_gap >= 0):
            raise AKFInputError(f"max_gap must be a time >= 0 (s), got {max_gap!r}")
        self.max_gap = float(max_gap)
        self._read_files(paths)
        order = np.argsort([t.start for t in self.timings], kind="stable")
        self.files = [self.files[i] for i in order]
        self.timings = [self.timings[i] for i in order]
        self.sources = [self.sources[i] for i in order]
        self._check_joins()
        self._check_units()
        self.offsets = None

    def _read_files(self, paths):
        """Each file's time grid and sources (``files``, ``timings``, ``sources``), in the order
        given; a file without a data row among others skipped (``empty_files``)."""
        self.files, self.timings, self.sources, self.empty_files = [], [], [], []
        for p in paths:
            reader = self._open(p)
            try:
                timing = reader.timing()
            except EmptyFileError:
                timing = None
            if timing is None or timing.n_steps == 0:
                if len(paths) == 1:
                    raise EmptyFileError(f"{p}: 0 data rows; a record needs at least two time steps")
                self.empty_files.append(p)          # a DAQ session stopped at once: nothing to join
                continue
            self.files.append(p)
            self.timings.append(timing)
            self.sources.append(self._resolve(reader))
            del reader
        if not self.files:
            raise EmptyFileError(f"none of the record's {len(paths)} files has a data row ({paths[0]}, ...)")

    # ---------------------------------------------------------------------------- channels
    def _channel_map(self, channels):
        """file channel -> sensor label, checked: every sensor mapped once, no unknown sensor."""
        if channels is None:
            return {label: label for label in self.labels}
        if not isinstance(channels, dict):
            raise AKFInputError(f"channels must map file channels to sensors, e.g. {{'SG13': 'strain:13'}}; got "
                                f"{type(channels).__name__}")
        mapped = {}
        for name, sensor in channels.items():
            label = as_layout([sensor])[0].label
            if label not in self.labels:
                raise AKFInputError(f"channel {name!r} is mapped to {sensor!r}, which is not among the job's sensors "
                                    f"{self.labels}")
            if label in mapped.values():
                other = next(k for k, v in mapped.items() if v == label)
                raise AKFInputError(f"sensor {label!r} is mapped twice: from channels {other!r} and {name!r}")
            mapped[name] = label
        unmapped = [s for s in self.labels if s not in mapped.values()]
        if unmapped:
            raise AKFInputError(f"sensor(s) {unmapped} have no channel: map a file channel to each, e.g. "
                                f"channels = {{\"CHANNEL\" = \"{unmapped[0]}\"}}")
        return mapped

    def _per_channel(self, value, name):
        return value.get(name) if isinstance(value, dict) else value

    def _resolve(self, reader):
        """The sources of the sensors (in layout order) in one file, with their conversions."""
        by_sensor = {v: k for k, v in self.channels_map.items()}
        missing = [by_sensor[s] for s in self.labels if by_sensor[s] not in reader.channels()]
        if missing:
            raise AKFInputError(f"{reader.path}: no channel(s) {missing}; the file has {reader.channels()}")
        file_units = reader.units()
        out = []
        for sensor, label in zip(self.layout, self.labels):
            name = by_sensor[label]
            recorded = file_units.get(name)
            stated = None if is_unset(recorded) else str(recorded)
            unit = self.units_given.get(name, stated)
            gf = self._per_channel(self.gauge_factor, name)
            br = self._per_channel(self.bridge, name)
            explicit = any(isinstance(v, dict) and name in v for v in (self.gauge_factor, self.bridge))
            if not explicit and not (sensor.kind == "strain" and is_bridge_unit(unit)):
                gf = br = None      # a record-wide gauge factor and bridge concern the bridge channels only
            conv = conversion(unit, sensor.kind, f"{name} ({os.path.basename(reader.path)})", gf, br)
            out.append(Channel(label, name, conv.unit, conv, -1.0 if name in self.invert else 1.0, stated))
        return out

    def _check_units(self):
        """Each channel's unit across the files: one file that states none where another states one
        is an error (it would be read as SI, silently); two stated units are converted each by its
        own and named in :attr:`unit_warnings`."""
        self.unit_warnings = []
        if len(self.files) < 2:
            return
        for j, name in enumerate(s.name for s in self.sources[0]):
            if name in self.units_given:
                continue
            stated = {}         # conversion (None: no unit stated) -> (unit as stated, first file)
            for path, sources in zip(self.files, self.sources):
                c = sources[j].convert
                key = None if sources[j].stated is None else (c.scale, c.bridge, c.gauge_factor)
                stated.setdefault(key, (sources[j].stated, path))
            if len(stated) < 2:
                continue
            shown = ", ".join(f"{'no unit' if u is None else repr(u)} in {os.path.basename(p)}"
                              for u, p in list(stated.values())[:4]) + (", ..." if len(stated) > 4 else "")
            if None in stated:
                raise AKFInputError(f"channel {name!r} ({self.sources[0][j].sensor}) states {shown}: a file without a "
                                    f"unit would be read as SI ({UNITS[self.layout[j].kind]}); "
                                    f"give the channel's unit: units = {{{name!r}: \"...\"}}")
            self.unit_warnings.append(f"channel {name!r} ({self.sources[0][j].sensor}) is recorded in different units: "
                                      f"{shown}; each file is converted by its own (give units to override)")

    # ---------------------------------------------------------------------------- time
    def _check_joins(self):
        """The files' places on one time grid: ``first_steps`` (the record step of each file's first
        row) and ``gaps``; an error for a file at another step, an overlap or a gap off the grid."""
        t0 = self.timings[0]
        self.first_steps, self.gaps = [0], []
        for i, ((fa, a), (fb, b)) in enumerate(zip(zip(self.files, self.timings), zip(self.files[1:], self.timings[1:]))):
            if abs(b.dt - t0.dt) * max(b.n_steps, 1) > TIME_GRID_RTOL * t0.dt:     # drifts off the grid
                raise AKFInputError(f"{fb}: time step {b.dt:.9g} s differs from {t0.dt:.9g} s of {self.files[0]}")
            delta = b.start - a.end
            steps = delta / t0.dt
            if abs(b.start - a.start) <= TIME_GRID_RTOL * t0.dt and b.n_steps == a.n_steps and a.n_steps:
                try:
                    same = os.path.samefile(fa, fb)
                except OSError:
                    same = False
                raise AKFInputError(f"{fa} and {fb} hold the same time span ({a.n_steps} steps from {a.start:.9g} s): "
                                    + ("they are one file (a link to it)" if same else "is one a copy of the other?")
                                    + "; remove one from the record")
            if delta < -TIME_GRID_RTOL * t0.dt or abs(steps - round(steps)) > TIME_GRID_RTOL:
                what = (f"an overlap of {-delta:.6g} s ({-steps:.6g} steps)" if delta < 0
                        else f"a gap of {delta:.6g} s ({steps:.6g} steps, not a whole number)")
                raise AKFInputError(f"the record has {what} between {fa} (ends at {a.end - a.dt:.9g} s, next step "
                                    f"{a.end:.9g} s) and {fb} (starts at {b.start:.9g} s); files must join step by "
                                    "step or leave whole steps out: remove or fix the files in question")
            gap = int(round(steps))
            if gap:
                self.gaps.append(Gap(i + 1, a.end, gap, gap * t0.dt > self.max_gap))
            self.first_steps.append(self.first_steps[-1] + self.timings[i].n_steps + gap)

    def gap_notes(self) -> list[str]:
        """One line per gap between files: where, how long, and what the filter does there.

        Returns
        -------
        list of str
        """
        return [f"a gap of {g.steps * self.dt:.6g} s ({g.steps} steps) from {g.start:.9g} s, before "
                f"{os.path.basename(self.files[g.file])}: " + ("longer than max_gap = "
                f"{self.max_gap:g} s, the filter restarts from its prior after it" if g.restart else
                "the filter predicts through it (its steps are missing samples)") for g in self.gaps]

    @property
    def warnings(self) -> list[str]:
        """What a reader of the results should know of the record's files: files skipped for having
        no data row, channels recorded in different units (:attr:`unit_warnings`)."""
        return [f"{p}: no data row (an empty file); skipped" for p in self.empty_files] + list(self.unit_warnings)

    def rate_notes(self) -> list[str]:
        """Channels at rates of their own (:meth:`MixedRecord.rate_notes`): none in a record whose
        files hold all its channels at one rate.

        Returns
        -------
        list of str
        """
        return []

    @property
    def dt(self):
        return self.timings[0].dt

    @property
    def start(self):
        return self.timings[0].start

    @property
    def n_steps(self):
        """Steps from the record's first to its last, gaps between files included."""
        return self.first_steps[-1] + self.timings[-1].n_steps

    @property
    def n_filtered(self):
        """Steps the filter runs: :attr:`n_steps` without the gaps it restarts after."""
        return self.n_steps - sum(g.steps for g in self.gaps if g.restart)

    def check_dt(self, dt: float) -> None:
        """Check the record's time step.

        Parameters
        ----------
        dt : float
            The job's time step (s).

        Raises
        ------
        AKFInputError
            Unless the record's step matches ``dt`` to :data:`TIME_GRID_RTOL`.
        """
        if abs(self.dt - dt) > TIME_GRID_RTOL * dt:
            raise AKFInputError(f"{self.files[0]}: sampling interval {self.dt:.9g} s (median step) does not match the job's "
                                f"dt = {dt:.9g} s ({self.dt / dt:.4g} x dt)")

    # ---------------------------------------------------------------------------- data
    def _raw_chunks(self, size, start=0):
        """SI chunks without offset removal, cut at the record steps that are multiples of ``size``,
        from step ``start`` (a multiple of ``size``; the files before it are not read).  A gap up to
        ``max_gap`` comes as missing samples (NaN); the chunks skip a longer one (the next chunk's
        first step tells)."""
        return _aligned(self._blocks(size, start), size)

    def _blocks(self, size, start):
        """``(record step, rows)`` of the data from ``start`` on, in order, a gap's NaN rows included."""
        restarts = {g.file: g for g in self.gaps}
        for i, (path, sources, timing) in enumerate(zip(self.files, self.sources, self.timings)):
            first = self.first_steps[i]
            if first + timing.n_steps <= start:
                continue
            gap = restarts.get(i)
            if gap is not None and not gap.restart and first > start:     # predicted through: missing samples
                for a in range(max(first - gap.steps, start), first, size):      # a long gap: chunk by chunk
                    yield a, np.full((min(a + size, first) - a, len(self.labels)), np.nan)
            drop = max(start - first, 0)          # rows of this file before ``start``
            step = first + drop
            reader = self._open(path)
            for block in reader.chunks([s.name for s in sources], size):
                if drop:
                    block, drop = block[drop:], max(drop - block.shape[0], 0)
                    if not block.shape[0]:
                        continue
                Y = _si(block, sources)
                self._check_readable(step, Y)
                yield step, Y
                step += block.shape[0]
            del reader

    def _offsets(self, size):
        if self.remove_offset is False:
            return np.zeros(len(self.labels))
        if self.offsets is None:
            n = self.n_steps if self.remove_offset is True else int(round(self.remove_offset / self.dt))
            if n < 1 or n > self.n_steps:
                raise AKFInputError(f"remove_offset = {self.remove_offset!r} s is not within the record "
                                    f"({self.n_steps * self.dt:.6g} s)")
            total, count, seen = np.zeros(len(self.labels)), 0, np.zeros(len(self.labels), int)
            for _, Y in self._raw_chunks(size):
                take = Y[:n - count]
                total += np.nansum(take, axis=0)
                seen += np.count_nonzero(~np.isnan(take), axis=0)
                count += take.shape[0]
                if count >= n:
                    break
            if not seen.all():
                j = int(np.flatnonzero(seen == 0)[0])
                raise AKFInputError(f"remove_offset: channel {self._named(j)} has no observed sample in the first "
                                    f"{count} steps; there is no offset to remove (set remove_offset to a longer time)")
            self.offsets = total / seen
        return self.offsets

    def chunks(self, size: int = 65536, start: int = 0) -> Iterator[tuple[int, FloatArray]]:
        """The record in chunks, in SI.

        Each chunk is checked: strain plausible in m/m, no channel constant over the chunk.

        Parameters
        ----------
        size : int
            Steps per chunk (the last one shorter).
        start : int
            The first step, a multiple of ``size`` (where a resumed run continues).

        Yields
        ------
        step : int
            The record step of the chunk's first row.
        Y : ndarray (k, m)
            The samples in SI, columns in sensor order.
        """
        if size < 1:
            raise AKFInputError(f"chunk size must be at least one step, got {size}")
        if start % size:
            raise AKFInputError(f"a record is resumed at a multiple of the chunk size {size}, not at step {start}")
        offsets = self._offsets(size)
        for step, Y in self._raw_chunks(size, start):
            Y = Y - offsets
            self._check_chunk(step, Y)
            yield step, Y

    def _check_readable(self, step, Y):
        """Refuse samples beyond what a sensor of the channel's kind reads (:data:`~core_akf.sensors.MAX_READABLE`),
        naming the first: a corrupt value or an overflow code, or the whole channel in another unit."""
        with np.errstate(invalid="ignore"):
            beyond = np.abs(Y) > self._limits                # NaN (missing) is not beyond
        if not beyond.any():
            return
        j = int(np.flatnonzero(beyond.any(axis=0))[0])
        rows = np.flatnonzero(beyond[:, j])
        observed = int(np.count_nonzero(~np.isnan(Y[:, j])))
        kind, unit = self.layout[j].kind, UNITS[self.layout[j].kind]
        where = (f"{rows.size} of {observed} samples of steps {step}..{step + len(Y) - 1}, the first "
                 f"{Y[rows[0], j]:.4g} {unit} at step {step + rows[0]} (t = {self.start + (step + rows[0]) * self.dt:.6g} s)")
        if rows.size * 2 > observed:            # most of the channel: its unit (strain: the RMS check tells)
            if kind == "strain":
                return
            raise AKFInputError(f"channel {self._named(j)}: {where} are beyond what {SENSOR_NAMES[kind]} reads "
                                f"(|x| > {MAX_READABLE[kind]:g} {unit}); is the channel's unit right?")
        raise AKFInputError(f"channel {self._named(j)}: {where} are beyond what {SENSOR_NAMES[kind]} reads "
                            f"(|x| > {MAX_READABLE[kind]:g} {unit}): corrupt values or a data-acquisition "
                            "system's overflow code, not measurements; mark them missing (NaN or an empty cell) in "
                            "the file")

    def _check_chunk(self, step, Y):
        where = f"{os.path.basename(self.files[0])}{' ...' if len(self.files) > 1 else ''}, steps {step}..{step + len(Y) - 1}"
        for j, s in enumerate(self.layout):
            col = Y[:, j]
            col = col[~np.isnan(col)]               # the observed samples
            if col.size >= _CONSTANT_MIN_STEPS and np.ptp(col) == 0:
                raise AKFInputError(f"channel {self._named(j)} is constant ({col[0]:.9g}) over "
                                    f"{col.size} steps ({where}): a disconnected or saturated sensor gives no "
                                    "information; remove it from the job's sensors")
            if s.kind == "strain" and col.size:
                level = float(np.sqrt(np.mean(col ** 2)))
                if level > MAX_PLAUSIBLE_STRAIN:
                    raise AKFInputError(
                        f"strain channel {self._named(j)} has an RMS of {level:.4g} ({where}), "
                        f"impossible in m/m for an elastic structure (> {MAX_PLAUSIBLE_STRAIN:g}); it looks like "
                        f"microstrain: set units={{{self.sources[0][j].name!r}: 'microstrain'}}")

    def _named(self, j):
        """Channel ``j`` for messages: ``'SG13' (strain:13)``, or ``'strain:13'`` if named so."""
        name, label = self.sources[0][j].name, self.labels[j]
        return repr(name) if name == label else f"{name!r} ({label})"

    def observed_counts(self, size: int = 65536) -> np.ndarray:
        """The observed (not missing) samples of every channel over the record: one pass, computed once.

        Parameters
        ----------
        size : int
            Steps read at a time.

        Returns
        -------
        ndarray (m,) of int
        """
        if getattr(self, "_observed", None) is None:
            counts = np.zeros(len(self.labels), int)
            for _, Y in self._raw_chunks(size):
                counts += np.count_nonzero(~np.isnan(Y), axis=0)
            self._observed = counts
        return self._observed

    def channel_offsets(self, size: int = 65536) -> FloatArray:
        """The offset subtracted from each channel (``remove_offset``; zeros without), computed once.

        Parameters
        ----------
        size : int
            Steps read at a time.

        Returns
        -------
        ndarray (m,)
            SI.
        """
        return self._offsets(size)

    def read_file(self, index: int, size: int = 65536) -> FloatArray:
        """One file of the record, in SI, checked as a chunk (the piece a worker reads in a
        time-parallel run, :func:`core_akf.filter.parallel.estimate_in_parallel`).

        Parameters
        ----------
        index : int
            The file (0-based, in time order: :attr:`files`).
        size : int
            Steps read at a time.

        Returns
        -------
        ndarray (k, m)
            The file's samples in SI, columns in sensor order.
        """
        if not 0 <= int(index) < len(self.files):
            raise AKFInputError(f"the record has {len(self.files)} files; there is no file {index}")
        offsets = self._offsets(size)
        sources = self.sources[index]
        reader = self._open(self.files[index])
        blocks = [_si(b, sources) for b in reader.chunks([s.name for s in sources], size)]
        del reader
        Y = (np.vstack(blocks) if blocks else np.empty((0, len(self.labels)))) - offsets
        self._check_chunk(self.first_steps[index], Y)
        return Y

    def read(self, size: int = 65536) -> tuple[Time, FloatArray]:
        """The whole record in memory.

        Parameters
        ----------
        size : int
            Steps read per chunk.

        Returns
        -------
        t : ndarray (N,)
            Time (s); it jumps over a gap longer than ``max_gap``.
        Y : ndarray (N, m)
            Samples in SI, columns in sensor order.
        """
        steps, parts = [], []
        for step, Y in self.chunks(size):
            steps.append(step + np.arange(Y.shape[0]))
            parts.append(Y)
        return self.start + self.dt * np.concatenate(steps), np.vstack(parts)

    def describe(self) -> list[str]:
        """One line per sensor: ``sensor <- channel [unit, sign]`` (for logs and summaries).

        Returns
        -------
        list of str
        """
        return [f"{s.sensor} <- {s.name} [{s.unit}{', inverted' if s.sign < 0 else ''}"
                f"{f', bridge {s.convert.bridge} GF {s.convert.gauge_factor:g}' if s.convert.bridge else ''}]"
                for s in self.sources[0]]


# ------------------------------------------------------------------------------ mixed rates
def open_record(files: str | os.PathLike | Sequence[str | os.PathLike], sensors: Layout, *,
                channels: Mapping[str, str] | None = None, **kw: object) -> Record | MixedRecord:
    """A record whose files hold all its channels (:class:`Record`), or channel sets at their own
    sampling rates in files of their own (:class:`MixedRecord`).

    Parameters
    ----------
    files, sensors, channels, **kw
        As :class:`Record` (``units``, ``invert``, ``gauge_factor`` and ``bridge`` name file
        channels of any of the files).

    Returns
    -------
    Record or MixedRecord

    Examples
    --------
    Accelerometers at 1 kHz in one file, a gauge at 250 Hz in another:

    >>> import os, tempfile
    >>> import numpy as np, pandas as pd
    >>> folder = tempfile.mkdtemp()
    >>> t = np.arange(100) * 1e-3
    >>> pd.DataFrame({"time": t, "acc:8:y": np.cos(20 * t)}).to_csv(os.path.join(folder, "acc.csv"), index=False)
    >>> pd.DataFrame({"time": t[::4], "strain:13": 1e-6 * np.sin(20 * t[::4])}).to_csv(
    ...     os.path.join(folder, "gauge.csv"), index=False)
    >>> rec = open_record(folder, ["acc:8:y", "strain:13"])
    >>> t, Y = rec.read()                   # on the 1 kHz grid, the gauge missing between its samples
    >>> Y.shape, int(np.isnan(Y[:, 1]).sum())
    ((100, 2), 75)
    """
    paths = record_files(files)
    labels = [s.label for s in as_layout(sensors)]
    sensor_of = {name: as_layout([s])[0].label for name, s in channels.items()} if isinstance(channels, dict) else \
        {label: label for label in labels}
    sets = {}
    for p in paths:
        reader = open_file(p, kw.get("format"), kw.get("time_column", "time"), kw.get("group"))
        rates = reader.rate_sets()
        for names in rates:             # a file's channels at rates of their own are sets of their own
            present = tuple(sorted({sensor_of[c] for c in names if c in sensor_of}, key=labels.index))
            if present or len(rates) == 1:
                sets.setdefault(present, []).append(p)
        del reader
    if len(sets) == 1:
        return Record(paths, sensors, channels=channels, **kw)
    seen = {}
    for present, group in sets.items():
        if not present:
            raise AKFInputError(f"{group[0]} holds none of the sensors' channels {labels}")
        for label in present:
            if label in seen:
                raise AKFInputError(f"sensor {label} is in files of two channel sets ({seen[label][0]} and {group[0]}); "
                                    "a record's files either hold all its channels or channel sets of their own")
            seen[label] = group
    lost = [label for label in labels if label not in seen]
    if lost:
        raise AKFInputError(f"sensor(s) {lost} have no channel in any file of the record")
    subs = []
    for present, group in sets.items():
        names = {c for c, label in sensor_of.items() if label in present}
        part = {k: ({c: v for c, v in value.items() if c in names} if isinstance(value, dict) else value)
                for k, value in kw.items()}
        if part.get("invert"):
            part["invert"] = [c for c in part["invert"] if c in names]
        part["max_gap"] = np.inf          # the mixed record predicts through every gap
        sub_channels = {c: s for c, s in channels.items() if c in names} if isinstance(channels, dict) else None
        subs.append(Record(group, list(present), channels=sub_channels, **part))
    return MixedRecord(sensors, subs)


def _ordinal(k: int) -> str:
    """The English ordinal suffix of ``k`` (2 -> "nd", 11 -> "th")."""
    return "th" if 10 <= k % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(k % 10, "th")


def _reader_of(reader, channels_map):
    """``reader`` restricted to the record's channels where its channels come at several rates (a
    channel set of a :class:`MixedRecord` that shares its file with others)."""
    if len(reader.rate_sets()) > 1:
        reader.restrict([c for c in reader.channels() if c in channels_map])
    return reader


class MixedRecord:
    """A record of channel sets at their own sampling rates, each in files of its own (or in
    channels of their own time step inside shared TDMS or HDF5 files).

    The filter steps at the fastest rate; a slower channel is observed at its own samples and
    missing (NaN) in between -- no resampling, no interpolation.  Every rate must divide into the
    fastest one (a whole number of its steps), and every set's first sample lie on its grid.  A
    gap in a set's files is missing samples, however long.

    Parameters
    ----------
    sensors : sequence of sensor specs
        The layout (columns of every chunk, in order).
    parts : list of Record
        One record per channel set.
    """

    def __init__(self, sensors: Layout, parts: list):
        self.layout = as_layout(sensors)
        self.labels = [s.label for s in self.layout]
        self.parts = sorted(parts, key=lambda r: r.dt)
        fastest = self.parts[0]
        self.start = min(r.start for r in self.parts)
        self.columns, self.ratios, self.offsets_steps = [], [], []
        for r in self.parts:
            ratio = r.dt / fastest.dt
            if abs(ratio - round(ratio)) > TIME_GRID_RTOL * max(ratio, 1.0):
                raise AKFInputError(f"channels {', '.join(r.labels)} sample every {r.dt:.6g} s ({1 / r.dt:.6g} Hz), which is "
                                    f"not a whole number of the fastest channels' step {fastest.dt:.6g} s ({1 / fastest.dt:.6g} "
                                    f"Hz; {', '.join(fastest.labels)}): the ratio {ratio:.6g} must be an integer")
            shift = (r.start - self.start) / fastest.dt
            if abs(shift - round(shift)) > TIME_GRID_RTOL:
                raise AKFInputError(f"channels {', '.join(r.labels)} start at {r.start:.9g} s, {shift:.6g} steps of "
                                    f"{fastest.dt:.6g} s after the record's start: not on its time grid")
            self.columns.append([self.labels.index(label) for label in r.labels])
            self.ratios.append(int(round(ratio)))
            self.offsets_steps.append(int(round(shift)))
        self.dt = fastest.dt
        self.files = [f for r in self.parts for f in r.files]
        self.gaps = []
        self._observed = None

    @property
    def n_steps(self) -> int:
        """Steps of the fastest grid from the first sample of any set to the last."""
        return max(o + (r.n_steps - 1) * k + 1 for r, o, k in zip(self.parts, self.offsets_steps, self.ratios))

    @property
    def n_filtered(self) -> int:
        """Steps the filter runs (every gap is predicted through): :attr:`n_steps`."""
        return self.n_steps

    def check_dt(self, dt: float) -> None:
        """Check that the fastest channels sample at the job's time step.

        Parameters
        ----------
        dt : float
            The job's time step (s).
        """
        if abs(self.dt - dt) > TIME_GRID_RTOL * dt:
            rates = ", ".join(f"{', '.join(r.labels)} at {1 / r.dt:.6g} Hz" for r in self.parts)
            raise AKFInputError(f"the record's fastest channels sample every {self.dt:.9g} s, not at the job's dt = "
                                f"{dt:.9g} s ({rates})")

    @property
    def unit_warnings(self) -> list[str]:
        """The channels of every channel set recorded in different units by its files (:attr:`Record.unit_warnings`)."""
        return [w for r in self.parts for w in r.unit_warnings]

    @property
    def warnings(self) -> list[str]:
        """The warnings of every channel set (:attr:`Record.warnings`)."""
        return [w for r in self.parts for w in r.warnings]

    def rate_notes(self) -> list[str]:
        """One line per channel set slower than the fastest: its rate, and how the filter takes it.

        Returns
        -------
        list of str
        """
        fast = 1 / self.dt
        return [f"{', '.join(r.labels)} sample{'s' if len(r.labels) == 1 else ''} at {1 / r.dt:.6g} Hz, every "
                f"{k}{_ordinal(k)} step of the {fast:.6g} Hz grid: the filter takes {'it' if len(r.labels) == 1 else 'them'} "
                "at its own samples (missing in between), without resampling"
                for r, k in zip(self.parts, self.ratios) if k > 1]

    def gap_notes(self) -> list[str]:
        """The gap notes of every channel set (:meth:`Record.gap_notes`).

        Returns
        -------
        list of str
        """
        return [note for r in self.parts for note in r.gap_notes()]

    def describe(self) -> list[str]:
        """One line per sensor, with its rate.

        Returns
        -------
        list of str
        """
        lines = {}
        for r in self.parts:
            for label, line in zip(r.labels, r.describe()):
                lines[label] = f"{line} at {1 / r.dt:.6g} Hz"
        return [lines[label] for label in self.labels]

    def channel_offsets(self, size: int = 65536) -> FloatArray:
        """The offset subtracted from each channel (:meth:`Record.channel_offsets`).

        Parameters
        ----------
        size : int
            Steps read at a time.

        Returns
        -------
        ndarray (m,)
        """
        out = np.zeros(len(self.labels))
        for r, cols in zip(self.parts, self.columns):
            out[cols] = r.channel_offsets(size)
        return out

    def chunks(self, size: int = 65536, start: int = 0) -> Iterator[tuple[int, FloatArray]]:
        """The record in chunks on the fastest grid, NaN where a channel has no sample.

        Parameters
        ----------
        size : int
            Steps per chunk (the last one shorter).
        start : int
            The first step, a multiple of ``size``.

        Yields
        ------
        step : int
            The record step of the chunk's first row.
        Y : ndarray (k, m)
            SI, columns in sensor order.
        """
        if size < 1:
            raise AKFInputError(f"chunk size must be at least one step, got {size}")
        if start % size:
            raise AKFInputError(f"a record is resumed at a multiple of the chunk size {size}, not at step {start}")
        cursors = [_Cursor(r, cols, o, k, size, start) for r, cols, o, k in
                   zip(self.parts, self.columns, self.offsets_steps, self.ratios)]
        for a in range(start, self.n_steps, size):
            Y = np.full((min(a + size, self.n_steps) - a, len(self.labels)), np.nan)
            for c in cursors:
                c.fill(Y, a)
            yield a, Y

    def observed_counts(self, size: int = 65536) -> np.ndarray:
        """The observed samples of every channel (:meth:`Record.observed_counts`).

        Parameters
        ----------
        size : int
            Steps read at a time.

        Returns
        -------
        ndarray (m,) of int
        """
        if self._observed is None:
            self._observed = sum(np.count_nonzero(~np.isnan(Y), axis=0) for _, Y in self.chunks(size))
        return self._observed

    def read(self, size: int = 65536) -> tuple[Time, FloatArray]:
        """The whole record in memory, on the fastest grid.

        Parameters
        ----------
        size : int
            Steps read per chunk.

        Returns
        -------
        t : ndarray (N,)
            Time (s).
        Y : ndarray (N, m)
            SI, NaN where a channel has no sample.
        """
        parts = [Y for _, Y in self.chunks(size)]
        Y = np.vstack(parts)
        return self.start + self.dt * np.arange(Y.shape[0]), Y

    def read_file(self, index: int, size: int = 65536) -> FloatArray:
        """Not for a record of several rates (it is read as a whole).

        Parameters
        ----------
        index : int
            The file.
        size : int
            Steps read at a time.

        Returns
        -------
        ndarray
            Never: it raises.

        Raises
        ------
        AKFInputError
            Always.
        """
        raise AKFInputError("a record of channels at different rates is read as a whole, not file by file")


class _Cursor:
    """One channel set of a :class:`MixedRecord`: its chunks placed on the fastest grid."""

    def __init__(self, record, columns, offset, ratio, size, start):
        self.columns, self.offset, self.ratio = columns, offset, ratio
        local = max(0, -(-(start - offset) // ratio))          # its first sample at or after ``start``
        sub = max(1, size // ratio)
        self.skip = local - (local // sub) * sub
        self.chunks = record.chunks(sub, (local // sub) * sub)
        self.steps, self.rows = np.empty(0, int), np.empty((0, len(columns)))

    def fill(self, Y, a):
        b = a + Y.shape[0]
        while True:
            if not self.steps.size:
                nxt = next(self.chunks, None)
                if nxt is None:
                    return
                step, rows = nxt
                if self.skip:
                    cut = min(self.skip, rows.shape[0])
                    rows, step, self.skip = rows[cut:], step + cut, self.skip - cut
                self.steps = self.offset + (step + np.arange(rows.shape[0])) * self.ratio
                self.rows = rows
            inside = self.steps < b
            take = inside & (self.steps >= a)
            Y[np.ix_(self.steps[take] - a, self.columns)] = self.rows[take]
            self.steps, self.rows = self.steps[~inside], self.rows[~inside]
            if self.steps.size:
                return
