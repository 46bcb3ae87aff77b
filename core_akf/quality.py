"""What a record's channels hold: missing samples, the spans they form, and the sets of live
channels over time.

A NaN sample is missing: the filter skips it (:func:`core_akf.filter.kernels.gapped_filter`).  This
module describes the holes -- per channel, the missing fraction, the number of missing spans and
the longest one -- and tracks the spans over which the same channels are dead
(:class:`LiveSets`), the unit the detectability over time is checked on.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def runs(flags):
    """The runs of True in a boolean sequence.

    Parameters
    ----------
    flags : array_like (N,) of bool

    Returns
    -------
    ndarray (k, 2) of int
        ``[first, stop)`` of every run, in order.

    Examples
    --------
    >>> runs([False, True, True, False, True]).tolist()
    [[1, 3], [4, 5]]
    """
    f = np.r_[False, np.asarray(flags, bool), False].astype(np.int8)
    edges = np.flatnonzero(np.diff(f))
    return edges.reshape(-1, 2)


def missing_statistics(Y, dt):
    """Per channel: the missing fraction, the number of missing spans and the longest one.

    Parameters
    ----------
    Y : ndarray (N, m)
        The record, NaN where a sample is missing.
    dt : float
        The filter's time step (s).

    Returns
    -------
    list of dict
        One per channel: ``missing_fraction``, ``missing_spans``, ``longest_missing_s`` (s).

    Examples
    --------
    >>> import numpy as np
    >>> y = np.array([[1.0], [np.nan], [np.nan], [2.0]])
    >>> missing_statistics(y, 0.5)
    [{'missing_fraction': 0.5, 'missing_spans': 1, 'longest_missing_s': 1.0}]
    """
    missing = np.isnan(np.asarray(Y, float))
    out = []
    for j in range(missing.shape[1]):
        spans = runs(missing[:, j])
        longest = int(np.max(spans[:, 1] - spans[:, 0])) if len(spans) else 0
        out.append({"missing_fraction": float(missing[:, j].mean()) if missing.shape[0] else 0.0,
                    "missing_spans": int(len(spans)), "longest_missing_s": longest * float(dt)})
    return out


class HoleCounter:
    """:func:`missing_statistics` of a record seen chunk by chunk (a hole may span chunks), in
    constant memory; pieces counted apart join with :meth:`merge`.

    Examples
    --------
    >>> import numpy as np
    >>> c = HoleCounter(1)
    >>> for part in ([[1.0], [np.nan]], [[np.nan], [2.0]]):
    ...     c.update(np.array(part))
    >>> c.statistics(0.5)
    [{'missing_fraction': 0.5, 'missing_spans': 1, 'longest_missing_s': 1.0}]

    Parameters
    ----------
    m : int
        Channels.
    """

    def __init__(self, m):
        self.steps = 0
        self.missing = np.zeros(m, int)
        self.spans = np.zeros(m, int)
        self.longest = np.zeros(m, int)
        self.lead = np.zeros(m, int)          # the hole the first steps are in (0: none)
        self.trail = np.zeros(m, int)         # the hole still open at the last step

    def update(self, Y):
        """Count one chunk of the record, in order.

        Parameters
        ----------
        Y : ndarray (k, m)
            NaN where missing.
        """
        gone = np.isnan(np.asarray(Y, float))
        self._join(_Counts.of(gone))

    def merge(self, later):
        """Join the counts of the piece that follows this one.

        Parameters
        ----------
        later : HoleCounter

        Returns
        -------
        HoleCounter
            ``self``.
        """
        self._join(later)
        return self

    def _join(self, later):
        if self.steps == 0:
            for k in ("steps", "missing", "spans", "longest", "lead", "trail"):
                setattr(self, k, np.copy(getattr(later, k)) if k != "steps" else later.steps)
            return
        bridged = (self.trail > 0) & (later.lead > 0)
        joined = self.trail + later.lead
        self.spans = self.spans + later.spans - bridged
        self.longest = np.maximum(np.maximum(self.longest, later.longest), np.where(bridged, joined, 0))
        self.lead = np.where(self.lead == self.steps, self.lead + later.lead, self.lead)
        self.trail = np.where(later.trail == later.steps, self.trail + later.steps, later.trail)
        self.missing = self.missing + later.missing
        self.steps += later.steps

    def statistics(self, dt):
        """As :func:`missing_statistics`, over the steps counted.

        Parameters
        ----------
        dt : float
            Time step (s).

        Returns
        -------
        list of dict
        """
        return [{"missing_fraction": float(self.missing[j] / self.steps) if self.steps else 0.0,
                 "missing_spans": int(self.spans[j]), "longest_missing_s": int(self.longest[j]) * float(dt)}
                for j in range(len(self.missing))]


@dataclass
class _Counts:
    steps: int
    missing: np.ndarray
    spans: np.ndarray
    longest: np.ndarray
    lead: np.ndarray
    trail: np.ndarray

    @classmethod
    def of(cls, gone):
        k, m = gone.shape
        spans, longest, lead, trail = (np.zeros(m, int) for _ in range(4))
        for j in range(m):
            r = runs(gone[:, j])
            if len(r):
                spans[j], longest[j] = len(r), int(np.max(r[:, 1] - r[:, 0]))
                lead[j] = r[0, 1] if r[0, 0] == 0 else 0
                trail[j] = k - r[-1, 0] if r[-1, 1] == k else 0
        return cls(k, gone.sum(axis=0), spans, longest, lead, trail)


#: a set of live channels is checked for detectability once it has lasted this long (s)
LIVE_SET_MIN_S = 0.1


class LiveSets:
    """The spans over which channels are dead (missing for at least ``min_steps`` steps in a row),
    tracked chunk by chunk; :meth:`undetectable` names the spans whose live set is not detectable.

    Parameters
    ----------
    labels : list of str
        The channels.
    min_steps : int
        The shortest hole that makes a channel dead.

    Examples
    --------
    >>> import numpy as np
    >>> live = LiveSets(["a", "b"], 3)
    >>> Y = np.ones((10, 2))
    >>> Y[2:7, 1] = np.nan
    >>> live.update(Y[:4], 0); live.update(Y[4:], 4)
    >>> live.spans(10)
    [(2, 7, ('b',))]
    """

    def __init__(self, labels, min_steps):
        self.labels, self.min_steps = list(labels), max(1, int(min_steps))
        self.open = np.full(len(self.labels), -1)        # the step a channel's current hole began (-1: none)
        self.holes = []                                    # (channel, first, stop)

    def update(self, Y, step):
        """Take the next chunk of the record.

        Parameters
        ----------
        Y : ndarray (k, m)
            NaN where missing.
        step : int
            The record step of its first row.
        """
        gone = np.isnan(np.asarray(Y, float))
        for j in range(gone.shape[1]):
            col = gone[:, j]
            if not col.size:
                continue
            if self.open[j] >= 0 and not col[0]:           # the hole from the chunks before ends here
                self._close(j, self.open[j], step)
                self.open[j] = -1
            for a, b in runs(col):
                first = self.open[j] if a == 0 and self.open[j] >= 0 else step + a
                if b < len(col):
                    self._close(j, first, step + b)
                    self.open[j] = -1
                else:
                    self.open[j] = first

    def state(self):
        """What a checkpoint keeps (:meth:`restore` takes it back).

        Returns
        -------
        dict of str to ndarray
        """
        return {"live_open": self.open.copy(), "live_holes": np.array(self.holes, int).reshape(-1, 3)}

    def restore(self, state):
        """Continue from a :meth:`state` (a checkpoint without one: no hole before it).

        Parameters
        ----------
        state : mapping of str to ndarray

        Returns
        -------
        LiveSets
            ``self``.
        """
        if "live_open" in state:
            self.open = np.array(state["live_open"], int)
            self.holes = [tuple(int(v) for v in row) for row in np.asarray(state["live_holes"]).reshape(-1, 3)]
        return self

    def _close(self, j, first, stop):
        if stop - first >= self.min_steps:
            self.holes.append((j, int(first), int(stop)))

    def spans(self, end):
        """The spans with the same dead channels.

        Parameters
        ----------
        end : int
            The record's last step + 1 (a hole still open ends there).

        Returns
        -------
        list of (int, int, tuple of str)
            ``(first, stop, dead labels)``.
        """
        holes = self.holes + [(j, int(a), int(end)) for j, a in enumerate(self.open) if a >= 0 and end - a >= self.min_steps]
        cuts = sorted({c for _, a, b in holes for c in (a, b)})
        out = []
        for a, b in zip(cuts[:-1], cuts[1:]):
            dead = tuple(self.labels[j] for j in sorted({j for j, x, y in holes if x <= a and b <= y}))
            if not dead:
                continue
            if out and out[-1][2] == dead and out[-1][1] == a:
                out[-1] = (out[-1][0], b, dead)
            else:
                out.append((a, b, dead))
        return out

    def undetectable(self, report_of, end, dt, t0=0.0):
        """Warnings for the spans whose live set is not detectable.

        Parameters
        ----------
        report_of : callable
            ``report_of(live labels) -> DetectabilityReport`` (:meth:`core_akf.filter.Filter.report_of`).
        end : int
            The record's last step + 1.
        dt, t0 : float
            Time step and time of step 0 (s).

        Returns
        -------
        list of str
        """
        out, reports = [], {}
        for a, b, dead in self.spans(end):
            live = [x for x in self.labels if x not in dead]
            if not live:
                out.append(f"t = {t0 + a * dt:.6g}-{t0 + b * dt:.6g} s: every channel missing: the filter predicts, the "
                           "forces carry their prior, and the bands show it")
                continue
            if dead not in reports:
                reports[dead] = report_of(live)
            report = reports[dead]
            if report.detectable:
                continue
            why = "; ".join(f["unseen"].split(": ", 1)[-1].split(";")[0] for f in report.failures) or "PBH test"
            out.append(f"t = {t0 + a * dt:.6g}-{t0 + b * dt:.6g} s: {', '.join(dead)} missing; the remaining set is not "
                       f"detectable ({why}): there the forces carry their prior, and the bands show it")
        return out
