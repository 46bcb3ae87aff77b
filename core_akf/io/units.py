"""Units of measured channels, converted to SI once at the boundary (pint).

A channel's unit is a string the units library understands (``"microstrain"``, ``"µε"``,
``"mm/s^2"``, ``"g"``, ``"in/s"``, ...) or a bridge output (``"mV/V"``, ``"V/V"``, ``"µV/V"``) that a
gauge factor and a bridge type turn into strain.  Sensor kinds and their SI units: strain m/m,
acc m/s^2, vel m/s, disp m.  For an acceleration channel ``g`` means standard gravity
(9.80665 m/s^2), not gram; ``mg`` and ``µg`` likewise.

Why pint: it knows every unit a data-acquisition system writes, with prefixes and compound units,
and refuses a unit of the wrong dimension; a table of our own would know only what we thought of.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..checks import AKFInputError
from ..sensors import UNITS

#: the SI unit of each sensor kind (what the filter works in): the one table, :data:`core_akf.sensors.UNITS`
SI_UNITS = UNITS
_SI_PINT = {"strain": "dimensionless", "acc": "m/s^2", "vel": "m/s", "disp": "m"}

#: bridge types: strain = factor * r / GF (``r`` the bridge output in V/V); the quarter bridge with
#: its nonlinearity, ``4 r / (GF (1 + 2 r))`` (one active gauge, NI's "quarter-bridge I")
BRIDGES = {"quarter": 4.0, "half": 2.0, "full": 1.0}

#: acceleration in multiples of standard gravity, as DAQ systems write it
_GRAVITY = {"g": "gravity", "G": "gravity", "mg": "milligravity", "ug": "microgravity", "µg": "microgravity",
            "μg": "microgravity", "g0": "gravity", "gn": "gravity", "g_n": "gravity"}
#: strain as DAQ systems and gauge catalogues abbreviate it (compared case-blind)
_STRAIN_NAMES = {"ue": "microstrain", "µe": "microstrain", "μe": "microstrain", "ustrain": "microstrain",
                 "µstrain": "microstrain", "me": "millistrain", "mstrain": "millistrain", "e": "strain",
                 "ε": "strain", "eps": "strain", "uɛ": "microstrain", "µɛ": "microstrain", "μɛ": "microstrain",
                 "ɛ": "strain"}     # ɛ: the Latin epsilon some catalogues print for ε
#: pint's dimensionless units that no sensor reads in: counts of raw values, and logarithmic levels
#: (matched at the end of a name, so that prefixed ones such as "kilobyte" and "decibel" are caught)
_RAW_COUNTS = ("count", "bit", "byte", "baud")
_LOGARITHMIC = ("bel", "neper", "octave", "decade")
_NOT_PHYSICAL = _RAW_COUNTS + _LOGARITHMIC
#: a unit's power written as digits after its name, as DAQ systems label channels ("m/s2", "m s-2")
_BARE_POWER = re.compile(r"(?<=[A-Za-zµμ])(-?\d+)(?![\d.])")


@lru_cache(maxsize=1)
def registry():
    """The units registry (built once, about a second): strain is dimensionless (``strain``,
    ``m/m``, ``microstrain``, ``µε``, ``µm/m``)."""
    import pint

    try:
        return pint.UnitRegistry(cache_folder=":auto:")      # parsed definitions cached per user: 0.1 s
    except OSError:                                           # no writable cache folder
        return pint.UnitRegistry()


@dataclass(frozen=True)
class Conversion:
    """How one channel becomes SI.

    ``si = sign * scale * raw`` or, for a bridge, strain from the bridge output
    ``r = scale * raw`` in V/V.

    Attributes
    ----------
    unit : str
        The channel's unit.
    scale : float
        Factor to SI (or to V/V for a bridge output).
    bridge : str or None
        "quarter", "half" or "full" for a bridge output.
    gauge_factor : float or None
        Gauge factor of a bridge output.
    """

    unit: str
    scale: float
    bridge: str | None = None
    gauge_factor: float | None = None

    def __call__(self, raw):
        with np.errstate(over="ignore"):        # a value beyond reach is named by the record's check
            r = raw * self.scale
        if self.bridge is None:
            return r
        if self.bridge == "quarter":
            return BRIDGES["quarter"] * r / (self.gauge_factor * (1.0 + 2.0 * r))
        return BRIDGES[self.bridge] * r / self.gauge_factor


_SIMPLE = {("strain", u): 1.0 for u in ("m/m", "strain")} | {("acc", "m/s^2"): 1.0, ("acc", "m/s**2"): 1.0,
                                                                 ("vel", "m/s"): 1.0, ("disp", "m"): 1.0}


def conversion(unit: str, kind: str, channel: str, gauge_factor: float | None = None,
               bridge: str | None = None) -> Conversion:
    """The :class:`Conversion` of a channel to the SI unit of its sensor kind.

    Parameters
    ----------
    unit : str
        The channel's unit (pint: "microstrain", "g", "mm/s", "mV/V").
    kind : str
        The sensor kind: "strain", "acc", "vel" or "disp".
    channel : str
        The channel's name, for messages.
    gauge_factor : float, optional
        Needed for a bridge unit (a voltage ratio).
    bridge : str, optional
        "quarter" (default), "half" or "full".

    Returns
    -------
    Conversion

    Examples
    --------
    >>> conversion("microstrain", "strain", "SG1")(1.0)
    1e-06
    """
    text = "" if unit is None else str(unit).strip()
    if (is_unset(text) or (kind, text) in _SIMPLE) and gauge_factor is None:
        return Conversion(SI_UNITS[kind] if is_unset(text) else text, 1.0)
    if kind == "acc" and text in _GRAVITY:
        text = _GRAVITY[text]
    if kind == "strain" and text.lower() in _STRAIN_NAMES:
        text = _STRAIN_NAMES[text.lower()]
    import pint

    ureg = registry()
    try:
        parsed = _parse(ureg, text)
    except (pint.errors.UndefinedUnitError, pint.errors.DefinitionSyntaxError, AttributeError, TypeError,
            ValueError, AssertionError) as exc:
        raise AKFInputError(f"channel {channel!r}: unknown unit {unit!r} ({exc}); give a unit such as "
                            f"{_examples(kind)}") from None
    raw = [str(u) for u in parsed._units if str(u).endswith(_NOT_PHYSICAL)]
    if raw:
        what = ("a logarithmic level" if raw[0].endswith(_LOGARITHMIC)
                else "a count of raw values (ADC counts, bits or bytes)")
        raise AKFInputError(f"channel {channel!r}: {unit!r} is {what}, not a unit of {kind}; give the unit the "
                            f"channel's values are scaled in, such as {_examples(kind)}")
    if kind == "strain" and _has_dimension(parsed, "V") and not _has_dimension(parsed, "", whole=True):
        raise AKFInputError(f"channel {channel!r} is a voltage in {unit!r}, not a bridge ratio: give it in mV/V (the "
                            "bridge output divided by its excitation voltage) with a gauge_factor, or in microstrain")
    if kind == "strain" and any(_has_dimension(ureg.parse_units(u), "radian") for u in parsed._units):
        raise AKFInputError(f"channel {channel!r}: {unit!r} is an angle, not a strain; give the strain in 'microstrain' "
                            "or 'm/m' (a rotation sensor is a 'disp' sensor of a rotational DOF, in rad)")
    if kind == "strain" and is_bridge_unit(text):
        if gauge_factor is None:
            raise AKFInputError(f"channel {channel!r} is a bridge output in {unit!r}: give its gauge_factor (and "
                                f"bridge: {', '.join(BRIDGES)})")
        bridge = bridge or "quarter"
        if bridge not in BRIDGES:
            raise AKFInputError(f"channel {channel!r}: unknown bridge type {bridge!r}; use one of {list(BRIDGES)}")
        if not gauge_factor > 0:
            raise AKFInputError(f"channel {channel!r}: gauge_factor must be positive, got {gauge_factor!r}")
        return Conversion(str(unit), float(ureg.Quantity(1.0, parsed).to("dimensionless").magnitude), bridge,
                          float(gauge_factor))
    if gauge_factor is not None or bridge is not None:
        raise AKFInputError(f"channel {channel!r}: a gauge factor or bridge type applies to a bridge output "
                            f"(mV/V, V/V) of a strain channel, not to {unit!r}")
    try:
        scale = ureg.Quantity(1.0, parsed).to(_SI_PINT[kind]).magnitude
    except pint.errors.DimensionalityError:
        raise AKFInputError(f"channel {channel!r}: unit {unit!r} is not a unit of {kind} (SI {SI_UNITS[kind]}); "
                            f"give a unit such as {_examples(kind)}") from None
    return Conversion(str(unit), float(scale))


def _parse(ureg, text):
    """pint's units of ``text``; where pint does not know it, again with a power written as bare
    digits after a unit's name read as that power (``m/s2`` as ``m/s^2``, ``m s-2`` as ``m s^-2``)."""
    try:
        return ureg.parse_units(text)
    except Exception:  # noqa: BLE001 -- the caller tells pint's errors apart; the first one is raised
        powered = _BARE_POWER.sub(r"^\1", text)
        if powered == text:
            raise
        try:
            return ureg.parse_units(powered)
        except Exception:  # noqa: BLE001 -- the unit as written is what the message names
            pass
        raise


def _has_dimension(parsed, unit, whole=False):
    """Whether parsed units have the dimensionality of ``unit`` (``whole``: as a whole), or
    contain a unit of it; angles are told apart by name, since pint counts them dimensionless."""
    ureg = registry()
    if unit == "radian":
        return any(str(u) in ("radian", "degree", "arcminute", "arcsecond", "turn", "gradian") or
                   str(u).endswith(("radian", "degree")) for u in parsed._units)
    if whole:
        return ureg.get_dimensionality(parsed) == ureg.get_dimensionality(unit)
    return any(ureg.get_dimensionality(u) == ureg.get_dimensionality(unit) for u in parsed._units)


def is_bridge_unit(unit):
    """Whether a unit is a bridge output (a voltage over a voltage: mV/V, V/V, µV/V).

    Parameters
    ----------
    unit : str

    Returns
    -------
    bool
    """
    if is_unset(unit) or str(unit).strip() in _GRAVITY:
        return False
    if re.fullmatch(r"[a-zA-Zµμ]?V\s*/\s*V", str(unit).strip()):      # V/V itself parses to a plain number
        return True
    try:
        parsed = registry().parse_units(str(unit).strip())
    except Exception:  # noqa: BLE001 -- an unparseable unit is reported where it is converted
        return False
    ureg = registry()
    return any(ureg.get_dimensionality(u) == ureg.get_dimensionality("V") for u in parsed._units)


def _examples(kind):
    return {"strain": "'microstrain', 'm/m' or 'mV/V' with a gauge factor", "acc": "'m/s^2', 'mm/s^2' or 'g'",
            "vel": "'m/s' or 'mm/s'", "disp": "'m' or 'mm'"}[kind]


def is_unset(unit):
    """Whether a unit is what a file writes when it has none (``""``, ``"NONE"``, ``"-"``).

    Parameters
    ----------
    unit : str or None

    Returns
    -------
    bool
    """
    return unit is None or re.fullmatch(r"\s*(none|-|n/a|)\s*", str(unit), flags=re.I) is not None
