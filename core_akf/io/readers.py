"""Readers of data-acquisition files behind one interface: CSV, Parquet, TDMS, UFF 58 and HDF5.

A :class:`Reader` opens one file and tells its channels, their units where the file records them,
its time grid (:class:`Timing`: first time, step and length, checked to be uniform) and gives the
samples of chosen channels chunk by chunk in the file's own units.  The format is chosen by the
file's extension or named (``format="tdms"``).  A user adds a format by subclassing
:class:`Reader` and calling :func:`register_reader` (or by an entry point in the group
``akf.readers`` that names the class).

Layouts read:

- CSV, Parquet: a time column (default ``time``) and one column per channel.
- TDMS (npTDMS): every channel of every group (``group/channel``, or ``channel`` where the name is
  unique); the time from the waveform properties ``wf_start_offset`` / ``wf_increment`` or from a
  channel named like the time column; units from ``unit_string``.  Channels with different
  ``wf_increment`` are channel sets at their own rates (:meth:`Reader.rate_sets`).
- UFF 58 (pyuff): one data set per channel, named by its ``id1`` (or ``NODE:DIR`` from the response
  node and direction where ``id1`` is empty or repeats); even abscissa spacing; units from the
  ordinate's unit label.  A UFF file is read whole (the format has no random access).
- HDF5 (h5py): one 1-D dataset per channel in a group (default the root), a ``time`` dataset or
  the attributes ``dt`` (or ``wf_increment``) and ``t0`` (or ``wf_start_offset``) on the group or,
  for a channel at a rate of its own, on its dataset; units from a dataset's ``unit`` or ``units``
  attribute.
"""
from __future__ import annotations

import contextlib
import importlib
import os
import re
from abc import ABC, abstractmethod
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from ..checks import AKFInputError, describe_cell, first_repeat, found_columns, install_hint

#: a time stamp may lie off the uniform grid ``t_0 + k dt`` by this fraction of a step
TIME_GRID_RTOL = 0.01


@dataclass(frozen=True)
class Timing:
    """A file's time grid.

    Attributes
    ----------
    start : float
        Time of the first step (s).
    dt : float
        Time step (s).
    n_steps : int
        Steps in the file.
    """

    start: float
    dt: float
    n_steps: int

    @property
    def end(self):
        """Time of the step after the last one (s): where the next file of a record starts."""
        return self.start + self.n_steps * self.dt


@contextlib.contextmanager
def file_damage_named(path):
    """Turn what a format library raises on a damaged file (a bad checksum or signature, a read
    past the end) into an error naming the file: for the reads that open and index a file.

    Parameters
    ----------
    path : str
        The file, for messages.

    Yields
    ------
    None
    """
    try:
        yield
    except AKFInputError:
        raise
    except (OSError, RuntimeError, KeyError, EOFError, UnicodeDecodeError) as exc:
        raise AKFInputError(f"{path}: the file cannot be read ({library_error(exc)}); is it damaged or cut "
                            "short?") from None


#: bytes a library quotes from a file (npTDMS: "does not start with b'TDSm', but with b'root'")
_QUOTED_BYTES = re.compile(r"""\bb(['"]).*?(?<!\\)\1""")


def library_error(exc):
    """What a format library said about a file, for a message: its error type and text, cut to 200
    characters, with any bytes it quotes from the file left out (a message never quotes a file's
    content).

    Parameters
    ----------
    exc : Exception
        What the library raised.

    Returns
    -------
    str
    """
    text = _QUOTED_BYTES.sub("(bytes of the file)", getattr(exc, "strerror", None) or str(exc))
    return f"{type(exc).__name__}: {text.strip(chr(39) + chr(34))[:200]}"


class MissingExtraError(AKFInputError):
    """A format whose reading library is not installed."""


class EmptyFileError(AKFInputError):
    """A data file without a data row (a record of many files skips it, with a warning)."""


class Reader(ABC):
    """One data file.

    Subclasses set ``format`` (a name), ``extensions`` and, for a format that needs an optional
    library, ``module`` (its import name) and ``extra`` (the pip extra).

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    time_column : str
        The time column or channel (s).
    group : str, optional
        The group holding the channels (TDMS, HDF5; default all groups / the root).
    """

    format: str = ""
    extensions: tuple = ()
    module: str | None = None
    extra: str | None = None

    def __init__(self, path: str | os.PathLike, time_column: str = "time", group: str | None = None):
        self.path = os.fspath(path)
        self.time_column = time_column
        self.group = group
        if not os.path.exists(self.path):
            raise AKFInputError(f"measurement file {self.path!r} not found")
        if os.path.isdir(self.path):
            raise AKFInputError(f"measurement file {self.path!r} is a folder; give a data file, or the folder as "
                                "files = \"folder/*.ext\"")
        if self.module:
            self.lib = _require(self.module, self.extra, self.format)

    @abstractmethod
    def channels(self) -> list:
        """The channel names in the file (without the time column).

        Returns
        -------
        list of str
        """

    def units(self) -> dict:
        """Units the file records per channel.

        Returns
        -------
        dict
            Channel -> unit (``{}`` where it records none).
        """
        return {}

    @abstractmethod
    def timing(self) -> Timing:
        """The time grid, checked: increasing, uniform within :data:`TIME_GRID_RTOL` of a step.

        Returns
        -------
        Timing
        """

    @abstractmethod
    def chunks(self, channels: Sequence[str], size: int) -> Iterator[np.ndarray]:
        """The file's samples in time order, chunk by chunk, covering the whole file.

        Parameters
        ----------
        channels : sequence of str
            The channels to read, in this order.
        size : int
            Steps per chunk at most.

        Yields
        ------
        ndarray (k, len(channels))
            Samples in the file's units, ``k <= size``.
        """

    def rate_sets(self) -> list[list[str]]:
        """The channels grouped by their own time grid (TDMS and HDF5 channels may carry their own
        time step); one group for a file whose channels share one grid.

        Returns
        -------
        list of list of str
        """
        return [self.channels()]

    def restrict(self, names: Sequence[str]) -> None:
        """Read only these channels from now on (one of :meth:`rate_sets`, or a part of one): the
        file's time grid is then theirs.

        Parameters
        ----------
        names : sequence of str
            Channels of the file.
        """
        if set(self.channels()) - set(names):
            raise AKFInputError(f"{self.path}: a {self.format} file's channels are read together; it cannot read "
                                f"{sorted(names)} alone")

    def _check_channels(self, channels):
        known = self.channels()
        missing = [c for c in channels if c not in known]
        if missing:
            raise AKFInputError(f"{self.path}: no channel(s) {missing}; the file has {known}")

    def __repr__(self):
        return f"{type(self).__name__}({self.path!r})"


def _require(module, extra, fmt):
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingExtraError(f"reading {fmt} files needs the package {module!r}: {install_hint(extra)}") from None


def check_time_grid(t, path, dt=None, offset=0):
    """The time grid of time stamps, or a located error.

    Parameters
    ----------
    t : ndarray (N,)
        Time stamps (s).
    path : str
        The file, for messages.
    dt : float, optional
        The step if known (else the mean step).
    offset : int
        The row number of ``t[0]`` in the file (for messages).

    Returns
    -------
    Timing

    Raises
    ------
    AKFInputError
        For a time that repeats or goes back, or a stamp off the uniform grid (a gap or jitter)
        by more than :data:`TIME_GRID_RTOL` of a step.
    """
    t, origin = time_in_seconds(t, path)
    if t.size < 1:
        raise EmptyFileError(f"{path}: 0 data rows; a record needs at least two time steps")
    if not np.all(np.isfinite(t)):
        r = int(np.flatnonzero(~np.isfinite(t))[0])
        raise AKFInputError(f"{path}: time column has a missing/NaN value in data row {offset + r + 1}")
    steps = np.diff(t)
    if np.any(steps <= 0):
        r = int(np.flatnonzero(steps <= 0)[0])
        what = "repeats" if steps[r] == 0 else "goes back"
        raise AKFInputError(f"{path}: time {what} at data row {offset + r + 2} (t = {t[r + 1]:.9g} s after "
                            f"t = {t[r]:.9g} s in row {offset + r + 1}); time stamps must increase by dt")
    if dt is None:
        if t.size < 2:
            raise AKFInputError(f"{path}: 1 data row; a record needs at least two time steps")
        dt = float(t[-1] - t[0]) / (t.size - 1)     # the mean step: time stamps rounded in the file average out
        median = float(np.median(steps))
        if abs(median - dt) * t.size <= TIME_GRID_RTOL * dt:
            dt = median                             # as good over the file, and exact for exact stamps
    off = np.abs(t - t[0] - dt * np.arange(t.size))
    if off.size and np.max(off) > TIME_GRID_RTOL * dt:
        jump = np.abs(steps - np.median(steps)) > TIME_GRID_RTOL * dt      # the first irregular step, if any
        if jump.any():
            r, dt = int(np.argmax(jump)) + 1, float(np.median(steps))
            dev = t[r] - t[r - 1] - dt
        else:
            r = int(np.argmax(off > TIME_GRID_RTOL * dt))
            dev = off[r]
        raise AKFInputError(f"{path}: data row {offset + r + 1} (t = {t[r]:.9g} s) is {dev:.3g} s ({dev / dt:.3g} "
                            f"steps) off the uniform grid t0 + k dt (dt = {dt:.9g} s): a gap or jitter there")
    return Timing(origin + float(t[0]), float(dt), int(t.size))


def time_in_seconds(t, path):
    """Time stamps as seconds from an origin: numbers as they are (origin 0); date-times
    (``datetime64``, as TDMS and Parquet store time stamps) and durations (``timedelta64``) as
    seconds after the first stamp, counted in whole nanoseconds so that the steps keep their
    precision, with the first stamp's seconds since 1970 (or 0 for a duration) as the origin.

    Parameters
    ----------
    t : array_like (N,)
        Time stamps.
    path : str
        The file, for messages.

    Returns
    -------
    seconds : ndarray (N,) of float
        Seconds after the origin (NaN for a missing stamp).
    origin : float
        The origin (s).
    """
    t = np.asarray(t)
    if t.dtype.kind in "mM":
        ns = t.astype(f"{t.dtype.kind}8[ns]")
        valid = ~np.isnat(ns)
        seconds = np.full(t.shape, np.nan)
        if not valid.any():
            return seconds, 0.0
        first = ns[valid][0]
        seconds[valid] = (ns[valid] - first).astype("int64") * 1e-9
        return seconds, (float(first.astype("int64")) * 1e-9 if t.dtype.kind == "M" else 0.0)
    try:
        return np.asarray(t, float), 0.0
    except (TypeError, ValueError):
        raise AKFInputError(f"{path}: the time stamps are not numbers or date-times (they hold {t.dtype} values, "
                            "such as text)") from None


def grid_number(value, path, what):
    """A time-grid number a file states (a step or a first time, s) as a float, or an error naming
    it: one finite real number, not text, an array or NaN.

    Parameters
    ----------
    value : object
        What the file holds (a property or an attribute).
    path : str
        The file, for messages.
    what : str
        Which property or attribute it is, for messages.

    Returns
    -------
    float
    """
    v = value.decode(errors="replace") if isinstance(value, bytes) else value
    try:
        arr = np.asarray(v)
        number = float(arr.reshape(())) if arr.size == 1 and arr.dtype.kind in "iuf" else None
    except (TypeError, ValueError, OverflowError):
        number = None
    if number is None or not np.isfinite(number):
        shown = (repr(number) if number is not None else repr(v) if np.asarray(v).size == 1
                 else f"an array of {np.asarray(v).size} values")
        raise AKFInputError(f"{path}: {what} is {shown[:60]}, not a finite number of seconds")
    return number


def uniform_grid(path, start, dt, n, where):
    """The :class:`Timing` of a grid a file states (first time ``start`` s, step ``dt`` s, ``n``
    steps), or an error naming where it is stated: the step positive, and the first time small
    enough that its steps can be told apart in double precision.

    Parameters
    ----------
    path : str
        The file, for messages.
    start, dt : float
        The first time and the step (s).
    n : int
        Steps.
    where : str
        Where the file states the grid (its properties or attributes), for messages.

    Returns
    -------
    Timing
    """
    if not dt > 0:
        raise AKFInputError(f"{path}: {where}: the time step {dt!r} s is not positive")
    if abs(start) * np.finfo(float).eps > TIME_GRID_RTOL * dt:
        raise AKFInputError(f"{path}: {where}: the first time {start:.6g} s is so large that steps of {dt:.6g} s "
                            "after it cannot be told apart in double precision (is it in another unit?)")
    return Timing(float(start), float(dt), int(n))


# ------------------------------------------------------------------------------------- tables
class CsvReader(Reader):
    """CSV: a header row, a time column and one numeric column per channel.

    Parameters
    ----------
    path, time_column, group
        As :class:`Reader`.
    """

    format, extensions = "csv", (".csv", ".txt")

    def __init__(self, path, time_column="time", group=None):
        super().__init__(path, time_column, group)
        import pandas as pd

        try:
            self._columns = list(pd.read_csv(self.path, nrows=0).columns)
        except pd.errors.EmptyDataError:
            raise AKFInputError(f"{self.path}: the file is empty; expected a header row and one row per time "
                                "step") from None
        except (pd.errors.ParserError, UnicodeDecodeError) as exc:
            raise AKFInputError(f"{self.path}: not a readable CSV file ({library_error(exc)})") from None
        _check_unique_columns(self._header(), self.path)
        if time_column not in self._columns:
            sep = next((c for c in ";\t|" if len(self._columns) == 1 and c in self._columns[0]), None)
            hint = (f"; the header looks {'tab' if sep == chr(9) else repr(sep)}-separated: CSV files here are "
                    "comma-separated with a decimal point (save as CSV, or convert with pandas: "
                    "pd.read_csv(path, sep=..., decimal=...).to_csv(new, index=False))") if sep else ""
            raise AKFInputError(f"{self.path}: no time column {time_column!r}; {found_columns(self._columns)}{hint}")
        self._timing = None

    def _header(self):
        """The column names as written in the header row (pandas renames a repeated name ``a.1``)."""
        import csv

        with open(self.path, newline="", encoding="utf-8", errors="replace") as fh:
            return [c.strip() for c in next(csv.reader(fh), [])]

    def channels(self):
        return [c for c in self._columns if c != self.time_column]

    def _read(self, columns, size):
        import pandas as pd

        try:
            yield from pd.read_csv(self.path, usecols=columns, chunksize=size, dtype=str)
        except (pd.errors.ParserError, UnicodeDecodeError, ValueError) as exc:
            raise AKFInputError(f"{self.path}: not a readable CSV file ({library_error(exc)})") from None

    def timing(self):
        if self._timing is None:
            parts = []
            for frame in self._read([self.time_column], 1 << 20):
                parts.append(_time_stamps(frame[self.time_column], self.path, self.time_column, sum(map(len, parts))))
            t = np.concatenate(parts) if parts else np.empty(0)
            self._timing = check_time_grid(t, self.path)
            check_row_widths(self.path, len(self._header()))
        return self._timing

    def chunks(self, channels, size):
        self._check_channels(channels)
        row = 0
        for frame in self._read(list(channels), size):
            yield np.column_stack([_numeric(frame[c], self.path, c, row) for c in channels])
            row += len(frame)


#: bytes of a CSV file read at a time when the widths of its rows are checked
WIDTH_BLOCK = 1 << 24


def check_row_widths(path, width):
    """Refuse a CSV file whose data rows do not each have the header's ``width`` fields.

    pandas reads such a row without a word when it picks columns: an extra field (a decimal comma,
    a separator too many) is dropped and the row's later cells shift to other channels; a torn or
    short row gives missing samples.  Blank lines are skipped, as pandas skips them.

    Parameters
    ----------
    path : str
        The CSV file (comma-separated, a header row).
    width : int
        The header's fields.

    Raises
    ------
    AKFInputError
        Naming the first data row of another width (1-based, as the other record messages count).
    """
    row, tail = 0, b""
    with open(path, "rb") as fh:
        fh.readline()                                   # the header
        while True:
            block = fh.read(WIDTH_BLOCK)
            data = tail + block
            end = len(data) if not block else data.rfind(b"\n") + 1
            lines, tail = data[:end], data[end:]
            if lines and not lines.endswith(b"\n"):
                lines += b"\n"
            fields = _fields_per_line(lines)
            bad = np.flatnonzero(fields != width)
            if bad.size:
                r = row + int(bad[0]) + 1
                raise AKFInputError(f"{path}: data row {r} has {fields[bad[0]]} fields where the header names {width}: a "
                                    "broken or torn row (a decimal comma, a separator too many or too few); a missing "
                                    "sample is an empty cell between two commas")
            row += fields.size
            if not block:
                return


def _fields_per_line(lines):
    """The fields of each non-blank line of ``lines`` (bytes ending in a newline): commas + 1, or
    the csv module's count where a quote may hide a comma."""
    if b'"' in lines:
        import csv
        import io

        rows = csv.reader(io.StringIO(lines.decode("utf-8", errors="replace"), newline=""))
        return np.array([len(r) for r in rows if r], int)
    a = np.frombuffer(lines, np.uint8)
    newline = np.flatnonzero(a == 10)
    start = np.r_[0, newline[:-1] + 1]
    commas = np.r_[0, np.cumsum(a == 44)]
    count = commas[newline] - commas[start]
    length = newline - start - (a[np.maximum(newline - 1, 0)] == 13)
    return (count + 1)[length > 0]


def _check_unique_columns(names, path):
    """Refuse a table that names a column twice: which of the two is the channel is not known."""
    repeat = first_repeat(names)
    if repeat:
        i, j, name = repeat
        raise AKFInputError(f"{path}: column {name!r} appears twice (columns {i + 1} and {j + 1}); every channel "
                            "needs a name of its own")


#: cell texts that mean a missing sample (an empty cell is one too)
MISSING_TEXTS = frozenset({"", "nan", "na", "n/a", "null", "none", "-"})


def _numeric(column, path, name, row0, missing=True):
    """A column as floats, NaN for a missing sample (an empty cell or a text of :data:`MISSING_TEXTS`);
    a located error for text or an infinite value (and, with ``missing=False``, a missing sample)."""
    import pandas as pd

    values = pd.to_numeric(column, errors="coerce").to_numpy(float)
    nan = np.isnan(values)
    if nan.any():
        text = column.astype(object).where(column.notna(), "").astype(str).str.strip().str.lower().to_numpy()
        bad = np.flatnonzero(nan & ~np.isin(text, list(MISSING_TEXTS))) if missing else np.flatnonzero(nan)
        if bad.size:
            r = int(bad[0])
            what = "non-numeric" if missing else "missing/NaN or non-numeric"
            raise AKFInputError(f"{path}: column {name!r} has {bad.size} {what} sample(s); the first, in data row "
                                f"{row0 + r + 1}, is {describe_cell(column.iloc[r])} (a missing sample is an empty "
                                "cell or NaN)")
    _refuse_infinite(values, path, name, row0)
    return values


def _time_stamps(column, path, name, row0):
    """A CSV time column as seconds, or as date-times where every cell is an ISO 8601 date-time
    (``2026-12-05T10:00:00.000244``; a time zone is taken to UTC, none means UTC); a located error
    for anything else, as :func:`_numeric` names it."""
    import pandas as pd

    try:
        return _numeric(column, path, name, row0, missing=False)
    except AKFInputError:
        stamps = pd.to_datetime(column, format="ISO8601", utc=True, errors="coerce")
        if stamps.isna().any() or not len(stamps):
            raise
        return stamps.dt.tz_localize(None).to_numpy("datetime64[ns]")


def _samples(values, path, name, row0):
    """A channel's values as floats: true/false values (a digital line) and infinite values refused
    by name; a ``TypeError``/``ValueError`` for values that are not numbers (the caller names them).

    Parameters
    ----------
    values : array_like (k,)
        The channel's values as the format library gives them.
    path, name : str
        The file and the channel, for messages.
    row0 : int
        The data row of ``values[0]``, for messages.

    Returns
    -------
    ndarray (k,) of float
    """
    values = np.asarray(values)
    if values.dtype == bool:
        raise AKFInputError(f"{path}: channel {name!r} holds true/false values (a digital line or a flag), not "
                            "measurements")
    values = np.asarray(values, float)
    _refuse_infinite(values, path, name, row0)
    return values


def _refuse_infinite(values, path, name, row0):
    """A located error for an infinite sample (a missing one is NaN, not inf)."""
    bad = np.flatnonzero(np.isinf(values))
    if bad.size:
        raise AKFInputError(f"{path}: channel {name!r} has {bad.size} infinite sample(s); first in data row "
                            f"{row0 + int(bad[0]) + 1} (a missing sample is NaN or an empty cell)")


class ParquetReader(Reader):
    """Parquet (pyarrow): a time column and one numeric column per channel; read by row batches.

    Parameters
    ----------
    path, time_column, group
        As :class:`Reader`.
    """

    format, extensions = "parquet", (".parquet", ".pq")

    def __init__(self, path, time_column="time", group=None):
        super().__init__(path, time_column, group)
        import pyarrow.parquet as pq

        try:
            self._file = pq.ParquetFile(self.path)
        except Exception as exc:  # noqa: BLE001 -- pyarrow raises its own error types
            raise AKFInputError(f"{self.path}: not a readable Parquet file ({library_error(exc)})") from None
        self._columns = [c for c in self._file.schema_arrow.names if not c.startswith("__index_level")]
        _check_unique_columns(self._columns, self.path)
        if time_column not in self._columns:
            raise AKFInputError(f"{self.path}: no time column {time_column!r}; {found_columns(self._columns)}")
        self._timing = None

    def channels(self):
        return [c for c in self._columns if c != self.time_column]

    def timing(self):
        if self._timing is None:
            t = self._file.read(columns=[self.time_column]).column(0).to_numpy(zero_copy_only=False)
            self._timing = check_time_grid(t, self.path)
        return self._timing

    def chunks(self, channels, size):
        self._check_channels(channels)
        row = 0
        for batch in self._file.iter_batches(batch_size=size, columns=list(channels)):
            columns = []
            for i, c in enumerate(channels):
                values = batch.column(i).to_numpy(zero_copy_only=False)
                try:
                    values = _samples(values, self.path, c, row)          # a null is NaN: a missing sample
                except AKFInputError:
                    raise
                except (TypeError, ValueError):
                    import pandas as pd

                    values = _numeric(pd.Series(values), self.path, c, row)     # text: located
                columns.append(values)
            block = np.column_stack(columns)
            row += block.shape[0]
            yield block


# --------------------------------------------------------------------------------- DAQ formats
class _SlicedReader(Reader):
    """A format whose channels are arrays read by slices from an open file (``self._file``,
    ``self._series``: name -> sliceable channel, the time channel included if there is one)."""

    _file = None
    _series: dict = {}
    _only = None                      # the channels read (restrict); None: all

    def __del__(self):
        try:
            self._file.close()
        except Exception:  # noqa: BLE001, S110 -- closing at exit
            pass

    def channels(self):
        return [c for c in self._series if c != self.time_column and (self._only is None or c in self._only)]

    def _grid_of(self, name):
        """A channel's own ``(step, first time)`` where the file gives one per channel (None: the
        file's grid)."""
        return None

    def rate_sets(self):
        if self.time_column in self._series:          # one time channel: one grid
            return [self.channels()]
        sets = {}
        for c in self.channels():
            sets.setdefault(self._grid_of(c), []).append(c)
        return list(sets.values())

    def restrict(self, names):
        unknown = [c for c in names if c not in self._series or c == self.time_column]
        if unknown:
            raise AKFInputError(f"{self.path}: no channel(s) {unknown}; the file has {self.channels()}")
        self._only = set(names)
        self._timing = None

    def _one_grid(self):
        """The ``(step, first time)`` the channels read share (None where the file gives none per
        channel); an error naming the rate sets when they differ."""
        if self.time_column in self._series:          # one time channel: its grid
            return None
        grids = {self._grid_of(c) for c in self.channels()}
        if len(grids) > 1:
            step = lambda c: "no wf_increment" if self._grid_of(c)[0] is None else f"every {self._grid_of(c)[0]:.6g} s"  # noqa: E731
            sets = "; ".join(f"{', '.join(cs)} {step(cs[0])}" for cs in self.rate_sets())
            raise AKFInputError(f"{self.path}: its channels have different time grids ({sets}); open it with "
                                "core_akf.io.open_record (or [measurements] in a job), which reads each rate as a "
                                "channel set of its own")
        return grids.pop() if grids else None

    def _length(self):
        """The common length of the data channels (a located error if they differ)."""
        lengths = {len(self._series[c]) for c in self.channels()}
        if not lengths:
            raise AKFInputError(f"{self.path}: no data channels")
        if len(lengths) > 1:
            self._one_grid()            # different rates are named as such
            raise AKFInputError(f"{self.path}: channels of different lengths {sorted(lengths)}; a record needs one "
                                "sample of every channel per time step")
        return lengths.pop()

    def _time_channel_grid(self, n, stated_dt=None, where=""):
        """The time grid of the time channel, which must have one stamp per sample of the data and
        agree with a time step the file states elsewhere (``stated_dt``, s, in ``where``)."""
        t = self._series[self.time_column]
        if len(t) != n:
            raise AKFInputError(f"{self.path}: the time channel {self.time_column!r} has {len(t)} samples but the data "
                                f"channels have {n}; a record needs one time stamp per sample")
        timing = check_time_grid(t[:], self.path)
        stated_dt = None if stated_dt is None else grid_number(stated_dt, self.path, where)
        if stated_dt is not None and abs(stated_dt - timing.dt) > TIME_GRID_RTOL * timing.dt:
            raise AKFInputError(f"{self.path}: the time channel {self.time_column!r} steps by {timing.dt:.9g} s but "
                                f"{where} says {float(stated_dt):.9g} s; which one is right?")
        return timing

    def chunks(self, channels, size):
        self._check_channels(channels)
        n = self.timing().n_steps
        for start in range(0, n, size):
            stop = min(start + size, n)
            columns = []
            for c in channels:
                try:
                    values = _samples(self._series[c][start:stop], self.path, c, start)
                except AKFInputError:
                    raise
                except (TypeError, ValueError):
                    raise AKFInputError(f"{self.path}: channel {c!r} does not hold numbers (it holds "
                                        f"{np.asarray(self._series[c][start:start + 1]).dtype} values)") from None
                except (OSError, MemoryError, OverflowError, RuntimeError, KeyError, EOFError) as exc:
                    raise AKFInputError(f"{self.path}: samples {start}..{stop - 1} of channel {c!r} cannot be read "
                                        f"({library_error(exc)}): the file's index claims {self.timing().n_steps} "
                                        "samples; is it damaged or cut short?") from None
                columns.append(values)
            yield np.column_stack(columns)


class TdmsReader(_SlicedReader):
    """LabVIEW TDMS (npTDMS), opened for streaming: only the chunks asked for are read.

    Parameters
    ----------
    path, time_column, group
        As :class:`Reader`; the time comes from a time channel or from the waveform properties
        (``wf_start_time``, ``wf_increment``).
    """

    format, extensions, module, extra = "tdms", (".tdms",), "nptdms", "tdms"

    def __init__(self, path, time_column="time", group=None):
        super().__init__(path, time_column, group)
        try:
            self._file = self.lib.TdmsFile.open(self.path)
        except Exception as exc:  # noqa: BLE001 -- npTDMS raises its own error types
            raise AKFInputError(f"{self.path}: not a readable TDMS file ({library_error(exc)})") from None
        groups = self._file.groups()
        if group is not None:
            groups = [g for g in groups if g.name == group]
            if not groups:
                raise AKFInputError(f"{self.path}: no group {group!r}; the file has {[g.name for g in self._file.groups()]}")
        all_channels = [(g.name, c) for g in groups for c in g.channels()]
        if not all_channels:
            raise AKFInputError(f"{self.path}: no channels" + (f" in group {group!r}" if group is not None else "")
                                + ": is it a TDMS file of measurements (it starts with the tag TDSm)?")
        names = [c.name for _, c in all_channels]
        self._series = {}
        for gname, c in all_channels:
            self._series[c.name if names.count(c.name) == 1 else f"{gname}/{c.name}"] = c
        self._timing = None

    def units(self):
        return {name: c.properties["unit_string"] for name, c in self._series.items()
                if name != self.time_column and "unit_string" in c.properties}

    def timing(self):
        if self._timing is None:
            n = self._length()
            data = [self._series[c] for c in self.channels()]
            if self.time_column in self._series:
                self._timing = self._time_channel_grid(n, data[0].properties.get("wf_increment"),
                                                       f"the wf_increment of channel {data[0].name!r}")
            else:
                grid = self._one_grid()
                if grid is None or grid[0] is None:
                    raise AKFInputError(f"{self.path}: no time: the channels have no wf_increment property and there "
                                        f"is no channel {self.time_column!r}")
                self._timing = uniform_grid(self.path, grid[1], grid[0], n,
                                            "the channels' wf_start_offset and wf_increment")
        return self._timing

    def _grid_of(self, name):
        props = self._series[name].properties
        dt = props.get("wf_increment")
        return (None if dt is None else grid_number(dt, self.path, f"channel {name!r}: wf_increment"),
                grid_number(props.get("wf_start_offset", 0.0), self.path, f"channel {name!r}: wf_start_offset"))


#: UFF 58 function types (record 6, field 1) other than a time response
UFF_FUNCTION_TYPES = {0: "general or unknown function", 2: "auto spectrum", 3: "cross spectrum",
                      4: "frequency response function (FRF)", 5: "transmissibility", 6: "coherence",
                      7: "auto-correlation", 8: "cross-correlation", 9: "power spectral density (PSD)",
                      10: "energy spectral density", 11: "probability density function", 12: "spectrum",
                      13: "cumulative frequency distribution", 14: "peaks valley", 15: "stress/cycles",
                      16: "strain/cycles", 17: "orbit", 18: "mode indicator function", 19: "force pattern",
                      20: "partial power", 21: "partial coherence", 22: "eigenvalue", 23: "eigenvector",
                      24: "shock response spectrum", 25: "finite impulse response filter",
                      26: "multiple coherence", 27: "order function"}


class Uff58Reader(Reader):
    """Universal File Format data sets 58 (pyuff): one set per channel, evenly spaced.

    Parameters
    ----------
    path, time_column, group
        As :class:`Reader` (the time comes from the sets' abscissa).
    """

    format, extensions, module, extra = "uff", (".uff", ".unv"), "pyuff", "uff"

    def __init__(self, path, time_column="time", group=None):
        super().__init__(path, time_column, group)
        try:
            uff = self.lib.UFF(self.path)
            types = list(uff.get_set_types())
            sets = uff.read_sets([i for i, t in enumerate(types) if int(t) == 58]) if 58 in types else []
        except Exception as exc:  # noqa: BLE001 -- pyuff raises bare Exceptions
            raise AKFInputError(f"{self.path}: not a readable UFF file ({library_error(exc)})") from None
        sets = [sets] if isinstance(sets, dict) else list(sets)
        if not sets:
            raise AKFInputError(f"{self.path}: no data set of type 58 (function at nodal DOF)")
        ids = [str(s.get("id1", "")).strip() for s in sets]
        self._sets = {}
        for s, name in zip(sets, ids):
            if not name or name.upper() == "NONE" or ids.count(name) > 1:
                name = f"{int(s.get('rsp_node', 0))}:{int(s.get('rsp_dir', 0))}"
            if name in self._sets:
                raise AKFInputError(f"{self.path}: two data sets named {name!r}")
            func = int(s.get("func_type", 1))
            if func != 1:
                what = UFF_FUNCTION_TYPES.get(func, f"function type {func}")
                raise AKFInputError(f"{self.path}: data set {name!r} is a {what}, not a time response (function type "
                                    "1); a record holds measured time series")
            if np.iscomplexobj(s.get("data")):
                raise AKFInputError(f"{self.path}: data set {name!r} holds complex values; a record holds real time "
                                    "series")
            if int(s.get("abscissa_spacing", 1)) != 1:
                raise AKFInputError(f"{self.path}: data set {name!r} has uneven abscissa spacing; a record needs a "
                                    "uniform time step")
            self._sets[name] = s

    def channels(self):
        return list(self._sets)

    def units(self):
        from .units import is_unset

        return {n: str(s["ordinate_axis_units_lab"]).strip() for n, s in self._sets.items()
                if not is_unset(s.get("ordinate_axis_units_lab"))}

    def timing(self):
        grids = {(grid_number(s["abscissa_min"], self.path, f"data set {c!r}: abscissa minimum"),
                  grid_number(s["abscissa_inc"], self.path, f"data set {c!r}: abscissa increment"), int(len(s["data"])))
                 for c, s in self._sets.items()}
        if len(grids) > 1:
            raise AKFInputError(f"{self.path}: the data sets have different time grids (start, step, length): "
                                f"{sorted(grids)}")
        start, dt, n = grids.pop()
        return uniform_grid(self.path, start, dt, n, "the data sets' abscissa minimum and increment")

    def chunks(self, channels, size):
        self._check_channels(channels)
        data = np.column_stack([_samples(self._sets[c]["data"], self.path, c, 0) for c in channels])
        for start in range(0, data.shape[0], size):
            yield data[start:start + size]


class Hdf5Reader(_SlicedReader):
    """HDF5 (h5py): 1-D datasets per channel in a group; read by slices.

    Parameters
    ----------
    path, time_column, group
        As :class:`Reader`.
    """

    format, extensions, module, extra = "hdf5", (".h5", ".hdf5", ".hdf"), "h5py", "hdf5"

    def __init__(self, path, time_column="time", group=None):
        super().__init__(path, time_column, group)
        try:
            self._file = self.lib.File(self.path, "r")
        except Exception as exc:  # noqa: BLE001 -- h5py raises OSError subclasses of its own
            raise AKFInputError(f"{self.path}: not a readable HDF5 file ({library_error(exc)})") from None
        with file_damage_named(self.path):
            if group and group not in self._file:
                raise AKFInputError(f"{self.path}: no group {group!r}; the file has {list(self._file)}")
            self._group = self._file[group] if group else self._file
            items = list(self._group.items())
        self._series = {k: v for k, v in items if isinstance(v, self.lib.Dataset) and v.ndim == 1}
        self._skipped = [f"{k} {v.shape}" for k, v in items if isinstance(v, self.lib.Dataset) and v.ndim != 1]
        self._timing = None

    def _length(self):
        if not self.channels() and self._skipped:
            raise AKFInputError(f"{self.path}: no data channels: a channel is a 1-D dataset, and the datasets here are "
                                f"not 1-D ({', '.join(self._skipped[:5])}); store one 1-D dataset per channel")
        n = super()._length()
        for name in self.channels():
            written = self._written(self._series[name])
            if written is not None and written < n:
                raise AKFInputError(f"{self.path}: dataset {name!r} declares {n} samples but holds data for only about "
                                    f"{written} of them; the rest would read as its fill value, not as measurements "
                                    "(a recording cut short?): write the dataset with the length of its data")
        return n

    @staticmethod
    def _written(ds):
        """About how many samples of a dataset were ever written (None: all, or not known): a
        chunked dataset's allocated chunks, a contiguous one's allocated storage."""
        try:
            if ds.chunks:
                return int(ds.id.get_num_chunks()) * int(ds.chunks[0])
            return None if ds.id.get_storage_size() or not len(ds) else 0
        except (AttributeError, RuntimeError, ValueError):     # an older h5py, a compact or virtual dataset
            return None

    def units(self):
        out = {}
        with file_damage_named(self.path):
            for name, ds in self._series.items():
                for key in ("unit", "units", "unit_string"):
                    if key in ds.attrs and name != self.time_column:
                        v = ds.attrs[key]
                        out[name] = v.decode(errors="replace") if isinstance(v, bytes) else str(v)
                        break
        return out

    def timing(self):
        with file_damage_named(self.path):
            return self._timing_of_file()

    def _timing_of_file(self):
        if self._timing is None:
            n = self._length()
            a = self._group.attrs
            if self.time_column in self._series:
                self._timing = self._time_channel_grid(n, a.get("dt", a.get("wf_increment")), "the group's attribute dt")
            else:
                dt, t0 = self._one_grid()
                if dt is None:
                    raise AKFInputError(f"{self.path}: no time: no dataset {self.time_column!r} and no attribute dt "
                                        "(or wf_increment) on the group or its datasets")
                self._timing = uniform_grid(self.path, t0, dt, n, "the attributes dt and t0")
        return self._timing

    def _grid_of(self, name):
        """A dataset's own attributes ``dt`` (or ``wf_increment``) and ``t0`` (or
        ``wf_start_offset``), else the group's."""
        own, group = self._series[name].attrs, self._group.attrs

        def attr(*keys, default=None):
            for where, whose in ((own, f"dataset {name!r}"), (group, "the group")):
                for key in keys:
                    if key in where:
                        return grid_number(where[key], self.path, f"attribute {key} of {whose}")
            return default

        return attr("dt", "wf_increment"), attr("t0", "wf_start_offset", default=0.0)


# ------------------------------------------------------------------------------------ registry
_READERS: dict = {}


def register_reader(reader: type[Reader]) -> type[Reader]:
    """Register a :class:`Reader` subclass for its ``format`` name and ``extensions``.

    A class decorator; a later registration of the same name or extension wins.

    Parameters
    ----------
    reader : type
        A :class:`Reader` subclass with a ``format`` name.

    Returns
    -------
    type
        ``reader``.

    Examples
    --------
    A reader of one's own, here CSV files with another extension:

    >>> @register_reader
    ... class LoggerCsv(CsvReader):
    ...     format, extensions = "logger-csv", (".lcsv",)
    >>> formats()["logger-csv"]
    ('.lcsv',)
    """
    if not (isinstance(reader, type) and issubclass(reader, Reader)) or not reader.format:
        raise TypeError(f"{reader!r} is not a Reader subclass with a format name")
    _READERS[reader.format] = reader
    return reader


for _cls in (CsvReader, ParquetReader, TdmsReader, Uff58Reader, Hdf5Reader):
    register_reader(_cls)

_ENTRY_POINTS_LOADED = False


def _load_entry_points():
    global _ENTRY_POINTS_LOADED
    if _ENTRY_POINTS_LOADED:
        return
    _ENTRY_POINTS_LOADED = True
    from importlib.metadata import entry_points

    for ep in entry_points(group="akf.readers"):
        try:
            register_reader(ep.load())
        except Exception as exc:  # noqa: BLE001 -- a broken plugin must not stop the built-in formats
            import warnings

            warnings.warn(f"reader plugin {ep.name!r} ({ep.value}) could not be loaded: {exc}")


def formats() -> dict[str, tuple[str, ...]]:
    """The registered formats.

    Returns
    -------
    dict
        Format name -> its file extensions.

    Examples
    --------
    >>> sorted(formats())
    ['csv', 'hdf5', 'parquet', 'tdms', 'uff']
    """
    _load_entry_points()
    return {name: cls.extensions for name, cls in _READERS.items()}


def reader_class(path, format=None):
    """The :class:`Reader` class of a file.

    Parameters
    ----------
    path : str
        The file.
    format : str, optional
        A registered format name; default the one of the file's extension.

    Returns
    -------
    type
    """
    _load_entry_points()
    if format is not None:
        if format not in _READERS:
            raise AKFInputError(f"unknown measurement format {format!r}; known: {sorted(_READERS)}")
        return _READERS[format]
    ext = os.path.splitext(os.fspath(path))[1].lower()
    for cls in reversed(list(_READERS.values())):
        if ext in cls.extensions:
            return cls
    raise AKFInputError(f"{os.fspath(path)}: no reader for extension {ext!r}; known: "
                        + ", ".join(f"{n} ({', '.join(e)})" for n, e in formats().items())
                        + "; or name the format (format = \"csv\")")


def open_file(path: str | os.PathLike, format: str | None = None, time_column: str = "time",
              group: str | None = None) -> Reader:
    """A :class:`Reader` for one file.

    Parameters
    ----------
    path : str
        The file.
    format : str, optional
        A registered format name; default the one of the file's extension.
    time_column, group
        As :class:`Reader`.

    Returns
    -------
    Reader

    Examples
    --------
    >>> import os, tempfile
    >>> path = os.path.join(tempfile.mkdtemp(), "run.csv")
    >>> import pandas as pd
    >>> pd.DataFrame({"time": [0.0, 0.001, 0.002], "SG13": [1.0, 2.0, 3.0]}).to_csv(path, index=False)
    >>> reader = open_file(path)
    >>> reader.channels(), reader.timing().n_steps
    (['SG13'], 3)
    """
    return reader_class(path, format)(path, time_column=time_column, group=group)
