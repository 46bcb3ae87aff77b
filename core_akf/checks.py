"""The inputs' contract, in one place: the type aliases of the public API (what an input may be),
the toolkit's exceptions (what is raised when it is not) and the checks that raise them.

**Type aliases** (for annotations; nothing here runs or checks shapes).  A sensor is a string in
the sensor grammar (``"strain:13"``, ``"strain:70:ex"``, ``"acc:8:y"``) or a
:class:`~core_akf.sensors.Sensor`; a force location is ``"8:y"`` or ``(8, "y")``; a covariance is
one level, a vector of variances, a matrix, or (for measurement noise) a table of variances per
sensor kind.  SI units throughout.  The array aliases carry their shape and unit as
:data:`typing.Annotated` metadata, as dynamax's ``types.py`` does with jaxtyping: ``Measurements``
is an array of shape (N, m) -- N time steps, m sensors -- in the sensors' SI units.  Letters: N
time steps, m sensors, n generalised coordinates (2n structural states), n_p unknown forces,
n_a = 2n + n_p augmented states, B a batch of problems.

**Exceptions.**  All derive from :class:`ValueError`, so that callers who only know the standard
library can still catch bad input in one place.

**Checks.**  Small input-validation helpers shared by the public functions; each raises
:class:`AKFInputError` naming the argument.
"""
from __future__ import annotations

import os
import re
from collections.abc import Mapping, Sequence
from typing import Annotated, Protocol, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray


# ------------------------------------------------------------------------------ exceptions
class AKFInputError(ValueError):
    """Invalid user input: wrong shape, NaN data, unknown id, duplicate sensor, ...

    A message that echoes a long value (a list of 10^5 modes) is shown cut to
    :data:`MESSAGE_CHARS` around what it says (:func:`shortened`).
    """

    def __str__(self):
        return shortened(super().__str__())


#: the longest message an input error carries
MESSAGE_CHARS = 2000
#: a quoted value longer than this is cut in a message
_VALUE_CHARS = 160


def shortened(message: str) -> str:
    """A message with every bracketed list or quoted text longer than a few lines cut to its
    start and its length, and the whole cut to :data:`MESSAGE_CHARS`.

    Parameters
    ----------
    message : str

    Returns
    -------
    str

    Examples
    --------
    >>> shortened("modes must be distinct, got " + str([1] * 1000))[:60]
    'modes must be distinct, got [1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1'
    >>> len(shortened("x" * 10**6)) <= MESSAGE_CHARS
    True
    """
    if len(message) <= _VALUE_CHARS:
        return message

    def cut(match):
        text = match.group(0)
        if len(text) <= _VALUE_CHARS:
            return text
        return f"{text[:_VALUE_CHARS - 40]} ... ({len(text):,} characters)" + text[-1]

    out = re.sub(r"\[[^\[\]\n]*\]|'[^'\n]*'|\"[^\"\n]*\"", cut, message)
    if len(out) > MESSAGE_CHARS:
        out = out[:MESSAGE_CHARS - 40] + f" ... ({len(message):,} characters)"
    return out


class ModelError(AKFInputError):
    """An invalid structural model (singular or non-symmetric mass matrix, ...)."""


class UndetectableError(AKFInputError):
    """The sensor set makes the augmented system undetectable (PBH test failed).

    Attributes
    ----------
    report : core_akf.statespace.DetectabilityReport
        Which eigenvalues fail the test and by how much.
    """

    def __init__(self, report):
        self.report = report
        super().__init__(
            "the sensor set is not detectable for the augmented state "
            "(the force/state estimate would drift or diverge):\n" + str(report)
            + "\nAdd strain or displacement sensors, use a Matérn force model or dummy displacements, or "
            "pass allow_undetectable=True to run the filter anyway."
        )


# ---------------------------------------------------------------------------- type aliases
class SensorLike(Protocol):
    """What a :class:`core_akf.sensors.Sensor` is to an annotation: an object with a ``kind`` and a
    ``label`` (structural, so that this module imports none of the modules that use it)."""

    kind: str

    @property
    def label(self) -> str:
        """The sensor's string, e.g. ``"acc:8:y"``."""


class Reference(Protocol):
    """The truth of a record, to compare an estimate with (a :class:`core_akf.simulate.Simulation`
    is one): the loads (N, n_p) in N and the strains (N, n_strain) in m/m."""

    loads: NDArray[np.float64]
    strains: NDArray[np.float64]


#: a sensor: its string (``"strain:13"``) or a :class:`core_akf.sensors.Sensor`
SensorSpec = Union[str, SensorLike]
Layout = Sequence[SensorSpec]
ForceSpec = Union[str, tuple[int, str]]
Forces = Sequence[ForceSpec]
#: a force location as the library returns it: 1-based node id and direction
ForceLocation = tuple[int, str]
Covariance = Union[float, ArrayLike]
NoiseCovariance = Union[float, ArrayLike, Mapping[str, float]]
#: damping of a model: a modal ratio (one, or one per mode), ``("rayleigh", alpha, beta)`` or None
Damping = Union[float, Sequence[float], tuple, None]
#: a random stream: a seed or a numpy Generator
Seed = Union[int, np.random.Generator, None]

FloatArray = NDArray[np.float64]
#: measurements: one row per time step, one column per sensor, SI (m/m, m/s^2, m/s, m)
Measurements = Annotated[ArrayLike, "(N, m) SI"]
#: a batch of measurement sets, one per layout
BatchMeasurements = Annotated[ArrayLike, "(B, N, m) SI"]
#: force histories, one column per force location
ForceHistories = Annotated[ArrayLike, "(N, n_p) N"]
#: one signal over time
Signal = Annotated[FloatArray, "(N,)"]
#: a time grid
Time = Annotated[FloatArray, "(N,) s"]
#: a square matrix (K, M, C, a covariance), or a stack of them
Matrix = Annotated[ArrayLike, "(..., n, n)"]
#: a layout as the placement GA holds it: sorted candidate indices (0-based)
CandidateLayout = tuple[int, ...]



# ---------------------------------------------------------------------------------- checks
def install_hint(extra: str) -> str:
    """The command that installs the optional dependencies ``extra`` into this installation.

    From a source folder (an editable install) it names that folder; from a local folder or wheel
    (pip's ``direct_url.json``) that path; else the distribution on the package index.

    Parameters
    ----------
    extra : str
        An extra of ``pyproject.toml`` ("tdms", "dask", "opensees", ...).

    Returns
    -------
    str
        e.g. ``python -m pip install -e "/home/me/akf[tdms]"``.

    Examples
    --------
    >>> install_hint("tdms").startswith("python -m pip install")
    True
    """
    import json
    import os
    from importlib import metadata
    from urllib.parse import unquote, urlparse

    folder = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    try:
        with open(os.path.join(folder, "pyproject.toml"), encoding="utf-8") as fh:
            if 'name = "akf-toolkit"' in fh.read():
                return f'python -m pip install -e "{folder}[{extra}]"'
    except OSError:
        pass
    try:
        url = json.loads(metadata.distribution("akf-toolkit").read_text("direct_url.json") or "{}").get("url", "")
    except (metadata.PackageNotFoundError, ValueError):
        url = ""
    if url.startswith("file://"):
        return f'python -m pip install "{unquote(urlparse(url).path)}[{extra}]"'
    return f'python -m pip install "akf-toolkit[{extra}]"'


def as_finite_array(value, name, ndim=None, shape=None, dtype=float):
    """Return ``value`` as a finite float array, or raise :class:`AKFInputError` naming it.

    Parameters
    ----------
    value : array_like
        The values to check.
    name : str
        What the values are, for the message ("measurements", "x0").
    ndim : int, optional
        The number of dimensions the array must have.
    shape : tuple of int, optional
        The shape the array must have.
    dtype : type, optional
        The type to convert to (default float).

    Returns
    -------
    ndarray
        ``value`` as an array of ``dtype``.

    Raises
    ------
    AKFInputError
        For values that are not numbers, NaN or infinite values (the first one located), or
        another dimension or shape.

    Examples
    --------
    >>> as_finite_array([1, 2], "dt").tolist()
    [1.0, 2.0]
    """
    if np.iscomplexobj(value):
        raise AKFInputError(f"{name} is complex; the filter works on real data (take .real, or the magnitude, first)")
    try:
        arr = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise AKFInputError(f"{name} must be numeric: {exc}") from None
    if ndim is not None and arr.ndim not in np.atleast_1d(ndim):
        raise AKFInputError(f"{name} must have {ndim} dimension(s), got shape {arr.shape}")
    if shape is not None:
        for axis, (want, got) in enumerate(zip(shape, arr.shape)):
            if want is not None and want != got:
                raise AKFInputError(
                    f"{name} has shape {arr.shape}; expected {tuple('*' if s is None else s for s in shape)}"
                    f" (axis {axis} should be {want})"
                )
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))
        first = tuple(int(i) for i in bad[0])
        raise AKFInputError(
            f"{name} contains {len(bad)} NaN/inf value(s); first at index {first}"
        )
    return arr


def check_numeric_kind(value, name):
    """Refuse measurements that numpy would convert without a word: complex values (their
    imaginary part dropped), text (numbers as strings) and true/false values (as 0/1).

    Parameters
    ----------
    value : array_like
    name : str
        What the values are, for the message.
    """
    try:
        arr = value if isinstance(value, np.ndarray) else np.asarray(value)
    except (TypeError, ValueError):
        return                  # ragged or nested: the conversion to floats names it
    if np.iscomplexobj(arr):
        raise AKFInputError(f"{name} is complex; the filter works on real data (take .real, or the magnitude, first)")
    kind = arr.dtype.kind
    if kind in "USb":
        raise AKFInputError(f"{name} must be numeric (NaN for a missing sample), not "
                            f"{'true/false values' if kind == 'b' else 'text'}: convert the channels to numbers in SI "
                            "first")


def as_measurements(value, name="measurements", ndim=None):
    """Return measurements as a float array in which NaN marks a missing sample.

    A missing sample (NaN) is data the filter skips; an infinite value or text is an error.

    Parameters
    ----------
    value : array_like (..., N, m)
        The record, one column per channel (SI).
    name : str
        What the values are, for the message.
    ndim : int or tuple of int, optional
        The number of dimensions the array must have.

    Returns
    -------
    ndarray
        ``value`` as floats, NaN where a sample is missing.

    Raises
    ------
    AKFInputError
        For text, complex or infinite values, another dimension, or a record without one
        observed sample.

    Examples
    --------
    >>> as_measurements([[1.0, float("nan")], [2.0, 3.0]]).tolist()
    [[1.0, nan], [2.0, 3.0]]
    """
    check_numeric_kind(value, name)
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise AKFInputError(f"{name} must be numeric (NaN for a missing sample): {exc}") from None
    if ndim is not None and arr.ndim not in np.atleast_1d(ndim):
        raise AKFInputError(f"{name} must have {ndim} dimension(s), got shape {arr.shape}")
    infinite = np.isinf(arr)
    if infinite.any():
        bad = np.argwhere(infinite)
        raise AKFInputError(f"{name} contains {len(bad)} infinite value(s); first at index {tuple(int(i) for i in bad[0])} "
                            "(a missing sample is NaN, not inf)")
    if arr.size and np.isnan(arr).all():
        raise AKFInputError(f"{name} has no observed sample: every value is NaN (missing)")
    return arr


def is_real(value):
    """Whether ``value`` is one real number (Python's or numpy's), not true/false.

    Parameters
    ----------
    value : object

    Returns
    -------
    bool
    """
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def is_integer(value):
    """Whether ``value`` is one integer (Python's or numpy's), not true/false.

    Parameters
    ----------
    value : object

    Returns
    -------
    bool
    """
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def check_positive(value, name):
    """A positive finite real number (a length, a modulus, a density), else an error naming it.

    Parameters
    ----------
    value : object
    name : str
        The argument, for the message.

    Returns
    -------
    float
    """
    if not is_real(value) or not np.isfinite(value) or value <= 0:
        raise AKFInputError(f"{name} must be a positive number, got {value!r}")
    return float(value)


def as_time_step(dt, name="time step dt"):
    """A time step as a positive finite float (s); text, an array of more than one value or a
    true/false value is named, not converted.

    Parameters
    ----------
    dt : float
    name : str
        What the value is, for the message.

    Returns
    -------
    float

    Examples
    --------
    >>> as_time_step(1e-3)
    0.001
    """
    value = None
    if isinstance(dt, np.ndarray) and dt.ndim == 0:
        dt = dt.item()
    if is_real(dt):
        value = float(dt)
    if value is None or not np.isfinite(value) or value <= 0:
        raise AKFInputError(f"{name} must be a positive number of seconds, got {shortened(repr(dt))}")
    return value


def as_seed(seed, name="seed"):
    """A seed checked: None, a whole number >= 0 or a :class:`numpy.random.Generator` (returned as
    is); a negative, fractional, true/false or text seed is named, not passed on to numpy.

    Parameters
    ----------
    seed : int, numpy.random.Generator or None
    name : str
        What the value is, for the message.

    Returns
    -------
    int, numpy.random.Generator or None

    Examples
    --------
    >>> as_seed(3)
    3
    """
    if seed is None or isinstance(seed, np.random.Generator):
        return seed
    if is_integer(seed) and seed >= 0:
        return int(seed)
    raise AKFInputError(f"{name} must be a whole number >= 0, got {shortened(repr(seed))}")


def as_count(value, name, minimum=0):
    """A whole number >= ``minimum`` (a population, a number of generations): an integral float
    (6.0) is taken, a fractional one, text or true/false is named.

    Parameters
    ----------
    value : int
    name : str
        What the value is, for the message.
    minimum : int

    Returns
    -------
    int

    Examples
    --------
    >>> as_count(6.0, "population", 2)
    6
    """
    if not (is_real(value) and np.isfinite(value) and value == int(value) and value >= minimum):
        raise AKFInputError(f"{name} must be a whole number >= {minimum}, got {shortened(repr(value))}")
    return int(value)


def as_probability(value, name):
    """A probability in [0, 1], checked.

    Parameters
    ----------
    value : float
    name : str
        What the value is, for the message.

    Returns
    -------
    float
    """
    if not (is_real(value) and 0 <= value <= 1):
        raise AKFInputError(f"{name} must be a probability between 0 and 1, got {shortened(repr(value))}")
    return float(value)


def as_n_jobs(n_jobs, name="n_jobs"):
    """A number of workers checked: a whole number >= 1, or -1 (every core) and below as joblib
    counts them.

    Parameters
    ----------
    n_jobs : int
    name : str
        What the value is, for the message.

    Returns
    -------
    int
    """
    if is_integer(n_jobs) and n_jobs != 0:
        return int(n_jobs)
    raise AKFInputError(f"{name} must be a whole number of workers >= 1 (or -1: every core), got "
                        f"{shortened(repr(n_jobs))}")


def check_square_symmetric(mat, name, rtol=1e-9):
    """Raise :class:`ModelError` unless ``mat`` is a square symmetric matrix.

    Parameters
    ----------
    mat : array_like (n, n)
        The matrix (a stiffness, mass or damping matrix).
    name : str
        Its name in the message ("K", "M").
    rtol : float
        Largest asymmetry accepted, relative to the largest magnitude of ``mat``.
    """
    if mat.ndim != 2 or mat.shape[0] != mat.shape[1]:
        raise ModelError(f"{name} must be square, got shape {mat.shape}")
    scale = np.max(np.abs(mat)) if mat.size else 0.0
    asym = np.max(np.abs(mat - mat.T)) if mat.size else 0.0
    if asym > rtol * max(scale, np.finfo(float).tiny):
        sym = name.split()[-1]
        raise ModelError(f"{name} is not symmetric (max |{sym} - {sym}^T| = {asym:.3g}, max |{sym}| = {scale:.3g})")


def check_positive_definite(mat, name):
    """Raise :class:`ModelError` unless ``mat`` is symmetric positive definite.

    Parameters
    ----------
    mat : array_like (n, n)
        The matrix (a mass matrix).
    name : str
        Its name in the message.
    """
    check_square_symmetric(mat, name)
    try:
        np.linalg.cholesky(mat)
    except np.linalg.LinAlgError:
        w = np.linalg.eigvalsh(mat)
        raise ModelError(
            f"{name} is singular or not positive definite (smallest eigenvalue {w[0]:.3g}, "
            f"largest {w[-1]:.3g}); check for DOFs without mass or a missing support"
        ) from None


#: a variance above this (in SI units squared) is a unit mistake: it would overflow the filter
_MAX_VARIANCE = 1e100


def check_covariance(mat, name, definite=False):
    """Check a covariance matrix, or a stack of them.

    The tests are free of units (strain variances of 1e-16 next to acceleration variances of 1
    are common): a diagonal entry must be >= 0 (> 0 if definite), and the correlation matrix
    ``D^-1/2 C D^-1/2`` (unit diagonal) must have no eigenvalue below ``-n eps`` (definite: none
    below ``n eps``), the rounding level of an eigenvalue solver on it (Weyl).  An asymmetry above
    1e-9 of the larger diagonal entry of the pair is a mistake, not the rounding of the products
    that formed the matrix (about n eps).

    Parameters
    ----------
    mat : array_like (..., n, n)
        The covariance (leading batch axes allowed), in squared units of its variables.
    name : str
        Its name in the message ("R", "initial covariance P0").
    definite : bool
        Require positive definiteness, as a measurement-noise covariance must be (default:
        semi-definite).

    Returns
    -------
    ndarray (..., n, n)
        ``mat`` as a float array.

    Raises
    ------
    AKFInputError
        For a matrix that is not finite, real, square, symmetric or (semi-)definite.
    """
    arr = as_finite_array(mat, name)
    if arr.ndim < 2 or arr.shape[-1] != arr.shape[-2]:
        raise AKFInputError(f"{name} must be a square matrix, got shape {arr.shape}")
    n = arr.shape[-1]
    flat = arr.reshape(-1, n, n)
    where = (lambda b: f" (batch entry {b})") if arr.ndim > 2 else (lambda b: "")
    big = np.max(np.abs(arr), initial=0.0)
    if big > _MAX_VARIANCE:
        raise AKFInputError(f"{name} has entries up to {big:.3g}: not a physical variance in SI units squared "
                            f"(above {_MAX_VARIANCE:g}); check the units")
    for b, C in enumerate(flat):
        d = np.diag(C)
        low = int(np.argmin(d)) if n else 0
        if n and (d[low] < 0 or (definite and d[low] == 0)):
            need = "> 0: every channel needs some noise" if definite else ">= 0"
            raise AKFInputError(f"{name} must be positive {'definite' if definite else 'semi-definite'}{where(b)}; "
                                f"its variance at position {low + 1} is {d[low]:.3g} (variances must be {need})")
        off = C - np.diag(d)
        if not np.any(off):
            continue
        scale = np.sqrt(np.outer(d, d))
        asym = np.abs(C - C.T)
        if np.any(asym > 1e-9 * np.maximum(np.maximum.outer(d, d), np.finfo(float).tiny)):
            i, j = np.unravel_index(int(np.argmax(asym)), asym.shape)
            raise AKFInputError(f"{name} is not symmetric{where(b)}: entries ({i + 1}, {j + 1}) and ({j + 1}, {i + 1}) "
                                f"are {C[i, j]:.6g} and {C[j, i]:.6g}")
        orphan = (scale == 0) & (np.abs(off) > n * np.finfo(float).eps * np.max(d))
        if np.any(orphan):
            i, j = np.argwhere(orphan)[0]
            raise AKFInputError(f"{name} is not positive semi-definite{where(b)}: entry ({i + 1}, {j + 1}) is "
                                f"{C[i, j]:.3g} although a variance of that pair is 0")
        corr = np.divide(0.5 * (C + C.T), scale, out=np.zeros_like(C), where=scale > 0)
        w = np.linalg.eigvalsh(corr)
        tol = n * np.finfo(float).eps
        if w[0] < -tol or (definite and w[0] <= tol):
            raise AKFInputError(f"{name} must be positive {'definite' if definite else 'semi-definite'}{where(b)}; "
                                f"its correlation matrix has the eigenvalue {w[0]:.3g} (correlations above 1 "
                                "or inconsistent ones)")
    return arr


def available_memory():
    """Bytes of memory available to a new allocation.

    Returns
    -------
    int or None
        ``MemAvailable`` on Linux, else the physical memory; None if unknown.
    """
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(n_steps, floats_per_step, what, fix, items="time steps"):
    """Refuse, before allocating, a record that would not fit in memory.

    Parameters
    ----------
    n_steps : float
        Time steps (or other ``items``) of the record.
    floats_per_step : float
        float64 values held per step.
    what : str
        What the record is, for the message ("a 2 s record at dt = 0.001 s").
    fix : str
        What to do instead, for the message.
    items : str
        What ``n_steps`` counts (default "time steps").

    Raises
    ------
    AKFInputError
        When the record needs more than 80 % of the available memory.
    """
    need = 8.0 * float(n_steps) * float(floats_per_step)
    have = available_memory()
    if have is not None and need > 0.8 * have:
        raise AKFInputError(f"{what}: {n_steps:.4g} {items} need about {need / 2 ** 30:.3g} GiB, but this machine "
                            f"has {have / 2 ** 30:.3g} GiB available; {fix}")


def distinct_labels(labels, limit, where, what):
    """A list of labels checked before anything is built from it: at most ``limit`` (all there
    are), none twice.

    Parameters
    ----------
    labels : sequence of str
    limit : int
        How many distinct labels there are to choose from.
    where : str
        The key that lists them, for the message ("[output] strains").
    what : str
        What they are ("strain outputs").

    Returns
    -------
    list of str

    Raises
    ------
    AKFInputError
        For a longer list or a label listed twice.

    Examples
    --------
    >>> distinct_labels(["strain:5", "strain:13"], 34, "[output] strains", "strain outputs")
    ['strain:5', 'strain:13']
    """
    labels = list(labels)
    repeat = first_repeat(labels)
    if repeat:
        i, j, label = repeat
        raise AKFInputError(f"{where} lists {label!r} twice (entries {i + 1} and {j + 1})"
                            + (f" in {len(labels)} entries; the model has {limit} {what}" if len(labels) > limit else ""))
    if len(labels) > limit:
        raise AKFInputError(f"{where} lists {len(labels)} labels; the model has {limit} {what}")
    return labels


def first_repeat(values):
    """The first value that repeats.

    Parameters
    ----------
    values : sequence
        Hashable values (sensor labels, node ids).

    Returns
    -------
    tuple or None
        ``(i, j, value)`` with positions ``i < j`` (0-based) of the first value that repeats, or
        ``None`` when every value is distinct.

    Examples
    --------
    >>> first_repeat(["strain:5", "acc:4:y", "strain:5"])
    (0, 2, 'strain:5')
    """
    seen = {}
    for j, v in enumerate(values):
        if v in seen:
            return seen[v], j, v
        seen[v] = j
    return None


def check_n_modes(n_modes, name="n_modes"):
    """A number of modes, checked.

    Parameters
    ----------
    n_modes : int
    name : str
        Its name in the message.

    Returns
    -------
    int
        ``n_modes`` as an int >= 1; ``2.5``, ``"all"`` or ``True`` are clear errors.
    """
    if isinstance(n_modes, (bool, np.bool_)) or not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
        raise AKFInputError(f"{name} must be a whole number of modes >= 1, got {n_modes!r} (leave it out for the full "
                            "model up to the size where it is reduced anyway)")
    return int(n_modes)


#: a number followed by text: a unit written into the cells
_NUMBER_THEN_TEXT = re.compile(r"^\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*[^\d\s.,;+-]")
#: a number alone (pandas adds ".1", ".2" to a repeated header cell)
_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
#: how a column name may look to be quoted in a message (a file that is no table is not quoted)
_COLUMN_NAME = re.compile(r"^[\w .:/()\[\]%^*#+-]{1,64}$")


def describe_cell(cell) -> str:
    """What a cell that is not a usable number holds, in words: messages name a problem, never a
    file's content.

    Parameters
    ----------
    cell : object
        The cell as a table reader gives it (text, a number, NaN for an empty cell).

    Returns
    -------
    str
        "an empty cell", "an infinite number", "a number followed by text (...)", "a number with
        a decimal comma (...)", "a fractional number" or "text, not a number".

    Examples
    --------
    >>> describe_cell("12,5")
    'a number with a decimal comma (the files are read with a decimal point)'
    >>> describe_cell(float("nan"))
    'an empty cell'
    """
    if cell is None or (isinstance(cell, float) and np.isnan(cell)):
        return "an empty cell"
    if is_real(cell):
        value = float(cell)
        return ("an infinite number" if not np.isfinite(value) else "a fractional number" if value != round(value)
                else "a number")
    text = str(cell).strip()
    if not text or text.lower() == "nan":
        return "an empty cell"
    if _NUMBER_THEN_TEXT.match(text):
        return "a number followed by text (a unit in the cells? give numbers alone, and the unit as the channel's unit)"
    if re.fullmatch(r"[-+]?\d+,\d+", text):
        return "a number with a decimal comma (the files are read with a decimal point)"
    return "text, not a number"


def found_columns(columns) -> str:
    """The columns a table was found to have, quoted only when they look like column names: a
    file that is no table (a system file, a log) has its first line read as a header.

    Parameters
    ----------
    columns : sequence
        The header's column names.

    Returns
    -------
    str
        "found [...]" or a count of columns that do not look like names.
    """
    numbers = [bool(_NUMBER.fullmatch(re.sub(r"\.\d+$", "", str(c)).strip())) for c in columns]
    if columns and all(numbers):
        return "found numbers in the first row: the table has no header row (add one that names the columns)"
    if any(numbers):
        return (f"found {len(columns)} column(s), {sum(numbers)} of them named by a number: is the header row "
                "missing? (add one that names the columns)")
    if len(columns) > 1 and all(_COLUMN_NAME.match(str(c)) for c in columns):
        shown = [str(c) for c in columns[:20]]
        return f"found {shown}" + (f" and {len(columns) - 20} more" if len(columns) > 20 else "")
    return (f"found {len(columns)} column(s) whose header does not look like column names (is it a comma-separated "
            "table with a header row?)")
