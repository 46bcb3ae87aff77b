"""Heterogeneous sensors and sensor layouts.

A :class:`Sensor` is addressed by user ids, 1-based as in the papers:

* ``Sensor("acc", node=4, direction="y")`` -- acceleration (m/s^2); likewise ``"vel"`` (m/s)
  and ``"disp"`` (m, or rad for plate rotations);
* ``Sensor("strain", member=5)`` -- axial strain of truss member 5;
* ``Sensor("strain", node=70, component="ex")`` -- plate surface strain at node 70.

The short string form used in job files is ``"acc:4:y"``, ``"strain:5"`` (truss member),
``"strain:70:ex"`` (plate).  :func:`selection_matrices` turns a layout into the
``S_a, S_v, S_d, S_s`` matrices of S17 eq. 27-30 in a structure's generalised coordinates.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .checks import AKFInputError
from .structure import STRAIN_COMPONENTS, check_structure

KINDS = ("strain", "acc", "vel", "disp")
#: units of each sensor kind (for labels and reports)
UNITS = {"strain": "m/m", "acc": "m/s^2", "vel": "m/s", "disp": "m"}
#: no sensor of a kind reads beyond this, in SI (strain m/m, acc m/s^2, vel m/s, disp m or rad): a
#: sample beyond it is a corrupt value or an overflow code (some DAQs write 9.9e37), not a measurement;
#: 1 m/m is 100 % strain, 1e6 m/s^2 about 100 000 g (the range of shock accelerometers)
MAX_READABLE = {"strain": 1.0, "acc": 1e6, "vel": 1e4, "disp": 1e4}
#: a sensor of each kind, in words (messages)
SENSOR_NAMES = {"strain": "a strain gauge", "acc": "an accelerometer", "vel": "a velocity sensor",
                "disp": "a displacement sensor"}
_ALIASES = {"accel": "acc", "acceleration": "acc", "a": "acc", "velocity": "vel", "v": "vel",
            "displacement": "disp", "d": "disp", "s": "strain", "eps": "strain"}



def readable_limits(layout) -> np.ndarray:
    """Per channel of a layout, the largest magnitude a sensor of its kind reads (:data:`MAX_READABLE`, SI).

    Parameters
    ----------
    layout : sequence of Sensor

    Returns
    -------
    ndarray (m,)
    """
    return np.array([MAX_READABLE[s.kind] for s in layout])

@dataclass(frozen=True)
class Sensor:
    """One sensor: its kind and its location.

    Build it from a string with :meth:`parse` (``"acc:4:y"``, ``"strain:5"``,
    ``"strain:70:ex"``).

    Parameters
    ----------
    kind : str
        "strain", "acc", "vel" or "disp".
    node : int, optional
        The node id (1-based; point sensors and plate strains).
    direction : str, optional
        The measured direction of a point sensor ("x", "y", "z", "w").
    member : int, optional
        The strain output of a truss member, an extensometer or a strain row (1-based).
    component : str, optional
        The plate strain component: "ex", "ey" or "gxy".
    """

    kind: str
    node: int | None = None
    direction: str | None = None
    member: int | None = None
    component: str | None = None

    def __post_init__(self):
        kind = _ALIASES.get(str(self.kind).lower(), str(self.kind).lower())
        if kind not in KINDS:
            raise AKFInputError(f"unknown sensor kind {self.kind!r}; use one of {KINDS}")
        object.__setattr__(self, "kind", kind)
        if kind == "strain":
            if (self.member is None) == (self.node is None):
                raise AKFInputError(f"a strain sensor needs either member= (truss) or node= and component= (plate): {self!r}")
            if self.node is not None and self.component not in STRAIN_COMPONENTS:
                raise AKFInputError(f"plate strain sensor at node {self.node} needs component in {STRAIN_COMPONENTS}, "
                                    f"got {self.component!r}")
        else:
            if self.node is None or self.direction is None:
                raise AKFInputError(f"a {kind} sensor needs node= and direction=: {self!r}")

    @classmethod
    def parse(cls, spec: str | dict | Sensor) -> Sensor:
        """A sensor from its spec.

        Parameters
        ----------
        spec : str, dict or Sensor
            ``"acc:4:y"``, ``"strain:5"``, ``"strain:70:ex"``, a dict of the fields, or a Sensor.

        Returns
        -------
        Sensor

        Examples
        --------
        >>> Sensor.parse("acc:4:y").label
        'acc:4:y'
        """
        if isinstance(spec, Sensor):
            return spec
        if isinstance(spec, dict):
            try:
                return cls(**spec)
            except TypeError as exc:
                raise AKFInputError(f"bad sensor {spec!r}: {exc}") from None
        if not isinstance(spec, str):
            raise AKFInputError(f"a sensor is a 'kind:...' string, a dict or a Sensor, got {spec!r}")
        parts = [p.strip() for p in spec.split(":")]
        kind = _ALIASES.get(parts[0].lower(), parts[0].lower())
        if kind not in KINDS:
            raise AKFInputError(f"unknown sensor kind {parts[0]!r} in {spec!r}; use one of {KINDS}")
        try:
            if kind == "strain" and len(parts) == 2:
                return cls("strain", member=int(parts[1]))
            if kind == "strain" and len(parts) == 3:
                return cls("strain", node=int(parts[1]), component=parts[2])
            if kind in KINDS and len(parts) == 3:
                return cls(kind, node=int(parts[1]), direction=parts[2])
        except ValueError:
            pass
        raise AKFInputError(
            f"cannot read sensor {spec!r}; write e.g. 'acc:4:y', 'strain:5' (truss member) or 'strain:70:ex' (plate)"
        )

    @property
    def label(self):
        """Short id, e.g. ``acc:4:y`` -- the same string :meth:`parse` reads."""
        if self.kind == "strain":
            return f"strain:{self.member}" if self.member is not None else f"strain:{self.node}:{self.component}"
        return f"{self.kind}:{self.node}:{self.direction}"

    def __str__(self):
        return self.label


def sees_accelerations(sensors):
    """Whether a layout holds an accelerometer (the one test behind the ``"auto"`` mode rules).

    Parameters
    ----------
    sensors : sequence of sensor specs

    Returns
    -------
    bool
    """
    return any(s.kind == "acc" for s in as_layout(sensors))


def as_layout(sensors):
    """A tuple of :class:`Sensor` from any sensor specs.

    Parameters
    ----------
    sensors : sequence of str, dict or Sensor

    Returns
    -------
    tuple of Sensor

    Raises
    ------
    AKFInputError
        For an empty set or a sensor given twice.
    """
    if isinstance(sensors, (str, Sensor, dict)):
        sensors = [sensors]
    if not isinstance(sensors, (list, tuple, np.ndarray)):
        raise AKFInputError(f"sensors must be a list of sensor labels (\"acc:4:y\", \"strain:5\"), got {sensors!r}")
    layout = tuple(Sensor.parse(s) for s in sensors)
    if not layout:
        raise AKFInputError("the sensor layout is empty")
    seen = {}
    for i, s in enumerate(layout):
        if s in seen:
            raise AKFInputError(f"duplicate sensor {s.label} (positions {seen[s] + 1} and {i + 1} in the layout)")
        seen[s] = i
    return layout


def selection_matrices(structure, sensors):
    """The observation selection matrices of S17 eq. 27-30 for a layout.

    Parameters
    ----------
    structure : Structure
    sensors : sequence of sensor specs
        m sensors.

    Returns
    -------
    dict
        ``"acc"``, ``"vel"``, ``"disp"``, ``"strain"`` -> ndarray (m, n): one row per sensor (in
        layout order), zero where the sensor is of another kind.

    Raises
    ------
    AKFInputError
        For a sensor that is not on the structure (an unknown node, member or component).
    """
    layout = as_layout(sensors)
    n = structure.n
    out = {k: np.zeros((len(layout), n)) for k in KINDS}
    for i, s in enumerate(layout):
        if s.kind == "strain":
            key = s.member if s.member is not None else (s.node, s.component)
            if (s.member is not None) != (structure.strain_kind == "member"):
                want = "member=" if structure.strain_kind == "member" else "node= and component="
                raise AKFInputError(f"sensor {s.label}: strains on {structure.name!r} are addressed by {want}")
            out["strain"][i] = structure.strain_rows([key])[0]
        else:
            out[s.kind][i] = structure.dof_rows([(s.node, s.direction)])[0]
    return out


def parse_force_locations(structure, forces):
    """Force locations, checked against a structure.

    Parameters
    ----------
    structure : Structure
    forces : sequence of str or (int, str)
        ``"4:y"`` strings or ``(node, direction)`` pairs (1-based node ids).

    Returns
    -------
    list of (int, str)

    Raises
    ------
    AKFInputError
        For an unknown node, a constrained DOF or a location given twice.
    """
    check_structure(structure)
    if isinstance(forces, str):
        forces = [forces]
    if not isinstance(forces, (list, tuple, np.ndarray)):
        raise AKFInputError(f"forces must be a list of force locations (\"4:y\": node 4, direction y), got {forces!r}")
    locs = []
    for f in forces:
        if isinstance(f, str):
            parts = f.split(":")
            if len(parts) != 2:
                raise AKFInputError(f"cannot read force location {f!r}; write e.g. '4:y' (node 4, direction y)")
            try:
                f = (int(parts[0]), parts[1].strip())
            except ValueError:
                raise AKFInputError(f"cannot read force location {f!r}; the node must be an integer") from None
        try:
            node, d = f
        except (TypeError, ValueError):
            raise AKFInputError(f"a force location is (node, direction) or 'node:direction', got {f!r}") from None
        structure.dof_index(node, d)
        if (node, d) in locs:
            raise AKFInputError(f"duplicate force location {node}:{d}")
        locs.append((int(node), d))
    if not locs:
        raise AKFInputError("no force locations given")
    return locs


def strain_ends(structure, member):
    """The two nodes a member-addressed strain output spans.

    Parameters
    ----------
    structure : Structure
    member : int
        The strain output (1-based): a truss member or a virtual extensometer.

    Returns
    -------
    tuple of int or None
        The two node ids; ``None`` for a row of a strain operator of one's own, which has no place.
    """
    if structure.members is not None and 1 <= member <= len(structure.members):
        a, b = structure.members[member - 1]
        return int(a), int(b)
    ends = structure.meta.get("strain_ends", {}).get(int(member))
    return None if ends is None else (int(ends[0]), int(ends[1]))


def sensor_positions(structure, sensors):
    """Where each sensor of a layout is, as a table for ``layout.csv`` and JSON.

    Parameters
    ----------
    structure : Structure
    sensors : sequence of sensor specs

    Returns
    -------
    pandas.DataFrame
        One row per sensor: ``sensor`` (label), ``kind``, ``node`` (node id; the first end of a
        member or extensometer), ``node_b`` (its second end), ``direction`` (point sensors) or
        ``component`` (plate strains), ``x``, ``y``, ``z`` (m; the middle of a member or
        extensometer) and ``source`` (``dof``, ``member``, ``extensometer``, ``operator row k`` or
        ``plate node``).  A strain row of an operator of one's own has no place: its node and
        coordinates are empty.
    """
    import pandas as pd

    rows = []
    xyz = np.zeros((structure.n_nodes, 3))
    xyz[:, : structure.nodes.shape[1]] = structure.nodes
    for s in as_layout(sensors):
        row = {"sensor": s.label, "kind": s.kind, "node": None, "node_b": None, "direction": s.direction,
               "component": s.component, "x": np.nan, "y": np.nan, "z": np.nan, "source": "dof"}
        if s.kind == "strain" and s.member is not None:
            ends = strain_ends(structure, s.member)
            if ends is None:
                row["source"] = f"operator row {s.member}"
            else:
                own = structure.meta.get("strain_ends") or {}
                k = s.member - (min(own) - 1) if own else s.member      # after the operator rows, if any
                kind = "extensometer" if structure.meta.get("extensometers") else "member"
                row.update(node=ends[0], node_b=ends[1], source=f"{kind} {k}")
                row.update(zip("xyz", xyz[structure.node_rows(list(ends))].mean(axis=0)))
        else:
            row["node"] = int(s.node)
            if s.kind == "strain":
                row["source"] = "plate node"
            row.update(zip("xyz", xyz[structure.node_rows([s.node])[0]]))
        rows.append(row)
    frame = pd.DataFrame(rows)
    for col in ("node", "node_b"):
        frame[col] = frame[col].astype("Int64")
    return frame
