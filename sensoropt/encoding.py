"""Layout encodings for the placement GA: a candidate set of sensors of any kind at any place on
any structure (:class:`CandidateSet`), and the thesis' rectangular plate grid (:class:`PlateGrid`,
TH §4), one way to build such a set.

On any structure (:class:`CandidateSet`) a candidate is a sensor string -- a strain gauge on a
member, an extensometer or a row of the model's strain operator (``strain:13``), an accelerometer
on a node and direction (``acc:8:y``) -- placed at a point: the node, or the centroid of the nodes
a strain output reads.  The *move* mutation steps to one of the nearest candidates of the same
kind (a KD-tree on those points); the distance between layouts matches sensors by that spacing.

On the plate grid (:class:`PlateGrid`) a sensor is a gene triple ``(ix, iy, kind)`` -- grid column and row (1-based, node number
``(iy - 1)(nx + 1) + ix``) and kind ``"ex"``, ``"ey"``, ``"gxy"`` (strain components) or
``"acc"`` (out-of-plane acceleration w).  Only *admissible* sensors are candidates: a sensor
whose observation row is identically zero (an accelerometer on the clamped edge, e_x along a
clamped edge y = 0) cannot measure anything.  Internally a layout is the sorted tuple of
candidate indices, so orderings of the same sensors are one individual, and no sensor appears
twice.  The operators keep layouts unique, admissible and within the per-type budget by
construction; :meth:`PlateGrid.repair` is the safety net.
"""
from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from scipy.optimize import linear_sum_assignment

from core_akf.checks import AKFInputError, CandidateLayout
from core_akf.rank import zero_rows
from core_akf.structure import STRAIN_COMPONENTS

if TYPE_CHECKING:
    from core_akf.structure import Structure

STRAIN_KINDS = STRAIN_COMPONENTS
KINDS = STRAIN_KINDS + ("acc",)
#: directions an accelerometer measures (w: a plate's out-of-plane translation)
TRANSLATIONS = ("x", "y", "z", "w")


def sensor_type(kind):
    """The budget type of a sensor kind.

    Parameters
    ----------
    kind : str
        A candidate kind ("strain", "ex", "acc", "acc:z").

    Returns
    -------
    str
        "acc" for an accelerometer kind, else "strain".
    """
    return "acc" if kind == "acc" or str(kind).startswith("acc:") else "strain"


def candidate_sensors(structure, kinds):
    """Every sensor of some kinds on a structure, as sensor strings.

    Parameters
    ----------
    structure : Structure
    kinds : sequence of str
        ``"strain"`` every strain output (``"ex"``, ``"ey"``, ``"gxy"`` one component of a
        plate's), ``"acc"`` an accelerometer on every free translational DOF (``"acc:z"`` only
        direction z; ``w`` on a plate).

    Returns
    -------
    list of str
    """
    out = []
    for kind in kinds:
        if kind in STRAIN_KINDS and structure.strain_kind != "node":
            raise AKFInputError(f"unknown sensor kind {kind!r} on {structure.name!r}: {list(STRAIN_KINDS)} are a "
                                "plate's strain components; its strain outputs are members or extensometers: use 'strain'")
        if kind == "strain" or kind in STRAIN_KINDS:
            out += [lab for lab in structure.strain_labels if kind == "strain" or lab.endswith(f":{kind}")]
        elif kind == "acc" or kind.startswith("acc:"):
            dirs = [d for d in structure.dof_names if d in TRANSLATIONS] if kind == "acc" else [kind.split(":", 1)[1]]
            bad = [d for d in dirs if d not in structure.dof_names]
            if bad:
                raise AKFInputError(f"kind {kind!r}: this structure has no direction {bad[0]!r} (it has "
                                    f"{list(structure.dof_names)})")
            for node in structure.user_node_ids:
                for d in dirs:
                    try:
                        structure.dof_index(node, d)
                    except AKFInputError:
                        continue              # a support: no response there
                    out.append(f"acc:{node}:{d}")
        else:
            raise AKFInputError(f"unknown sensor kind {kind!r}; use 'strain', 'acc', 'acc:DIR' (e.g. 'acc:z') or a "
                                f"plate's strain components {list(STRAIN_KINDS)}")
    if not out:
        raise AKFInputError(f"no admissible sensor position for kinds {list(kinds)} on {structure.name!r}")
    return list(dict.fromkeys(out))


def _kind_of(sensor):
    """The kind of a sensor for the GA: ``strain`` (member, extensometer, operator row), a plate's
    strain component, or ``acc:DIR``."""
    if sensor.kind == "strain":
        return sensor.component if sensor.component is not None else "strain"
    return f"{sensor.kind}:{sensor.direction}"



def sensor_label(sensor) -> object:
    """A sensor as its string: a string as it is, a record of :attr:`PlacementResult.layout
    <sensoropt.ga.PlacementResult>` (``{"sensor": "acc:8:y", ...}``) or a
    :class:`~core_akf.sensors.Sensor` as its label; anything else unchanged (for the caller to refuse).

    Parameters
    ----------
    sensor : str, dict or Sensor

    Returns
    -------
    str, or ``sensor`` itself

    Examples
    --------
    >>> sensor_label({"sensor": "acc:8:y", "kind": "acc:y", "node": 8})
    'acc:8:y'
    """
    if isinstance(sensor, Mapping) and "sensor" in sensor:
        return str(sensor["sensor"])
    label = getattr(sensor, "label", None)
    return label if isinstance(label, str) else sensor

class CandidateSet:
    """Admissible sensors of any kind at any place of a structure, and the GA operators on layouts.

    Layouts are sorted tuples of candidate indices.  Outputs that are identically zero (a strain
    gauge on a member that cannot strain) are not candidates.

    Parameters
    ----------
    structure : Structure
        Any model (truss, plate, one's own from matrices, 2-D or 3-D).
    kinds : sequence of str
        Kinds that may be placed (:func:`candidate_sensors`); default strain gauges on every
        strain output and accelerometers on every free translational DOF.
    n_sensors : int, optional
        Total number of sensors (or ``budget``).
    budget : dict, optional
        Sensors per type, e.g. ``{"strain": 4, "acc": 2}`` (fixed counts).
    candidates : sequence of str, optional
        The candidate set itself (instead of ``kinds``); each must exist on the structure and
        measure something.
    neighbours : int
        Candidates of the same kind a *move* mutation may step to (nearest first).

    Examples
    --------
    Strain gauges on the S17 truss' members and accelerometers on its free joints:

    >>> from core_akf.models import s17_truss
    >>> candidates = CandidateSet(s17_truss(), kinds=("strain", "acc"), budget={"strain": 2, "acc": 1})
    >>> layout = candidates.from_sensors(["strain:13", "strain:9", "acc:8:y"])
    >>> candidates.sensors(layout), candidates.counts(layout), candidates.is_valid(layout)
    (['strain:9', 'strain:13', 'acc:8:y'], {'strain': 2, 'acc': 1}, True)
    """

    def __init__(self, structure: Structure, kinds: Sequence[str] = ("strain", "acc"), n_sensors: int | None = None,
                 budget: Mapping[str, int] | None = None, candidates: Sequence[str] | None = None, neighbours: int = 8):
        from scipy.spatial import cKDTree

        from core_akf.sensors import as_layout, selection_matrices

        self.structure = structure
        kinds = (kinds,) if isinstance(kinds, str) else tuple(kinds)
        if candidates is None:
            if not kinds:
                raise AKFInputError("give the kinds of sensor to place (e.g. ['strain', 'acc']) or the candidates")
            candidates = candidate_sensors(structure, kinds)
            given = False
        else:
            candidates, given = [str(c) for c in candidates], True
        layout = as_layout(candidates)
        labels = [s.label for s in layout]                 # as_layout refuses duplicates
        S = selection_matrices(structure, layout)          # every candidate exists (a clear error names one)
        dead = zero_rows(S["strain"] + S["disp"] + S["vel"] + S["acc"])
        if given and dead.any():
            raise AKFInputError(f"candidate sensor(s) {[labels[i] for i in np.flatnonzero(dead)][:5]} measure nothing "
                                "(an output that is identically zero on this structure)")
        keep = np.flatnonzero(~dead)
        if keep.size == 0:
            raise AKFInputError(f"no admissible sensor position for kinds {list(kinds)}")
        layout = [layout[i] for i in keep]
        self.labels = [labels[i] for i in keep]
        self.candidates = list(self.labels)
        self.kind = np.array([_kind_of(s) for s in layout])
        self.type = np.array([sensor_type(k) for k in self.kind])
        self.kinds = tuple(dict.fromkeys(self.kind.tolist()))
        self.node = np.array([s.node if s.node is not None else -1 for s in layout])
        self.position = self._positions(layout)
        self.index = {lab: i for i, lab in enumerate(self.labels)}
        self.budget = self._budget(n_sensors, budget)
        self.n_sensors = sum(self.budget.values()) if self.budget else int(n_sensors)
        pts = np.unique(np.round(self.position, 9), axis=0)
        if pts.shape[0] > 1:
            d, _ = cKDTree(pts).query(pts, k=2)
            self.spacing = float(np.median(d[:, 1]))
        else:
            self.spacing = 1.0
        self.span = float(np.max(np.ptp(self.position, axis=0)) / self.spacing) if pts.shape[0] > 1 else 1.0
        self.neighbours = {}
        for kind in self.kinds:
            pool = np.flatnonzero(self.kind == kind)
            k = min(int(neighbours) + 1, pool.size)
            _, nb = cKDTree(self.position[pool]).query(self.position[pool], k=k)
            nb = np.asarray(nb).reshape(pool.size, -1)        # (candidates, k), nearest first
            for row, g in enumerate(pool):
                self.neighbours[int(g)] = [int(pool[j]) for j in nb[row] if pool[j] != g]

    def _positions(self, layout):
        """Where each candidate is (m): an accelerometer's node; a strain output's centroid of the
        nodes it reads, weighted by the size of its coefficients."""
        s = self.structure
        nodes = s.nodes
        ndof = len(s.dof_names)
        out = np.zeros((len(layout), nodes.shape[1]))
        for i, sensor in enumerate(layout):
            if sensor.kind != "strain":
                out[i] = nodes[s.node_rows([sensor.node])[0]]
                continue
            key = sensor.member if sensor.member is not None else (sensor.node, sensor.component)
            row = s.strain_matrix[[s.strain_index(key)]]
            row = np.abs(row.toarray() if hasattr(row, "toarray") else np.asarray(row)).ravel()
            cols = np.flatnonzero(row)
            node_rows = s.free_dofs[cols] // ndof
            w = np.bincount(node_rows, weights=row[cols], minlength=nodes.shape[0])
            out[i] = w @ nodes / w.sum()
        return out

    def _budget(self, n_sensors, budget):
        types_allowed = set(self.type)
        if budget is not None:
            if n_sensors is not None and int(n_sensors) != sum(budget.values()):
                raise AKFInputError(f"n_sensors = {n_sensors} disagrees with the budget {budget}")
            budget = {str(k): int(v) for k, v in budget.items() if int(v) != 0}
            if not budget:
                raise AKFInputError("the sensor budget is empty: give at least one sensor")
            for t, c in budget.items():
                if t not in ("strain", "acc"):
                    raise AKFInputError(f"budget types are 'strain' and 'acc', got {t!r}")
                if c < 0:
                    raise AKFInputError(f"budget for {t!r} must be >= 0, got {c}")
                if t not in types_allowed:
                    raise AKFInputError(f"budget has {c} {t} sensor(s) but kinds {list(self.kinds)} allow none")
                avail = int(np.sum(self.type == t))
                if c > avail:
                    raise AKFInputError(f"{c} {t} sensors requested but only {avail} admissible positions")
            return budget
        if n_sensors is None or int(n_sensors) < 1:
            raise AKFInputError("give n_sensors >= 1 or a budget per sensor type")
        if int(n_sensors) > len(self.candidates):
            raise AKFInputError(f"{n_sensors} sensors requested but only {len(self.candidates)} admissible positions")
        return None


    # ------------------------------------------------------------------ conversions
    def sensors(self, layout: Sequence[int]) -> list[str]:
        """Sensor strings of a layout.

        Parameters
        ----------
        layout : sequence of int
            Candidate indices.

        Returns
        -------
        list of str
            ``"strain:13"``, ``"acc:8:y"``, ``"strain:58:ex"``.
        """
        return [self.labels[i] for i in layout]

    def records(self, layout: Sequence[int]) -> list[dict]:
        """A layout as records for tables and JSON.

        Parameters
        ----------
        layout : sequence of int
            Candidate indices.

        Returns
        -------
        list of dict
            ``{"sensor": "acc:8:y", "kind": "acc:y", "node": 8}`` per sensor (node None for a strain
            output that is not at one node).
        """
        return [{"sensor": self.labels[i], "kind": str(self.kind[i]),
                 "node": int(self.node[i]) if self.node[i] >= 0 else None} for i in layout]

    def from_sensors(self, sensors: Sequence[str]) -> CandidateLayout:
        """A layout from sensor strings.

        Parameters
        ----------
        sensors : sequence of str
            Candidates, e.g. ``["strain:13", "acc:8:y"]`` (or a result's ``layout`` records).

        Returns
        -------
        tuple of int
            Sorted candidate indices.
        """
        from core_akf.sensors import as_layout

        out = []
        for s in map(sensor_label, sensors):
            label = as_layout([s])[0].label
            if label not in self.index:
                raise AKFInputError(f"sensor {s!r} is not a candidate (kinds {list(self.kinds)}; an output that "
                                    "measures nothing is not one)")
            out.append(self.index[label])
        if len(set(out)) != len(out):
            raise AKFInputError(f"duplicate sensors in {list(sensors)}")
        return tuple(sorted(out))

    # ------------------------------------------------------------------ validity
    def counts(self, layout: Sequence[int]) -> dict[str, int]:
        """Sensors per type in a layout.

        Parameters
        ----------
        layout : sequence of int
            Candidate indices.

        Returns
        -------
        dict
            ``{"strain": n, "acc": m}``.
        """
        t = self.type[list(layout)]
        return {k: int(np.sum(t == k)) for k in ("strain", "acc")}

    def is_genome(self, genes: object) -> bool:
        """Whether genes read back (from a GA checkpoint) are a canonical layout: a sorted list of
        candidate indices that :meth:`is_valid` accepts.

        Parameters
        ----------
        genes : object

        Returns
        -------
        bool
        """
        if not isinstance(genes, list) or not all(isinstance(g, int) and not isinstance(g, bool) for g in genes):
            return False
        return genes == sorted(genes) and all(0 <= g < len(self.candidates) for g in genes) and self.is_valid(tuple(genes))

    def is_valid(self, layout: Sequence[int]) -> bool:
        """Whether a layout is admissible: distinct sensors, the right number, the budget kept.

        Parameters
        ----------
        layout : sequence of int
            Candidate indices.

        Returns
        -------
        bool
        """
        if len(set(layout)) != len(layout) or len(layout) != self.n_sensors:
            return False
        if not all(self._ok(g) for g in layout):
            return False
        if self.budget:
            c = self.counts(layout)
            return all(c.get(t, 0) == n for t, n in self.budget.items()) and sum(c.values()) == self.n_sensors
        return True

    #: which candidates may be placed (None: all); set by :meth:`restrict`
    allowed = None

    def restrict(self, allowed: np.ndarray) -> None:
        """Allow only some candidates (forbidden regions, :class:`~sensoropt.constraints.Constraints`):
        the others are never drawn, moved or flipped to, and a gene on one is redrawn among the
        allowed candidates of its type by :meth:`repair`.

        Parameters
        ----------
        allowed : ndarray of bool (n_candidates,)
        """
        allowed = np.asarray(allowed, bool)
        if allowed.shape != (len(self.candidates),):
            raise AKFInputError(f"allowed must hold one flag per candidate ({len(self.candidates)})")
        if not allowed.any():
            raise AKFInputError("no candidate is allowed")
        self.allowed = None if allowed.all() else allowed

    def with_size(self, n_sensors: int) -> CandidateSet:
        """The same candidates (and restriction) for layouts of ``n_sensors`` sensors of any type.

        Parameters
        ----------
        n_sensors : int

        Returns
        -------
        CandidateSet
        """
        import copy

        if not 1 <= int(n_sensors) <= len(self.candidates):
            raise AKFInputError(f"a layout must have 1..{len(self.candidates)} sensors, got {n_sensors}")
        out = copy.copy(self)
        out.budget, out.n_sensors = None, int(n_sensors)
        return out

    def _ok(self, g):
        """Whether candidate ``g`` may be placed."""
        return self.allowed is None or bool(self.allowed[g])

    def allowed_indices(self, sensor_type: str | None = None) -> np.ndarray:
        """The candidates that may be placed (of one type: ``strain`` or ``acc``).

        Parameters
        ----------
        sensor_type : str, optional

        Returns
        -------
        ndarray of int
        """
        return self._pool(sensor_type)

    def _pool(self, t=None):
        pool = np.arange(len(self.candidates)) if t is None else np.flatnonzero(self.type == t)
        return pool if self.allowed is None else pool[self.allowed[pool]]

    def random_layout(self, rng: np.random.Generator) -> CandidateLayout:
        """A random admissible layout.

        Parameters
        ----------
        rng : numpy.random.Generator

        Returns
        -------
        tuple of int
            Sorted candidate indices.
        """
        if self.budget:
            parts = [rng.choice(self._pool(t), size=n, replace=False) for t, n in self.budget.items()]
            return tuple(sorted(int(i) for p in parts for i in p))
        if self.allowed is not None:
            return tuple(sorted(int(i) for i in rng.choice(self._pool(), size=self.n_sensors, replace=False)))
        return tuple(sorted(int(i) for i in rng.choice(len(self.candidates), size=self.n_sensors, replace=False)))

    def repair(self, genes: Sequence[int], rng: np.random.Generator) -> CandidateLayout:
        """A valid canonical layout from any gene list.

        Duplicates and surplus of a type are dropped, missing sensors filled with random unused
        admissible positions of the type.

        Parameters
        ----------
        genes : sequence of int
            Candidate indices, possibly invalid.
        rng : numpy.random.Generator

        Returns
        -------
        tuple of int
        """
        seen, keep = set(), []
        for g in genes:
            g = int(g)
            if 0 <= g < len(self.candidates) and g not in seen and self._ok(g):
                seen.add(g)
                keep.append(g)
        if self.budget:
            out = []
            for t, n in self.budget.items():
                mine = [g for g in keep if self.type[g] == t][:n]
                free = np.setdiff1d(self._pool(t), mine)
                if len(mine) < n:
                    mine += [int(i) for i in rng.choice(free, size=n - len(mine), replace=False)]
                out += mine
            return tuple(sorted(out))
        keep = keep[:self.n_sensors]
        if len(keep) < self.n_sensors:
            free = np.setdiff1d(self._pool(), keep)
            keep += [int(i) for i in rng.choice(free, size=self.n_sensors - len(keep), replace=False)]
        return tuple(sorted(keep))

    # ------------------------------------------------------------------ operators
    def crossover_set(self, a: Sequence[int], b: Sequence[int],
                      rng: np.random.Generator) -> tuple[CandidateLayout, CandidateLayout]:
        """Set-based crossover of two layouts.

        Each child draws its sensors (per type when budgeted) from the union of the parents' sensors,
        so shared sensors tend to stay and children are unique.

        Parameters
        ----------
        a, b : sequence of int
            The parents.
        rng : numpy.random.Generator

        Returns
        -------
        tuple
            Two children (layouts).
        """
        def child():
            if self.budget:
                genes = []
                for t, n in self.budget.items():
                    union = sorted({g for g in a + b if self.type[g] == t})
                    genes += [int(i) for i in rng.choice(union, size=min(n, len(union)), replace=False)]
                return self.repair(genes, rng)
            union = sorted(set(a) | set(b))
            return self.repair([int(i) for i in rng.choice(union, size=self.n_sensors, replace=False)], rng)
        return child(), child()

    def _nearest(self, point, kind, exclude, rng):
        """The candidate of ``kind`` nearest to ``point`` (m), not in ``exclude``."""
        pool = np.flatnonzero(self.kind == kind)
        pool = pool[~np.isin(pool, list(exclude))]
        pool = pool if self.allowed is None else pool[self.allowed[pool]]
        if pool.size == 0:
            return None
        d = np.sum((self.position[pool] - point) ** 2, axis=1)
        best = pool[d <= d.min() * (1 + 1e-12)]
        return int(rng.choice(best))

    def crossover_intermediate(self, a: Sequence[int], b: Sequence[int], rng: np.random.Generator,
                               alpha: float = 0.5) -> tuple[CandidateLayout, CandidateLayout]:
        """Intermediate crossover on the positions of paired sensors.

        ``c = p1 + u (p2 - p1)`` with ``u ~ U(-alpha, 1 + alpha)`` per coordinate, then the nearest
        unused candidate of the kind of either parent (of the first under a budget).

        Parameters
        ----------
        a, b : sequence of int
            The parents.
        rng : numpy.random.Generator
        alpha : float
            Extent beyond the parents.

        Returns
        -------
        tuple
            Two children (layouts).
        """
        def child():
            genes, used = [], set()
            for g1, g2 in zip(a, b):
                u = rng.uniform(-alpha, 1 + alpha, size=self.position.shape[1])
                point = self.position[g1] + u * (self.position[g2] - self.position[g1])
                kind = self.kind[g1] if (self.budget or rng.random() < 0.5) else self.kind[g2]
                g = self._nearest(point, kind, used, rng)
                if g is not None:
                    genes.append(g)
                    used.add(g)
            return self.repair(genes, rng)
        return child(), child()

    def _flip(self, g, others, rng):
        """Another allowed kind at the place of candidate ``g`` (same type under a budget)."""
        here = np.flatnonzero(np.all(np.abs(self.position - self.position[g]) <= 1e-9 * self.spacing, axis=1))
        here = [int(h) for h in here if self.kind[h] != self.kind[g] and h not in others and self._ok(h)
                and (not self.budget or self.type[h] == self.type[g])]
        return int(rng.choice(here)) if here else None

    def _move(self, g, others, rng):
        """One of the nearest candidates of the kind of ``g`` (its KD-tree neighbours), unused."""
        near = [h for h in self.neighbours[g] if h not in others and self._ok(h)]
        return int(rng.choice(near)) if near else None

    def mutate(self, layout: Sequence[int], rng: np.random.Generator, indpb: float | None = None, p_move: float = 0.5,
               p_jump: float = 0.3) -> CandidateLayout:
        """Per-sensor mutation.

        Each sensor changes with probability ``indpb``: a *move* to a neighbouring candidate of the
        same kind, a *jump* anywhere, or a *kind flip* (another kind at the same place).

        Parameters
        ----------
        layout : sequence of int
        rng : numpy.random.Generator
        indpb : float, optional
            Probability per sensor (default 1/n).
        p_move : float
            Probability that a change is a move.
        p_jump : float
            Probability that a change is a jump (the rest are kind flips).

        Returns
        -------
        tuple of int
        """
        genes = list(layout)
        indpb = 1.0 / len(genes) if indpb is None else indpb
        hit = rng.random(len(genes)) < indpb
        if not hit.any():
            hit[rng.integers(len(genes))] = True
        for j in np.flatnonzero(hit):
            g = genes[j]
            others = set(genes) - {g}
            r = rng.random()
            if r < p_move:
                ng = self._move(g, others, rng)
            elif r < p_move + p_jump:
                pool = self._pool(self.type[g] if self.budget else None)
                pool = pool[~np.isin(pool, list(others | {g}))]
                ng = int(rng.choice(pool)) if pool.size else None
            else:
                ng = self._flip(g, others, rng)
            if ng is not None:
                genes[j] = ng
        return self.repair(genes, rng)

    def mutate_adaptive(self, layout: Sequence[int], rng: np.random.Generator, scale: float) -> CandidateLayout:
        """Gaussian steps on the positions, shrinking over the generations.

        Steps of ``scale`` candidate spacings on the positions, a random kind change with
        probability ``scale / span``, repaired to the nearest unused candidate.

        Parameters
        ----------
        layout : sequence of int
        rng : numpy.random.Generator
        scale : float
            Standard deviation of a step (candidate spacings).

        Returns
        -------
        tuple of int
        """
        genes, used = [], set()
        for g in layout:
            point = self.position[g] + rng.normal(0, scale * self.spacing, size=self.position.shape[1])
            kind = self.kind[g]
            if rng.random() < scale / max(self.span, 1.0):
                kinds = [k for k in self.kinds if not self.budget or sensor_type(k) == self.type[g]]
                kind = str(rng.choice(kinds))
            ng = self._nearest(point, kind, used, rng)
            if ng is not None:
                genes.append(ng)
                used.add(ng)
        return self.repair(genes, rng)

    def distance(self, a: Sequence[int], b: Sequence[int]) -> float:
        """Distance between two layouts.

        The minimum-cost matching of their sensors, cost = distance in candidate spacings + 1 for a
        different kind; 0 for the same layout.

        Parameters
        ----------
        a, b : sequence of int

        Returns
        -------
        float
        """
        C = self.costs(np.asarray(list(a), int)[None], np.asarray(list(b), int)[None])[0]
        r, c = linear_sum_assignment(C)
        return float(C[r, c].sum())

    def costs(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Matching costs of pairs of layouts: distance in units of the candidate spacing, + 1 for
        a different kind.

        Parameters
        ----------
        a, b : ndarray (P, k) of int
            P pairs of layouts of k sensors (candidate indices).

        Returns
        -------
        ndarray (P, k, k)
            ``C[p, i, j]``: the cost of matching sensor i of ``a[p]`` with sensor j of ``b[p]``.
        """
        C = np.linalg.norm(self.position[a][:, :, None] - self.position[b][:, None, :], axis=-1) / self.spacing
        return C + (self.kind[a][:, :, None] != self.kind[b][:, None, :])

    def diversity(self, layouts: Sequence[Sequence[int]]) -> float:
        """Mean distance of each layout to its nearest *other* individual (TH's diversity).

        Above :data:`DIVERSITY_SAMPLE` layouts, of that many spread evenly over the population (the
        pairs grow as n^2: a population of a million would need 7 TiB and days).

        Parameters
        ----------
        layouts : sequence of layouts

        Returns
        -------
        float
        """
        n = len(layouts)
        if n < 2:
            return 0.0
        if n > DIVERSITY_SAMPLE:
            layouts = [layouts[i] for i in np.linspace(0, n - 1, DIVERSITY_SAMPLE).astype(int)]
            n = DIVERSITY_SAMPLE
        D = np.full((n, n), np.inf)
        i, j = np.triu_indices(n, 1)
        sizes = {len(l) for l in layouts}
        k = sizes.pop() if len(sizes) == 1 else 0
        if 1 <= k <= _ENUMERATE_UP_TO:
            # every pair at once: the cheapest of the k! matchings (what linear_sum_assignment finds
            # one pair at a time), summed in row order as it does
            L = np.array([list(l) for l in layouts], int)
            perms = np.array(list(itertools.permutations(range(k))), int)         # (k!, k)
            step = max(1, _ENTRIES_PER_CALL // perms.size)
            for s in range(0, i.size, step):
                C = self.costs(L[i[s:s + step]], L[j[s:s + step]])                # (p, k, k)
                D[i[s:s + step], j[s:s + step]] = C[:, np.arange(k), perms].sum(axis=-1).min(axis=-1)
        else:
            for a, b in zip(i, j):
                D[a, b] = self.distance(layouts[a], layouts[b])
        D = np.minimum(D, D.T)
        return float(np.mean(D.min(axis=1)))


#: the diversity of a larger population is measured on this many of its layouts
DIVERSITY_SAMPLE = 500
#: layouts of up to this many sensors are matched by enumerating the k! matchings of all pairs at
#: once (120 at 5); larger ones pair by pair with linear_sum_assignment
_ENUMERATE_UP_TO = 5
#: (pairs x k! x k) entries per batched call: bounds its memory to ~16 MB
_ENTRIES_PER_CALL = 2_000_000


class PlateGrid(CandidateSet):
    """Admissible sensor candidates of a plate on its grid, and the GA operators on layouts.

    Parameters
    ----------
    structure : Structure
        A plate from :func:`core_akf.models.plate`.
    kinds : sequence of str
        Allowed kinds, a subset of ``("ex", "ey", "gxy", "acc")``.
    n_sensors : int, optional
        Total number of sensors (any allowed kind), or ``budget``.
    budget : dict, optional
        Sensors per type, e.g. ``{"strain": 3, "acc": 1}`` (fixed counts).
    """

    def __init__(self, structure: Structure, kinds: Sequence[str] = STRAIN_KINDS, n_sensors: int | None = None,
                 budget: Mapping[str, int] | None = None):
        kinds = (kinds,) if isinstance(kinds, str) else tuple(kinds)
        bad = [k for k in kinds if k not in KINDS]
        if bad or not kinds:
            raise AKFInputError(f"unknown sensor kind(s) {bad or kinds}; use some of {list(KINDS)}")
        if structure.strain_kind != "node":
            raise AKFInputError("sensor placement works on plate models (strains at nodes)")
        self.structure = structure
        self.kinds = tuple(dict.fromkeys(kinds))
        xs, ys = np.unique(np.round(structure.nodes[:, 0], 12)), np.unique(np.round(structure.nodes[:, 1], 12))
        self.nx, self.ny = len(xs), len(ys)
        if self.nx * self.ny != structure.n_nodes:
            raise AKFInputError("the plate's nodes do not form a rectangular grid")
        ix = np.searchsorted(xs, np.round(structure.nodes[:, 0], 12)) + 1
        iy = np.searchsorted(ys, np.round(structure.nodes[:, 1], 12)) + 1
        dead = zero_rows(structure.strain_operator)      # identically zero outputs (e_x along a clamp)
        cands = []
        for node in range(1, structure.n_nodes + 1):
            for kind in self.kinds:
                if kind == "acc":
                    try:
                        structure.dof_index(node, "w")
                    except (AKFInputError, ValueError, KeyError):
                        continue
                else:
                    if dead[structure.strain_labels.index(f"strain:{node}:{kind}")]:
                        continue
                cands.append((node, int(ix[node - 1]), int(iy[node - 1]), kind))
        if not cands:
            raise AKFInputError(f"no admissible sensor position for kinds {list(self.kinds)}")
        self.candidates = cands
        self.node = np.array([c[0] for c in cands])
        self.ix = np.array([c[1] for c in cands])
        self.iy = np.array([c[2] for c in cands])
        self.kind = np.array([c[3] for c in cands])
        self.type = np.array([sensor_type(k) for k in self.kind])
        self.index = {(c[1], c[2], c[3]): i for i, c in enumerate(cands)}
        self.labels = [f"acc:{c[0]}:w" if c[3] == "acc" else f"strain:{c[0]}:{c[3]}" for c in cands]
        self.position = structure.nodes[self.node - 1]
        self.span = max(self.nx, self.ny)           # grid units across the plate
        self.spacing = 1.0
        self.budget = self._budget(n_sensors, budget)
        self.n_sensors = sum(self.budget.values()) if self.budget else int(n_sensors)

    # ------------------------------------------------------------------ conversions
    def triples(self, layout: Sequence[int]) -> list[tuple[int, int, str]]:
        """A layout as the thesis' genes.

        Parameters
        ----------
        layout : sequence of int

        Returns
        -------
        list of (int, int, str)
            ``(ix, iy, kind)`` per sensor.
        """
        return [(int(self.ix[i]), int(self.iy[i]), str(self.kind[i])) for i in layout]

    def records(self, layout: Sequence[int]) -> list[dict]:
        """A layout as records for tables and JSON.

        Parameters
        ----------
        layout : sequence of int

        Returns
        -------
        list of dict
            ``{"sensor": "strain:58:ex", "kind": "ex"|"ey"|"gxy"|"acc", "node": id}`` (1-based node ids).
        """
        return [{"sensor": self.labels[i], "kind": str(self.kind[i]), "node": int(self.node[i])} for i in layout]

    def from_sensors(self, sensors: Sequence[str | tuple[int, str]]) -> CandidateLayout:
        """A layout from sensor strings or ``(node, kind)`` pairs.

        Parameters
        ----------
        sensors : sequence of str or (int, str)

        Returns
        -------
        tuple of int
            Sorted candidate indices.
        """
        out = []
        for s in map(sensor_label, sensors):
            if isinstance(s, str):
                parts = s.split(":")
                node, kind = int(parts[1]), ("acc" if parts[0] == "acc" else parts[2])
            else:
                node, kind = int(s[0]), str(s[1])
            hits = [i for i, c in enumerate(self.candidates) if c[0] == node and c[3] == kind]
            if not hits:
                raise AKFInputError(f"sensor {s!r} is not an admissible position (off the mesh, clamped, "
                                    f"or kind not in {list(self.kinds)})")
            out.append(hits[0])
        if len(set(out)) != len(out):
            raise AKFInputError(f"duplicate sensors in {list(sensors)}")
        return tuple(sorted(out))

    # ------------------------------------------------------------------ operators
    def _nearest(self, ix, iy, kind, exclude, rng):
        """The admissible candidate of ``kind`` nearest to grid point (ix, iy), not in ``exclude``."""
        pool = np.flatnonzero(self.kind == kind)
        pool = pool[~np.isin(pool, list(exclude))]
        pool = pool if self.allowed is None else pool[self.allowed[pool]]
        if pool.size == 0:
            return None
        d = (self.ix[pool] - ix) ** 2 + (self.iy[pool] - iy) ** 2
        best = pool[d == d.min()]
        return int(rng.choice(best))

    def crossover_intermediate(self, a: Sequence[int], b: Sequence[int], rng: np.random.Generator,
                               alpha: float = 0.5) -> tuple[CandidateLayout, CandidateLayout]:
        """The thesis' baseline: intermediate crossover on the (ix, iy) genes of paired sensors.

        ``c = p1 + u (p2 - p1)`` with ``u ~ U(-alpha, 1 + alpha)``, rounded to the grid, kinds taken
        from either parent, then repaired to the nearest admissible unused position.

        Parameters
        ----------
        a, b : sequence of int
            The parents.
        rng : numpy.random.Generator
        alpha : float
            Extent beyond the parents.

        Returns
        -------
        tuple
            Two children (layouts).
        """
        def child():
            genes, used = [], set()
            for g1, g2 in zip(a, b):
                u = rng.uniform(-alpha, 1 + alpha, size=2)
                ix = int(np.clip(np.rint(self.ix[g1] + u[0] * (self.ix[g2] - self.ix[g1])), 1, self.nx))
                iy = int(np.clip(np.rint(self.iy[g1] + u[1] * (self.iy[g2] - self.iy[g1])), 1, self.ny))
                kind = self.kind[g1] if rng.random() < 0.5 else self.kind[g2]
                if self.budget:
                    kind = self.kind[g1]  # keep the type counts
                g = self._nearest(ix, iy, kind, used, rng)
                if g is not None:
                    genes.append(g)
                    used.add(g)
            return self.repair(genes, rng)
        return child(), child()

    def _move(self, g, others, rng):
        """The nearest admissible candidate of the same kind one grid step (of 8) away."""
        step = rng.choice([(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (-1, -1), (1, -1), (-1, 1)])
        return self._nearest(self.ix[g] + step[0], self.iy[g] + step[1], self.kind[g], others | {g}, rng)

    def _flip(self, g, others, rng):
        """Another allowed kind at the grid point of ``g`` (of the same type under a budget)."""
        kinds = [k for k in self.kinds if k != self.kind[g] and (not self.budget or sensor_type(k) == self.type[g])]
        if not kinds:
            return None
        ng = self.index.get((int(self.ix[g]), int(self.iy[g]), str(rng.choice(kinds))))
        return None if ng in others or (ng is not None and not self._ok(ng)) else ng

    def mutate_adaptive(self, layout: Sequence[int], rng: np.random.Generator, scale: float) -> CandidateLayout:
        """The thesis' baseline: Gaussian steps on the (ix, iy) genes.

        Steps of standard deviation ``scale`` (grid units, shrinking over the generations), random
        kind changes with probability ``scale / max(nx, ny)``, repaired to the nearest admissible
        unused point.

        Parameters
        ----------
        layout : sequence of int
        rng : numpy.random.Generator
        scale : float

        Returns
        -------
        tuple of int
        """
        genes, used = [], set()
        for g in layout:
            ix = int(np.clip(np.rint(self.ix[g] + rng.normal(0, scale)), 1, self.nx))
            iy = int(np.clip(np.rint(self.iy[g] + rng.normal(0, scale)), 1, self.ny))
            kind = self.kind[g]
            if rng.random() < scale / max(self.nx, self.ny):
                kinds = [k for k in self.kinds if not self.budget or sensor_type(k) == self.type[g]]
                kind = str(rng.choice(kinds))
            ng = self._nearest(ix, iy, kind, used, rng)
            if ng is not None:
                genes.append(ng)
                used.add(ng)
        return self.repair(genes, rng)

    def distance(self, a: Sequence[int], b: Sequence[int]) -> float:
        """Distance between two layouts.

        The minimum-cost matching of their sensors, cost = grid distance + 1 for a different kind; 0
        for the same layout.

        Parameters
        ----------
        a, b : sequence of int

        Returns
        -------
        float
        """
        C = self.costs(np.asarray(list(a), int)[None], np.asarray(list(b), int)[None])[0]
        r, c = linear_sum_assignment(C)
        return float(C[r, c].sum())

    def costs(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Matching costs of pairs of layouts: grid distance, + 1 for a different kind.

        Parameters
        ----------
        a, b : ndarray (P, k) of int
            P pairs of layouts of k sensors (candidate indices).

        Returns
        -------
        ndarray (P, k, k)
        """
        C = np.hypot(self.ix[a][:, :, None] - self.ix[b][:, None, :], self.iy[a][:, :, None] - self.iy[b][:, None, :])
        return C + (self.kind[a][:, :, None] != self.kind[b][:, None, :])


def make_encoding(structure: Structure, kinds: Sequence[str] | None = None, n_sensors: int | None = None,
                  budget: Mapping[str, int] | None = None, candidates: Sequence[str] | None = None) -> CandidateSet:
    """The encoding of a placement problem.

    The thesis' plate grid (:class:`PlateGrid`) for a plate whose nodes form a rectangular grid
    and plate kinds (``ex ey gxy acc``), else a :class:`CandidateSet` of ``candidates`` or of
    ``kinds``.

    Parameters
    ----------
    structure : Structure
    kinds : sequence of str, optional
        Kinds that may be placed (default: strain gauges on every strain output).
    n_sensors : int, optional
        Total number of sensors (or ``budget``).
    budget : dict, optional
        Sensors per type.
    candidates : sequence of str, optional
        The candidate set itself.

    Returns
    -------
    CandidateSet or PlateGrid

    Examples
    --------
    >>> from core_akf.models import s17_truss, th_plate
    >>> type(make_encoding(th_plate(), n_sensors=3)).__name__, type(make_encoding(s17_truss(), n_sensors=3)).__name__
    ('PlateGrid', 'CandidateSet')
    """
    if candidates is None:
        if kinds is None:
            kinds = STRAIN_KINDS if structure.strain_kind == "node" else ("strain",)
        kinds = (kinds,) if isinstance(kinds, str) else tuple(kinds)
        if structure.strain_kind == "node" and set(kinds) <= set(KINDS) and "w" in structure.dof_names:
            xs, ys = np.unique(np.round(structure.nodes[:, 0], 12)), np.unique(np.round(structure.nodes[:, 1], 12))
            if len(xs) * len(ys) == structure.n_nodes and structure.nodes.shape[1] == 2:
                return PlateGrid(structure, kinds=kinds, n_sensors=n_sensors, budget=budget)
    return CandidateSet(structure, kinds=kinds or (), n_sensors=n_sensors, budget=budget, candidates=candidates)
