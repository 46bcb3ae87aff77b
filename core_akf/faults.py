"""Sensor faults found in a record as it is filtered: stuck (flat-lined) spans, clipping at a rail,
isolated spikes and drift or offset jumps.

- **stuck**: ``stuck_steps`` or more identical raw samples in a row;
- **clipped**: the samples at a value that is the channel's largest (or smallest) so far and
  occurs ``clip_count`` times or more -- a rail;
- **spike**: at most ``spike_width`` samples in a row that stand out of the median of their
  ``2 (spike_width + 1)`` neighbours by more than ``spike_sigma`` robust standard deviations of that residual (the
  median absolute deviation over the chunk, times 1.4826);
- **drift**: a two-sided CUSUM on the normalised innovations, ``g_k = max(0, g_k-1 + nu_k - kappa)``,
  above ``cusum_threshold``; the span runs from the last step ``g`` was zero.

The raw tests (stuck, clipped, spike) see a chunk before the filter; the innovation test (drift)
after it, on the innovations normalised by their robust scale, so that ``faults = "drop"`` filters a chunk a second time with its faulty samples
missing.  A drift of a channel that no other channel checks (a gauge without static redundancy)
leaves no trace in the innovations: the filter moves the forces to fit it.
"""
from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass

import numpy as np

from .quality import runs

#: what ``[measurements] faults`` may be
FAULT_MODES = ("flag", "drop", "off")


@dataclass(frozen=True)
class FaultSettings:
    """The thresholds of the fault tests (see the module docstring).

    Attributes
    ----------
    stuck_steps : int
        Identical samples in a row that make a stuck span.
    clip_count : int
        Samples at one extreme value that make it a rail.
    spike_sigma : float
        Normalised innovation above which a sample is an outlier.
    spike_width : int
        The most outliers in a row that count as a spike.
    cusum_drift : float
        ``kappa``: the CUSUM's allowance, in robust standard deviations per step.
    cusum_threshold : float
        ``h``: the CUSUM's alarm level.
    """

    stuck_steps: int = 25
    clip_count: int = 3
    spike_sigma: float = 15.0
    spike_width: int = 2
    cusum_drift: float = 1.0
    cusum_threshold: float = 60.0


@dataclass(frozen=True)
class Fault:
    """One fault: a channel, a kind and a span of steps ``[first, stop)``, with its evidence."""

    channel: str
    kind: str
    first: int
    stop: int
    evidence: str

    def row(self, dt, t0=0.0):
        """The fault as a table row (times in s)."""
        return {"channel": self.channel, "kind": self.kind, "start_s": t0 + self.first * dt,
                "end_s": t0 + self.stop * dt, "samples": self.stop - self.first, "evidence": self.evidence}


class FaultDetector:
    """The fault tests over a record fed chunk by chunk, in order.

    Parameters
    ----------
    labels : list of str
        The channels.
    settings : FaultSettings, optional

    Examples
    --------
    >>> import numpy as np
    >>> y = np.random.default_rng(0).normal(size=(200, 1))
    >>> y[50:90, 0] = 0.3                                      # stuck for 40 steps
    >>> d = FaultDetector(["acc:4:y"])
    >>> int(d.raw(y, 0).sum()), d.faults()[0].kind
    (40, 'stuck')
    """

    def __init__(self, labels, settings=None):
        self.labels = list(labels)
        self.settings = settings or FaultSettings()
        m = len(self.labels)
        self.last = np.full(m, np.nan)            # the last raw sample, and how long it has repeated
        self.repeat = np.zeros(m, int)
        self.high, self.low = np.full(m, -np.inf), np.full(m, np.inf)
        self.rails = [set() for _ in range(m)]
        self.at_extreme = ([[] for _ in range(m)], [[] for _ in range(m)])   # steps at the largest, smallest value
        self.g = np.zeros((2, m))                # the CUSUM, up and down
        self.g_zero = np.zeros((2, m), int)      # the last step it was zero
        self.found = []

    # ----------------------------------------------------------------------- before the filter
    def raw(self, Y, step):
        """Stuck, clipped and spiking samples of a chunk (k, m) starting at record step ``step``.

        Returns
        -------
        ndarray (k, m) of bool
        """
        Y = np.asarray(Y, float)
        bad = np.zeros(Y.shape, bool)
        for j in range(Y.shape[1]):
            bad[:, j] = self._stuck(j, Y[:, j], step) | self._clipped(j, Y[:, j], step)
        return bad | self.spikes(np.where(bad, np.nan, Y), step)

    def _stuck(self, j, y, step):
        s = self.settings.stuck_steps
        same = np.r_[y[:1] == self.last[j], y[1:] == y[:-1]]      # equal to the sample before
        out = np.zeros(y.size, bool)
        for a, b in runs(same):
            before = self.repeat[j] if a == 0 else 0             # the run carried over from the chunk before
            length = b - a + 1 + before                          # the first sample of the run too
            if length >= s:
                first = max(a - 1, 0)
                out[first:b] = True
                self._add(j, "stuck", step + a - 1 - before, step + b,
                          f"{length} identical samples ({y[b - 1]:.6g})")
        tail = runs(same)
        self.repeat[j] = (tail[-1, 1] - tail[-1, 0] + 1 + (self.repeat[j] if tail[-1, 0] == 0 else 0)) \
            if len(tail) and tail[-1, 1] == y.size else 0
        if y.size:
            self.last[j] = y[-1]
        return out

    def _clipped(self, j, y, step):
        seen = y[~np.isnan(y)]
        if not seen.size:
            return np.zeros(y.size, bool)
        for side, value in ((0, seen.max()), (1, seen.min())):
            old = self.high[j] if side == 0 else self.low[j]
            if value == old:                                     # the extreme so far, met again
                self.at_extreme[side][j] += np.flatnonzero(y == value).tolist()
            elif (value > old) if side == 0 else (value < old):  # a new extreme
                self.at_extreme[side][j] = (step + np.flatnonzero(y == value)).tolist()
                if side == 0:
                    self.high[j] = value
                else:
                    self.low[j] = value
            else:
                continue
            at = self.at_extreme[side][j]
            if len(at) >= self.settings.clip_count and float(value) not in self.rails[j]:
                self.rails[j].add(float(value))
                for k in at:                                     # the samples at the rail before it was known
                    if k < step:
                        self._add(j, "clipped", k, k + 1, f"at the rail {value:.6g}")
        out = np.isin(y, list(self.rails[j])) if self.rails[j] else np.zeros(y.size, bool)
        for a, b in runs(out):
            self._add(j, "clipped", step + a, step + b, f"at the rail {y[a]:.6g}")
        return out

    def spikes(self, Y, step):
        """Isolated outliers of a chunk (k, m): samples that stand out of their neighbours'
        median by ``spike_sigma`` robust standard deviations of that residual, at most
        ``spike_width`` in a row.

        Returns
        -------
        ndarray (k, m) of bool
        """
        Y = np.asarray(Y, float)
        st = self.settings
        bad = np.zeros(Y.shape, bool)
        half = st.spike_width + 1
        if Y.shape[0] < 2 * half + 4:
            return bad
        windows = np.lib.stride_tricks.sliding_window_view(np.pad(Y, ((half, half), (0, 0)), mode="edge"), 2 * half + 1,
                                                           axis=0)
        neighbours = np.delete(windows, half, axis=-1)                 # the sample itself left out
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)            # an all-missing window
            residual = Y - np.nanmedian(neighbours, axis=-1)
        for j in range(Y.shape[1]):
            d = residual[:, j]
            seen = ~np.isnan(d)
            if seen.sum() < 10:
                continue
            scale = 1.4826 * np.median(np.abs(d[seen] - np.median(d[seen])))
            if not scale > 0:
                continue
            z = np.where(seen, d / scale, 0.0)
            out = np.abs(z) > st.spike_sigma
            for a, b in runs(out):
                if b - a > st.spike_width:
                    out[a:b] = False
                else:
                    self._add(j, "spike", step + a, step + b, f"{z[a:b][np.argmax(np.abs(z[a:b]))]:+.3g} robust "
                                                              "standard deviations off its neighbours")
            bad[:, j] = out
        return bad

    # ------------------------------------------------------------------------ after the filter
    def innovations(self, E, step, skip=None):
        """Drift in a chunk's innovations (k, m) (NaN where missing): the CUSUM test.

        Parameters
        ----------
        E : ndarray (k, m)
        step : int
            The record step of the chunk's first row.
        skip : ndarray (k, m) of bool, optional
            Samples already found faulty (left out of the test).

        Returns
        -------
        ndarray (k, m) of bool
        """
        E = np.asarray(E, float)
        bad = np.zeros(E.shape, bool)
        for j in range(E.shape[1]):
            e = E[:, j]
            seen = ~np.isnan(e) & (True if skip is None else ~skip[:, j])
            if seen.sum() < 10:
                continue
            centre = np.median(e[seen])
            scale = 1.4826 * np.median(np.abs(e[seen] - centre))
            if scale > 0:
                bad[:, j] = self._drift(j, np.where(seen, (e - centre) / scale, 0.0), step)
        return bad

    def _drift(self, j, nu, step):
        st = self.settings
        out = np.zeros(nu.size, bool)
        for side, sign in enumerate((1.0, -1.0)):
            g, zero = self.g[side, j], self.g_zero[side, j]
            alarm = None
            for k, v in enumerate(sign * nu):
                g = max(0.0, g + v - st.cusum_drift)
                if g == 0.0:
                    if alarm is not None:
                        self._add(j, "drift", alarm, step + k, f"CUSUM {'up' if sign > 0 else 'down'} above "
                                                               f"{st.cusum_threshold:g}")
                        alarm = None
                    zero = step + k + 1
                elif g > st.cusum_threshold and alarm is None:
                    alarm = zero
                if alarm is not None:
                    out[max(alarm - step, 0):k + 1] = True
            if alarm is not None:
                self._add(j, "drift", alarm, step + nu.size, f"CUSUM {'up' if sign > 0 else 'down'} above "
                                                             f"{st.cusum_threshold:g}")
            self.g[side, j], self.g_zero[side, j] = g, zero
        return out

    # ----------------------------------------------------------------------------- the findings
    def _add(self, j, kind, first, stop, evidence):
        for i, f in enumerate(self.found):         # a span that continues one found before
            if f.channel == self.labels[j] and f.kind == kind and first <= f.stop and stop >= f.first:
                self.found[i] = Fault(f.channel, kind, min(f.first, first), max(f.stop, stop), evidence)
                return
        self.found.append(Fault(self.labels[j], kind, int(first), int(stop), evidence))

    def faults(self):
        """Every fault found so far, in order of its first step.

        Returns
        -------
        list of Fault
        """
        return sorted(self.found, key=lambda f: (f.first, f.channel, f.kind))

    def state(self):
        """What a checkpoint keeps (:meth:`restore` takes it back)."""
        return {"fault_last": self.last.copy(), "fault_repeat": self.repeat.copy(), "fault_high": self.high.copy(),
                "fault_low": self.low.copy(), "fault_g": self.g.copy(), "fault_g_zero": self.g_zero.copy(),
                "fault_rails": np.array([[j, v] for j, r in enumerate(self.rails) for v in sorted(r)], float).reshape(-1, 2),
                "fault_found": np.array([repr(asdict(f)) for f in self.found], str)}

    def restore(self, state):
        """Continue from a :meth:`state` (a checkpoint without one: from scratch)."""
        import ast

        if "fault_last" not in state:
            return self
        self.last, self.repeat = np.array(state["fault_last"], float), np.array(state["fault_repeat"], int)
        self.high, self.low = np.array(state["fault_high"], float), np.array(state["fault_low"], float)
        self.g, self.g_zero = np.array(state["fault_g"], float), np.array(state["fault_g_zero"], int)
        self.rails = [set() for _ in self.labels]
        for j, v in np.asarray(state["fault_rails"], float).reshape(-1, 2):
            self.rails[int(j)].add(float(v))
        self.found = [Fault(**ast.literal_eval(str(s))) for s in np.asarray(state["fault_found"]).reshape(-1)]
        return self
