"""Placement constraints: forbidden regions, a minimum spacing, a cost per sensor and a budget.

How the GA honours them:

- **forbidden** boxes and nodes remove candidates: a forbidden candidate is never drawn, moved to
  or kept (:meth:`~sensoropt.encoding.CandidateSet.restrict`; a gene that lands on one is
  redrawn among the allowed candidates of its type);
- **min_spacing** and **budget** are penalties: a layout with two sensors closer than
  ``min_spacing`` or costing more than ``budget`` is infeasible (the GA's penalty fitness), so
  it never survives against a feasible one, and :class:`Constrained` reports it as ``inf``.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from core_akf.checks import AKFInputError

if TYPE_CHECKING:
    from .encoding import CandidateSet
    from .objective import Objective


@dataclass(frozen=True)
class Constraints:
    """What a layout may cost and where its sensors may go.

    Parameters
    ----------
    cost : dict, optional
        Cost of one sensor by type (``strain``, ``acc``) or kind (``ex``, ``acc:z``; a kind's
        entry wins over its type's); default 1 each.
    budget : float, optional
        The most a layout may cost.
    forbidden : list of boxes, optional
        ``[x0, y0, x1, y1]`` (2-D) or ``[x0, y0, z0, x1, y1, z1]`` (3-D), in m: a candidate whose
        position (:attr:`~sensoropt.encoding.CandidateSet.position`) lies in a box (its faces
        included) is never placed.
    forbidden_nodes : list of int, optional
        1-based nodes: an accelerometer or a gauge at one of them, or a member that ends at one,
        is never placed.
    min_spacing : float, optional
        The least distance between any two sensors of a layout (m).

    Examples
    --------
    >>> from core_akf.models import s17_truss
    >>> from sensoropt import CandidateSet
    >>> enc = CandidateSet(s17_truss(), kinds=("strain", "acc"), n_sensors=3)
    >>> rules = Constraints(cost={"strain": 1.0, "acc": 4.0}, budget=6.0)
    >>> rules.cost_of(enc, enc.from_sensors(["strain:5", "strain:9", "acc:8:y"]))
    6.0
    >>> rules.violation(enc, enc.from_sensors(["strain:5", "acc:4:y", "acc:8:y"]))
    'costs 9 (budget 6)'
    """

    cost: Mapping[str, float] | None = None
    budget: float | None = None
    forbidden: Sequence[Sequence[float]] | None = None
    forbidden_nodes: Sequence[int] | None = None
    min_spacing: float | None = None

    def __post_init__(self):
        for name in ("budget", "min_spacing"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise AKFInputError(f"{name} must be a positive number, got {value!r}")
        for k, v in (self.cost or {}).items():
            if not (math.isfinite(v) and v >= 0):
                raise AKFInputError(f"the cost of {k!r} must be a number >= 0, got {v!r}")

    @property
    def active(self) -> bool:
        """Whether any constraint is set (a cost table alone constrains nothing)."""
        return any(v is not None for v in (self.budget, self.forbidden, self.forbidden_nodes, self.min_spacing))

    def costs(self, encoding: CandidateSet) -> np.ndarray:
        """The cost of each candidate.

        Parameters
        ----------
        encoding : CandidateSet

        Returns
        -------
        ndarray (n_candidates,)
        """
        table = dict(self.cost or {})
        known = set(encoding.kinds) | set(encoding.type.tolist()) | {"strain", "acc"}
        unknown = sorted(set(table) - known)
        if unknown:
            raise AKFInputError(f"cost has an entry for {unknown}, which is no sensor type or kind of the candidates: "
                                f"the types are strain and acc, the kinds {list(encoding.kinds)}")
        return np.array([table.get(str(k), table.get(str(t), 1.0)) for k, t in zip(encoding.kind, encoding.type)])

    def cost_of(self, encoding: CandidateSet, layout: Sequence[int]) -> float:
        """The cost of a layout.

        Parameters
        ----------
        encoding : CandidateSet
        layout : sequence of int
            Candidate indices.

        Returns
        -------
        float
        """
        return float(self.costs(encoding)[list(layout)].sum())

    def allowed(self, encoding: CandidateSet) -> np.ndarray:
        """The candidates outside every forbidden box and node.

        Parameters
        ----------
        encoding : CandidateSet

        Returns
        -------
        ndarray of bool (n_candidates,)
        """
        pos = np.asarray(encoding.position, float)
        ok = np.ones(len(encoding.candidates), bool)
        dim = pos.shape[1]
        for box in self.forbidden or ():
            box = np.asarray(box, float)
            if box.size != 2 * dim or not np.all(np.isfinite(box)):
                raise AKFInputError(f"a forbidden box of this {dim}-D model is [{', '.join(['x0', 'y0', 'z0'][:dim])}, "
                                    f"{', '.join(['x1', 'y1', 'z1'][:dim])}] in m, got {box.tolist()}")
            lo, hi = np.minimum(box[:dim], box[dim:]), np.maximum(box[:dim], box[dim:])
            ok &= ~np.all((pos >= lo) & (pos <= hi), axis=1)
        if self.forbidden_nodes:
            structure = encoding.structure
            n_nodes = structure.nodes.shape[0]
            bad = [n for n in self.forbidden_nodes if not 1 <= int(n) <= n_nodes]
            if bad:
                raise AKFInputError(f"forbidden_nodes {bad} are not nodes of the model (1..{n_nodes})")
            ok &= ~np.isin(encoding.node, list(self.forbidden_nodes))
            members = getattr(structure, "members", None)
            if members is not None:
                ends = np.asarray(members)[:, :2]                    # 1-based end nodes
                for i, label in enumerate(encoding.labels):
                    parts = label.split(":")
                    if parts[0] == "strain" and len(parts) == 2 and parts[1].isdigit():
                        m = int(parts[1]) - 1
                        if 0 <= m < len(ends) and np.isin(ends[m], list(self.forbidden_nodes)).any():
                            ok[i] = False
        return ok

    def check(self, encoding: CandidateSet) -> None:
        """Refuse constraints no layout can meet: every candidate forbidden, too few allowed for
        the sensors asked, a budget below the cheapest layout.

        Parameters
        ----------
        encoding : CandidateSet
            The candidates (with their sensor count or budget per type).
        """
        ok = self.allowed(encoding)
        if not ok.any():
            raise AKFInputError("the forbidden regions cover every candidate: no sensor can be placed")
        counts = encoding.budget or {None: encoding.n_sensors}
        for t, n in counts.items():
            pool = ok if t is None else ok & (encoding.type == t)
            if pool.sum() < n:
                what = "sensors" if t is None else f"{t} sensors"
                raise AKFInputError(f"{n} {what} are asked, but only {int(pool.sum())} candidates lie outside the "
                                    "forbidden regions")
        if self.budget is not None:
            costs = self.costs(encoding)
            cheapest = sum(np.sort(costs[ok if t is None else ok & (encoding.type == t)])[:n].sum()
                           for t, n in counts.items())
            if cheapest > self.budget * (1 + 1e-12):
                raise AKFInputError(f"the budget {self.budget:g} is below the cheapest layout of {encoding.n_sensors} "
                                    f"sensors ({cheapest:g}; the cheapest sensor costs {costs[ok].min():g})")

    def violation(self, encoding: CandidateSet, layout: Sequence[int]) -> str | None:
        """What a layout breaks, or None.

        Parameters
        ----------
        encoding : CandidateSet
        layout : sequence of int
            Candidate indices.

        Returns
        -------
        str or None
        """
        return self.checker(encoding)(layout)

    def checker(self, encoding: CandidateSet) -> Checker:
        """:meth:`violation` for many layouts of one candidate set: the costs and the allowed
        candidates are computed once.

        Parameters
        ----------
        encoding : CandidateSet

        Returns
        -------
        Checker
            ``checker(layout) -> str or None``.
        """
        return Checker(self, encoding)


class Checker:
    """:meth:`Constraints.violation` of one candidate set, its costs and allowed candidates
    computed once (a plain object: it travels to parallel workers).

    Parameters
    ----------
    constraints : Constraints
    encoding : CandidateSet
    """

    def __init__(self, constraints: Constraints, encoding: CandidateSet):
        self.rules, self.labels = constraints, list(encoding.labels)
        self.costs = constraints.costs(encoding) if constraints.budget is not None else None
        self.allowed = constraints.allowed(encoding) if (constraints.forbidden or constraints.forbidden_nodes) else None
        self.position = np.asarray(encoding.position, float)

    def __call__(self, layout: Sequence[int]) -> str | None:
        """What ``layout`` (candidate indices) breaks, or None."""
        layout, rules = list(layout), self.rules
        if self.costs is not None:
            c = float(self.costs[layout].sum())
            if c > rules.budget * (1 + 1e-12):
                return f"costs {c:g} (budget {rules.budget:g})"
        if self.allowed is not None:
            bad = [self.labels[g] for g in layout if not self.allowed[g]]
            if bad:
                return f"{', '.join(bad)} in a forbidden region"
        if rules.min_spacing is not None and len(layout) > 1:
            pos = self.position[layout]
            d = np.sqrt(((pos[:, None] - pos[None]) ** 2).sum(-1))
            i, j = np.triu_indices(len(layout), 1)
            k = int(np.argmin(d[i, j]))
            if d[i[k], j[k]] < rules.min_spacing * (1 - 1e-12):
                return (f"{self.labels[layout[i[k]]]} and {self.labels[layout[j[k]]]} are {d[i[k], j[k]]:.4g} m "
                        f"apart (min_spacing {rules.min_spacing:g} m)")
        return None


class Constrained:
    """An objective whose layouts that break :class:`Constraints` score ``inf`` (infeasible).

    Parameters
    ----------
    objective : Objective
        Any placement objective; its other attributes are reached through this one.
    encoding : CandidateSet
    constraints : Constraints
    """

    def __init__(self, objective: Objective, encoding: CandidateSet, constraints: Constraints):
        self.objective, self.encoding, self.constraints = objective, encoding, constraints
        self.n_objectives = getattr(objective, "n_objectives", 1)
        self._violation = constraints.checker(encoding)

    @property
    def robustness(self) -> dict:
        """The inner objective's :attr:`~sensoropt.objective.StrainErrorObjective.robustness` and the
        constraints (kept with a GA checkpoint)."""
        c = self.constraints
        rules = {"cost": dict(c.cost) if c.cost else None, "budget": c.budget, "min_spacing": c.min_spacing,
                 "forbidden": [list(map(float, b)) for b in c.forbidden] if c.forbidden else None,
                 "forbidden_nodes": [int(n) for n in c.forbidden_nodes] if c.forbidden_nodes else None}
        return dict(getattr(self.objective, "robustness", None) or {}, constraints=rules)

    def __getattr__(self, name):
        if name in ("objective", "encoding", "constraints", "_violation"):
            raise AttributeError(name)
        return getattr(self.objective, name)

    def evaluate(self, layouts: Sequence[Sequence[str]]) -> list:
        """The objective of each layout that honours the constraints, ``inf`` for the others.

        Parameters
        ----------
        layouts : sequence of sequence of str

        Returns
        -------
        list
        """
        layouts = list(layouts)
        ok = [self._violation(self.encoding.from_sensors(l)) is None for l in layouts]
        inner = iter(self.objective.evaluate([l for l, k in zip(layouts, ok) if k]) if any(ok) else [])
        bad = math.inf if self.n_objectives == 1 else tuple([math.inf] * self.n_objectives)
        return [next(inner) if k else bad for k in ok]
