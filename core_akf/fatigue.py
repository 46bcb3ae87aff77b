"""Fatigue from stress histories: rainflow counting, S-N curves, Miner damage and damage-equivalent
stress ranges, for many outputs at once and for records that arrive in chunks.

Counting is the rainflow method of ASTM E1049-85 (the reversals of each series; a range between
two points that is no larger than the ranges on either side of it is a full cycle, counted and
taken out; what is left at the end, the residue, gives half cycles).  Here the cycles of all
outputs come out together: the reversals of every output sit in one flat array, and each pass
takes out every full cycle that is ready, in all outputs at once, until none is.  The residue is
all that is carried from one chunk to the next, so a record in pieces gives exactly the cycles of
the record in one piece.

S-N curves (:class:`SNCurve`) are piecewise power laws through points ``(N_i, Δσ_i)``: the
EN 1993-1-9 curves by detail category (:meth:`SNCurve.ec3`), or points of one's own.  Stress
ranges are in Pa throughout; detail categories are named in MPa, as the standard names them.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from .checks import AKFInputError, ArrayLike, FloatArray, as_count, check_memory, check_numeric_kind, is_real
from .structure import STRAIN_COMPONENTS

#: the detail categories of EN 1993-1-9, Table 8.1 ff.: Δσ_C (MPa) at 2e6 cycles
EC3_CATEGORIES = (160, 140, 125, 112, 100, 90, 80, 71, 63, 56, 50, 45, 40, 36)
MPA = 1e6


class SNCurve:
    """An S-N curve: the cycles to failure ``N`` of a stress range ``Δσ``.

    A piecewise power law through points ``(N_i, Δσ_i)`` (N increasing, Δσ decreasing), straight
    between them on log-log axes; above the first point its slope continues, below the last one
    (the cut-off limit) a range does no damage.

    Parameters
    ----------
    cycles : array_like (p,)
        ``N_i``, strictly increasing, p >= 2.
    ranges : array_like (p,)
        ``Δσ_i`` (Pa), strictly decreasing.
    name : str
        What the curve is, for tables.

    Examples
    --------
    >>> c = SNCurve.ec3(71)
    >>> round(float(c.cycles_to_failure(71e6)), 1), c.slopes.round(12).tolist()
    (2000000.0, [3.0, 5.0])
    """

    def __init__(self, cycles: ArrayLike, ranges: ArrayLike, name: str = ""):
        try:
            check_numeric_kind(cycles, "an S-N curve's cycles"), check_numeric_kind(ranges, "an S-N curve's ranges")
            N, S = np.asarray(cycles, dtype=float), np.asarray(ranges, dtype=float)
        except (TypeError, ValueError):
            raise AKFInputError("an S-N curve's cycles and ranges must be numbers (two lists of equal length)") from None
        if N.ndim != 1 or N.shape != S.shape or N.size < 2:
            raise AKFInputError(f"an S-N curve needs at least two (N, range) points, got {N.size}")
        if not (np.all(np.isfinite(N)) and np.all(np.isfinite(S)) and np.all(N > 0) and np.all(S > 0)):
            raise AKFInputError("an S-N curve's cycles and ranges must be positive finite numbers")
        if np.any(np.diff(N) <= 0) or np.any(np.diff(S) >= 0):
            raise AKFInputError("the S-N curve is not monotonic: give its points with the cycles increasing and the "
                                f"stress ranges decreasing; got N = {N.tolist()}, ranges = {(S / MPA).tolist()} MPa")
        self.cycles, self.ranges, self.name = N, S, name
        self.slopes = np.log(N[1:] / N[:-1]) / np.log(S[:-1] / S[1:])

    @classmethod
    def ec3(cls, category: float, gamma_mf: float = 1.0) -> SNCurve:
        """The EN 1993-1-9 curve of a detail category.

        Slope 3 through ``Δσ_C`` at 2e6 cycles down to ``Δσ_D = 0.737 Δσ_C`` at 5e6, slope 5 down to
        the cut-off ``Δσ_L = 0.549 Δσ_D`` at 1e8, no damage below.

        Parameters
        ----------
        category : float
            ``Δσ_C`` (MPa), one of :data:`EC3_CATEGORIES`.
        gamma_mf : float
            The partial factor for fatigue strength: the curve's ranges divided by it.

        Returns
        -------
        SNCurve
        """
        if isinstance(category, bool) or not np.isscalar(category) or float(category) not in EC3_CATEGORIES:
            raise AKFInputError(f"unknown detail category {category!r}: EN 1993-1-9 has {list(EC3_CATEGORIES)} (MPa)")
        if not (np.isfinite(gamma_mf) and gamma_mf >= 1.0):
            raise AKFInputError(f"gamma_mf is a partial factor >= 1, got {gamma_mf!r}")
        C = float(category) * MPA / gamma_mf
        D = C * (2.0 / 5.0) ** (1.0 / 3.0)
        L = D * (5e6 / 1e8) ** (1.0 / 5.0)
        return cls([2e6, 5e6, 1e8], [C, D, L], f"EN 1993-1-9 detail category {category:g}"
                   + (f", gamma_Mf {gamma_mf:g}" if gamma_mf != 1.0 else ""))

    @classmethod
    def from_points(cls, points: ArrayLike, gamma_mf: float = 1.0) -> SNCurve:
        """A curve of one's own through ``(N, Δσ in MPa)`` points.

        Parameters
        ----------
        points : array_like (p, 2)
            Cycles and stress ranges (MPa).
        gamma_mf : float
            The partial factor: the ranges divided by it.

        Returns
        -------
        SNCurve
        """
        P = np.asarray(points, dtype=float)
        if P.ndim != 2 or P.shape[1] != 2:
            raise AKFInputError(f"S-N points are (N, range in MPa) pairs, got an array of shape {P.shape}")
        if not (np.isfinite(gamma_mf) and gamma_mf >= 1.0):
            raise AKFInputError(f"gamma_mf is a partial factor >= 1, got {gamma_mf!r}")
        return cls(P[:, 0], P[:, 1] * MPA / gamma_mf, "S-N points of one's own")

    @property
    def cutoff(self) -> float:
        """The stress range (Pa) below which a cycle does no damage."""
        return float(self.ranges[-1])

    def cycles_to_failure(self, ranges: ArrayLike) -> FloatArray:
        """``N`` of each stress range.

        Parameters
        ----------
        ranges : array_like
            Stress ranges (Pa), any shape.

        Returns
        -------
        ndarray
            Cycles to failure, the shape of ``ranges``; ``inf`` below the cut-off.
        """
        S = np.asarray(ranges, dtype=float)
        seg = np.clip(np.searchsorted(-self.ranges, -S, side="right") - 1, 0, self.slopes.size - 1)
        with np.errstate(divide="ignore", over="ignore"):
            N = self.cycles[seg] * (self.ranges[seg] / S) ** self.slopes[seg]
        return np.where(S < self.cutoff, np.inf, N)

    def damage_per_cycle(self, ranges: ArrayLike) -> FloatArray:
        """Miner's damage of one cycle of each range, ``1 / N``.

        Parameters
        ----------
        ranges : array_like
            Stress ranges (Pa).

        Returns
        -------
        ndarray
            The shape of ``ranges``; 0 below the cut-off.
        """
        return 1.0 / self.cycles_to_failure(ranges)

    def __repr__(self):
        return f"SNCurve({self.name or 'points'}: slopes {self.slopes.tolist()}, cut-off {self.cutoff / MPA:.4g} MPa)"


@dataclass
class Cycles:
    """Rainflow cycles of one or many outputs.

    Attributes
    ----------
    ranges : ndarray (c,)
        Stress (or strain) ranges, in the series' unit.
    counts : ndarray (c,)
        1 for a full cycle, 0.5 for a half cycle.
    output : ndarray (c,) of int
        The output (column) each cycle belongs to.
    n_outputs : int
        Columns of the series counted.
    """

    ranges: FloatArray
    counts: FloatArray
    output: np.ndarray
    n_outputs: int

    def total(self) -> FloatArray:
        """Cycles per output.

        Returns
        -------
        ndarray (n_outputs,)
            Full cycles plus half the half cycles.
        """
        return np.bincount(self.output, weights=self.counts, minlength=self.n_outputs)

    def max_range(self) -> FloatArray:
        """The largest range per output.

        Returns
        -------
        ndarray (n_outputs,)
            In the unit of the ranges; 0 for an output without cycles.
        """
        out = np.zeros(self.n_outputs)
        np.maximum.at(out, self.output, self.ranges)
        return out


def _as_columns(series):
    check_numeric_kind(series, "the series")
    try:
        X = np.asarray(series, dtype=float)
    except (TypeError, ValueError):
        raise AKFInputError(f"a series is an array of numbers (N,) or (N, outputs), got {type(series).__name__}") from None
    if X.ndim == 1:
        X = X[:, None]
    if X.ndim != 2:
        raise AKFInputError(f"a series is (N,) or (N, outputs), got an array of shape {X.shape}")
    if not np.all(np.isfinite(X)):
        raise AKFInputError("the series holds NaN or infinite values")
    return X


def _reversals(X):
    """The reversals of every column of ``X`` (N, k): flat values and their column, in time order
    per column; the first and the last point of each column are kept, a plateau counts once."""
    N, k = X.shape
    if N <= 2:
        keep = np.ones((N, k), bool)
    else:
        s = np.sign(np.diff(X, axis=0))                        # (N-1, k)
        keep = np.empty((N, k), bool)
        keep[0] = keep[-1] = True
        if np.all(s):                                          # no plateau: a turn is a change of slope
            np.not_equal(s[1:], s[:-1], out=keep[1:-1])
        else:
            # point i (1..N-2) turns where the slope into it (the last non-zero one) and out of it differ
            idx = np.where(s != 0, np.arange(N - 1)[:, None], 0)
            np.maximum.accumulate(idx, axis=0, out=idx)
            filled = np.take_along_axis(s, idx, axis=0)
            keep[1:-1] = (s[1:] != 0) & (filled[:-1] != 0) & (s[1:] != filled[:-1])
    col, row = np.nonzero(keep.T)
    return X[row, col], col


def _flat_reversals(values, seg):
    """The reversals of flat sequences (each output's points in order, ``seg`` sorted): repeated
    values merged, the points where the slope keeps its sign dropped, each output's first and last
    point kept."""
    same = seg[1:] == seg[:-1]
    keep = np.ones(values.size, bool)
    keep[1:] = ~(same & (values[1:] == values[:-1]))          # a plateau counts once
    values, seg = values[keep], seg[keep]
    if values.size < 3:
        return values, seg
    d = np.sign(np.diff(values))
    same = seg[1:] == seg[:-1]
    inner = same[:-1] & same[1:]                              # point i with both neighbours in its output
    keep = np.ones(values.size, bool)
    keep[1:-1] = ~inner | (d[:-1] != d[1:])
    return values[keep], seg[keep]


def _take_cycles(values, seg):
    """Take out every full cycle of the flat reversal sequences (ASTM E1049-85: a range no larger
    than its neighbours), pass after pass.  Returns the residue ``(values, seg)`` and the full
    cycles' ``(ranges, seg)``."""
    ranges, owners = [], []
    while values.size >= 4:
        r = np.abs(np.diff(values))
        same = seg[1:] == seg[:-1]
        # pair (i, i+1) with neighbours i-1 and i+2 in the same output: r[i] < r[i-1] and r[i] <= r[i+1]
        inner = same[1:-1] & same[:-2] & same[2:]
        ready = inner & (r[1:-1] < r[:-2]) & (r[1:-1] <= r[2:])
        if not ready.any():
            break
        i = np.flatnonzero(ready) + 1
        ranges.append(r[i])
        owners.append(seg[i])
        drop = np.zeros(values.size, bool)
        drop[i] = drop[i + 1] = True
        values, seg = values[~drop], seg[~drop]
    if ranges:
        return values, seg, np.concatenate(ranges), np.concatenate(owners)
    return values, seg, np.empty(0), np.empty(0, int)


def _half_cycles(values, seg):
    """The half cycles of a residue: the ranges between its successive points."""
    same = seg[1:] == seg[:-1]
    return np.abs(np.diff(values))[same], seg[1:][same]


def rainflow(series: ArrayLike) -> Cycles:
    """Rainflow cycles (ASTM E1049-85) of one series or of many at once.

    Parameters
    ----------
    series : array_like (N,) or (N, k)
        The history (one column per output), any unit.

    Returns
    -------
    Cycles
        Full cycles (count 1) and the residue's half cycles (count 0.5), per output.

    Examples
    --------
    The example of ASTM E1049-85 (its Fig. 6): one full cycle of 4 and six half cycles.

    >>> c = rainflow([-2, 1, -3, 5, -1, 3, -4, 4, -2])
    >>> sorted(zip(c.ranges.tolist(), c.counts.tolist()))
    [(3.0, 0.5), (4.0, 0.5), (4.0, 1.0), (6.0, 0.5), (8.0, 0.5), (8.0, 0.5), (9.0, 0.5)]
    """
    X = _as_columns(series)
    values, seg = _reversals(X)
    values, seg, full, owner = _take_cycles(values, seg)
    half, half_owner = _half_cycles(values, seg)
    return Cycles(np.concatenate([full, half]), np.concatenate([np.ones(full.size), np.full(half.size, 0.5)]),
                  np.concatenate([owner, half_owner]).astype(int), X.shape[1])


def damage(cycles: Cycles, curve: SNCurve) -> FloatArray:
    """Miner's damage sum per output, ``sum n_i / N(Δσ_i)``.

    Parameters
    ----------
    cycles : Cycles
        Stress cycles (Pa).
    curve : SNCurve

    Returns
    -------
    ndarray (n_outputs,)
        Dimensionless (1: the detail's life is used up).

    Examples
    --------
    >>> c = rainflow([0.0, 71e6, 0.0, 71e6, 0.0])           # two cycles of 71 MPa (full and halves)
    >>> float(damage(c, SNCurve.ec3(71))[0] * 2e6)
    2.0
    """
    _check_cycles(cycles)
    if not isinstance(curve, SNCurve):
        raise AKFInputError(f"curve must be an SNCurve (SNCurve.ec3(71), say), got {type(curve).__name__}")
    return np.bincount(cycles.output, weights=cycles.counts * curve.damage_per_cycle(cycles.ranges),
                       minlength=cycles.n_outputs)


def equivalent_range(cycles: Cycles, m: float, n_eq: float) -> FloatArray:
    """The damage-equivalent range ``(sum n_i Δσ_i^m / N_eq)^(1/m)`` per output.

    Parameters
    ----------
    cycles : Cycles
    m : float
        The S-N slope of the equivalence (3 for steel details, 4-5 for others).
    n_eq : float
        The equivalent number of cycles (2e6, or the record's length in cycles at 1 Hz).

    Returns
    -------
    ndarray (n_outputs,)
        In the unit of the cycles' ranges.

    Examples
    --------
    >>> c = rainflow([0.0, 2.0, 0.0, 2.0, 0.0])
    >>> float(equivalent_range(c, 3.0, 2.0)[0])
    2.0
    """
    _check_cycles(cycles)
    _check_equivalence(m, n_eq)
    sums = np.bincount(cycles.output, weights=cycles.counts * cycles.ranges ** m, minlength=cycles.n_outputs)
    return (sums / n_eq) ** (1.0 / m)


def _check_cycles(cycles):
    if not isinstance(cycles, Cycles):
        raise AKFInputError(f"cycles must be the Cycles that rainflow() counts, got {type(cycles).__name__} (were the "
                            "arguments swapped?)")


def _check_equivalence(m, n_eq):
    if not (is_real(m) and is_real(n_eq)) or not (np.isfinite(m) and m > 0) or not (np.isfinite(n_eq) and n_eq > 0):
        raise AKFInputError(f"the equivalent range needs a slope m > 0 and N_eq > 0, got m = {m!r}, N_eq = {n_eq!r}")


@dataclass
class FatigueSummary:
    """Fatigue of every output over the record so far (:meth:`FatigueAccumulator.summary`).

    Attributes
    ----------
    cycles : ndarray (k,)
        Cycles counted (half cycles 0.5).
    max_range : ndarray (k,)
        The largest range (Pa).
    damage : ndarray (k,)
        Miner's sum.
    equivalent_range : ndarray (k,)
        The damage-equivalent range (Pa) of the accumulator's ``m`` and ``n_eq``.
    """

    cycles: FloatArray
    max_range: FloatArray
    damage: FloatArray
    equivalent_range: FloatArray


class FatigueAccumulator:
    """Rainflow counting and damage of a record that arrives in chunks, in constant memory.

    Each :meth:`update` takes the next rows of the stress histories; the full cycles are counted
    as they close and only the residue (the reversals not yet closed, a few dozen per output) is
    held.  :meth:`summary` adds the residue's half cycles without consuming it, so the record can
    go on.  The counts equal those of the record in one piece exactly, whatever the chunks.

    Parameters
    ----------
    n_outputs : int
        Columns of the stress histories.
    curve : SNCurve
        For the damage.
    m : float
        Slope of the damage-equivalent range.
    n_eq : float
        Its equivalent number of cycles.

    Examples
    --------
    >>> import numpy as np
    >>> y = np.cumsum(np.random.default_rng(0).normal(size=(1000, 2)), axis=0) * 1e6
    >>> acc = FatigueAccumulator(2, SNCurve.ec3(71), m=3.0, n_eq=2e6)
    >>> for part in np.array_split(y, 7):
    ...     acc.update(part)
    >>> whole = rainflow(y)
    >>> bool(np.array_equal(acc.summary().cycles, whole.total()))
    True
    """

    def __init__(self, n_outputs: int, curve: SNCurve, m: float = 3.0, n_eq: float = 2e6):
        _check_equivalence(m, n_eq)
        if not isinstance(curve, SNCurve):
            raise AKFInputError(f"curve must be an SNCurve (SNCurve.ec3(71), say), got {type(curve).__name__}")
        self.k, self.curve, self.m, self.n_eq = as_count(n_outputs, "n_outputs", minimum=1), curve, float(m), float(n_eq)
        check_memory(self.k, 16, f"fatigue of {self.k:.6g} outputs", "give fewer outputs", items="outputs")
        self.full_cycles = np.zeros(self.k)
        self.full_max = np.zeros(self.k)
        self.full_damage = np.zeros(self.k)
        self.full_sum_m = np.zeros(self.k)                 # sum of range^m of the full cycles
        self.residue = np.empty(0)
        self.residue_output = np.empty(0, int)

    def update(self, stresses: ArrayLike) -> None:
        """Count the next rows.

        Parameters
        ----------
        stresses : array_like (K, k)
            Stress histories (Pa), one column per output.
        """
        X = _as_columns(stresses)
        if X.shape[1] != self.k:
            raise AKFInputError(f"the accumulator counts {self.k} outputs; the chunk has {X.shape[1]} columns")
        if X.shape[0] == 0:
            return
        head_v, head_s, tail = self._split_residue()
        values, seg = _reversals(X if tail is None else np.vstack([tail, X]))
        if head_v.size:              # the closed part of the residue goes first, in each output
            values, seg = np.concatenate([head_v, values]), np.concatenate([head_s, seg])
            order = np.argsort(seg, kind="stable")
            values, seg = values[order], seg[order]
        self.residue, self.residue_output, full, owner = _take_cycles(values, seg)
        self._count(full, owner)

    def _count(self, full, owner):
        """Add full cycles (ranges, outputs) to the sums."""
        if full.size:
            self.full_cycles += np.bincount(owner, minlength=self.k)
            np.maximum.at(self.full_max, owner, full)
            self.full_damage += np.bincount(owner, weights=self.curve.damage_per_cycle(full), minlength=self.k)
            self.full_sum_m += np.bincount(owner, weights=full ** self.m, minlength=self.k)

    def _split_residue(self):
        """The residue but its last two points per output, and those two (or the one point doubled)
        as rows to put before the next chunk: the last point may not be a reversal once more
        follows."""
        if self.residue.size == 0:
            return np.empty(0), np.empty(0, int), None
        counts = np.bincount(self.residue_output, minlength=self.k)
        ends = np.cumsum(counts)
        last = self.residue[ends - 1]
        before = np.where(counts >= 2, self.residue[np.maximum(ends - 2, 0)], last)
        position = np.arange(self.residue.size) - np.repeat(ends - counts, counts)
        head = position < np.repeat(counts - 2, counts)
        return self.residue[head], self.residue_output[head], np.vstack([before, last])

    def merge(self, later: FatigueAccumulator) -> FatigueAccumulator:
        """Join the counts of the piece of record that follows this one (counted on its own, from its
        first sample): the cycles of the two pieces in one, exactly as if counted together.

        The cycles each piece closed on its own are cycles of the whole (the criterion only grows
        stricter nowhere when a piece's first sample turns out to be no reversal); the residues are
        joined and counted again.

        Parameters
        ----------
        later : FatigueAccumulator
            The counts of the next piece (same outputs, curve, slope and N_eq).

        Returns
        -------
        FatigueAccumulator
            ``self``, now holding both.
        """
        if later.k != self.k or later.m != self.m or later.n_eq != self.n_eq or \
                not np.array_equal(later.curve.ranges, self.curve.ranges) or \
                not np.array_equal(later.curve.cycles, self.curve.cycles):
            raise AKFInputError("only counts of the same outputs, S-N curve, slope and N_eq merge")
        self.full_cycles = self.full_cycles + later.full_cycles
        self.full_max = np.maximum(self.full_max, later.full_max)
        self.full_damage = self.full_damage + later.full_damage
        self.full_sum_m = self.full_sum_m + later.full_sum_m
        values = np.concatenate([self.residue, later.residue])
        seg = np.concatenate([self.residue_output, later.residue_output])
        order = np.argsort(seg, kind="stable")
        values, seg = _flat_reversals(values[order], seg[order])
        self.residue, self.residue_output, full, owner = _take_cycles(values, seg)
        self._count(full, owner)
        return self

    def summary(self) -> FatigueSummary:
        """The fatigue of the record so far: the full cycles and the residue's half cycles.

        Returns
        -------
        FatigueSummary
        """
        half, owner = _half_cycles(self.residue, self.residue_output)
        cycles = self.full_cycles + 0.5 * np.bincount(owner, minlength=self.k)
        biggest = self.full_max.copy()
        np.maximum.at(biggest, owner, half)
        dmg = self.full_damage + 0.5 * np.bincount(owner, weights=self.curve.damage_per_cycle(half), minlength=self.k)
        sum_m = self.full_sum_m + 0.5 * np.bincount(owner, weights=half ** self.m, minlength=self.k)
        return FatigueSummary(cycles, biggest, dmg, (sum_m / self.n_eq) ** (1.0 / self.m))

    def state(self) -> dict[str, np.ndarray]:
        """What is carried to the next chunk (to save with a checkpoint).

        Returns
        -------
        dict of str to ndarray
        """
        return {"fatigue_full": np.vstack([self.full_cycles, self.full_max, self.full_damage, self.full_sum_m]),
                "fatigue_residue": self.residue.copy(), "fatigue_residue_output": self.residue_output.copy()}

    def restore(self, state: dict) -> FatigueAccumulator:
        """Continue from a :meth:`state`.

        Parameters
        ----------
        state : mapping of str to ndarray

        Returns
        -------
        FatigueAccumulator
            ``self``.
        """
        full = np.asarray(state["fatigue_full"], float)
        if full.shape != (4, self.k):
            raise AKFInputError(f"the saved fatigue state is for {full.shape[-1]} outputs, not {self.k}")
        self.full_cycles, self.full_max, self.full_damage, self.full_sum_m = (row.copy() for row in full)
        self.residue = np.asarray(state["fatigue_residue"], float)
        self.residue_output = np.asarray(state["fatigue_residue_output"], int)
        return self


#: Young's moduli (Pa) of structural materials: polymers and timber (~1-10 GPa) to steels (~210 GPa)
YOUNGS_MODULUS_RANGE = (1e9, 1e12)


def check_youngs_modulus(E, key="[output.fatigue] youngs_modulus"):
    """Refuse a Young's modulus typed in another unit; warn about one outside structural materials.

    Below 1 MPa or above 10 TPa it is an error (``210`` or ``210000`` meant as GPa or MPa would give
    stresses 1e9 or 1e6 times too small); outside :data:`YOUNGS_MODULUS_RANGE`, a warning.

    Parameters
    ----------
    E : float or ndarray
        Pa.
    key : str
        Where it was given, for the message.

    Raises
    ------
    AKFInputError
        For a value no material has.

    Examples
    --------
    >>> check_youngs_modulus(210e9)
    """
    E = np.atleast_1d(np.asarray(E, float))
    low, high = float(E.min()), float(E.max())
    if low < 1e6 or high > 1e13:
        bad = low if low < 1e6 else high
        raise AKFInputError(f"{key} = {bad:.4g} Pa is no structural material's (steel 210e9, aluminium 70e9, "
                            "concrete 30e9 Pa): give it in Pa, e.g. 210e9 for 210 GPa")
    if low < YOUNGS_MODULUS_RANGE[0] or high > YOUNGS_MODULUS_RANGE[1]:
        bad = low if low < YOUNGS_MODULUS_RANGE[0] else high
        warnings.warn(f"{key} = {bad:.4g} Pa is outside the structural materials' 1e9-1e12 Pa: is it in Pa?",
                      UserWarning)


def relative_stress_operator(structure, outputs: list, youngs_modulus: float | None = None) -> FloatArray:
    """:func:`stress_operator` for measures relative to the truth (the relative error of a DEL):
    ``youngs_modulus``, else the model's E, else 1 Pa -- a uniform E scales every stress of the
    estimate and of the truth alike, so a model of one's own without E needs none.

    Parameters
    ----------
    structure : Structure
        The model.
    outputs : list of int
        Strain output indices (0-based).
    youngs_modulus : float, optional
        E (Pa), instead of the model's.

    Returns
    -------
    ndarray (k, n_strain)

    Examples
    --------
    >>> from core_akf.models import s17_truss
    >>> float(relative_stress_operator(s17_truss(), [12])[0, 12]) / 1e9
    200.0
    """
    if youngs_modulus is None and structure.meta.get("E") is None:
        youngs_modulus = 1.0
    return stress_operator(structure, outputs, youngs_modulus)


def stress_operator(structure, outputs: list, youngs_modulus: float | None = None) -> FloatArray:
    """The stresses of strain outputs as rows on all of them: ``σ = W ε``.

    A bar's or an extensometer's strain gives ``σ = E ε``.  A plate's surface strains at a node
    give the plane-stress components when the model knows its Poisson's ratio and has all three
    components there: ``σ_x = E / (1 - ν²) (ε_x + ν ε_y)``, ``σ_y`` alike, ``τ_xy = E / (2 (1 + ν))
    γ_xy``; otherwise ``E ε`` as well.

    Parameters
    ----------
    structure : Structure
        The model, with ``meta["E"]`` (and ``meta["nu"]``) unless ``youngs_modulus`` is given.
    outputs : list of int
        Strain output indices (0-based rows of ``structure.strain_operator``).
    youngs_modulus : float, optional
        E (Pa), instead of the model's.

    Returns
    -------
    ndarray (k, n_strain)
        Pa per unit strain.

    Raises
    ------
    AKFInputError
        For a model without strain outputs, or without a Young's modulus when none is given.

    Examples
    --------
    >>> from core_akf.models import s17_truss
    >>> W = stress_operator(s17_truss(), [12])
    >>> W.shape, float(W[0, 12]) / 1e9
    ((1, 34), 200.0)
    """
    n = structure.n_strain
    if not n:
        raise AKFInputError("the model has no strain outputs: fatigue is counted on the stresses of strain outputs "
                            "(truss members, plate surface strains, extensometers)")
    idx = [int(i) for i in outputs]
    if not idx or any(not 0 <= i < n for i in idx):
        raise AKFInputError(f"strain outputs must be between 0 and {n - 1}, got {outputs!r}")
    E = structure.meta.get("E") if youngs_modulus is None else youngs_modulus
    if E is None:
        raise AKFInputError("no Young's modulus for the strain outputs of this model (a model of one's own carries "
                            "none): give it, e.g. [output.fatigue] youngs_modulus = 210e9 (Pa)")
    E = np.broadcast_to(np.asarray(E, float), (n,)) if np.ndim(E) <= 1 and np.size(E) in (1, n) else None
    if E is None or not np.all(np.isfinite(E)) or np.any(E <= 0):
        raise AKFInputError("the Young's modulus must be one positive number (Pa), or one per strain output")
    W = np.zeros((len(idx), n))
    nu = structure.meta.get("nu")
    labels = structure.strain_labels
    for row, i in enumerate(idx):
        parts = labels[i].split(":")
        if structure.strain_kind == "node" and nu is not None and len(parts) == 3 and parts[2] in STRAIN_COMPONENTS:
            node, comp = int(parts[1]), parts[2]
            try:
                ex, ey = structure.strain_index((node, "ex")), structure.strain_index((node, "ey"))
            except AKFInputError:
                ex = ey = None
            if comp == "gxy":
                W[row, i] = E[i] / (2.0 * (1.0 + nu))
                continue
            if ex is not None and ey is not None:
                own, other = (ex, ey) if comp == "ex" else (ey, ex)
                W[row, own] = E[i] / (1.0 - nu ** 2)
                W[row, other] = E[i] * nu / (1.0 - nu ** 2)
                continue
        W[row, i] = E[i]
    return W
