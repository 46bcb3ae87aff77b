"""Sensor faults found in a record as it is filtered: stuck (flat-lined) spans, clipping at a rail,
isolated spikes and drift or offset jumps.

- **stuck**: ``stuck_steps`` or more identical raw samples in a row;
- **clipped**: the samples at a value among the chunk's largest (or smallest) 1 % that occurs
  ``clip_count`` times or more, in more than one run or in a run shorter than a stuck one -- a rail;
- **spike**: at most ``spike_width`` samples in a row that stand out of the median of their
  ``2 (spike_width + 1)`` neighbours by more than ``spike_sigma`` robust standard deviations of that residual (the
  median absolute deviation over the chunk, times 1.4826);
- **drift**: a two-sided CUSUM on the normalised innovations, ``g_k = max(0, g_k-1 + nu_k - kappa)``,
  above ``cusum_threshold``; the span runs from the last step ``g`` was zero.  ``nu = e / s`` with
  ``s`` the smallest robust scale of any chunk so far (1.4826 times the median of ``|e|``).

The raw tests (stuck, clipped, spike) see a chunk before the filter; the innovation test (drift)
after it, on the innovations normalised by their robust scale, so that ``faults = "drop"``
filters a chunk a second time with its faulty samples missing.  A drift of a channel that no
other channel checks (a gauge without static redundancy) leaves no trace of its own in the
innovations: the filter moves the forces to fit it, and the other channels' innovations drift.
"""
from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass

import numpy as np

from .quality import runs

#: what ``[measurements] faults`` may be
FAULT_MODES = ("flag", "drop", "off")
#: the share of a chunk's largest (and smallest) samples where a rail is looked for
EXTREME_SHARE = 0.01
#: extreme values held per channel before those met once are forgotten
MAX_CANDIDATES = 4096


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
    cusum_drift: float = 2.0
    cusum_threshold: float = 60.0


@dataclass(frozen=True)
class Fault:
    """One fault: a channel, a kind and a span of steps ``[first, stop)``, with its evidence.

    Parameters
    ----------
    channel : str
        The sensor label.
    kind : str
        "stuck", "clipped", "spike" or "drift".
    first, stop : int
        Record steps ``[first, stop)``.
    evidence : str
        What the test saw.
    """

    channel: str
    kind: str
    first: int
    stop: int
    evidence: str

    def row(self, dt, t0=0.0):
        """The fault as a table row.

        Parameters
        ----------
        dt, t0 : float
            Time step and time of step 0 (s).

        Returns
        -------
        dict
            ``channel``, ``kind``, ``start_s``, ``end_s`` (s), ``samples``, ``evidence``.
        """
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
        self.rails = [set() for _ in range(m)]
        self.candidates = [{} for _ in range(m)]      # extreme values met before a rail is known: their steps
        self.g = np.zeros((2, m))                # the CUSUM, up and down
        self.scale = np.full(m, np.inf)          # the innovations' robust scale, the smallest of any chunk
        self.g_zero = np.zeros((2, m), int)      # the last step it was zero
        self.found = []

    # ----------------------------------------------------------------------- before the filter
    def raw(self, Y, step):
        """Stuck, clipped and spiking samples of a chunk.

        Parameters
        ----------
        Y : ndarray (k, m)
            The chunk's raw samples (NaN where missing).
        step : int
            The record step of its first row.

        Returns
        -------
        ndarray (k, m) of bool
        """
        Y = np.asarray(Y, float)
        bad = np.zeros(Y.shape, bool)
        for j in range(Y.shape[1]):
            clipped = self._clipped(j, Y[:, j], step)
            bad[:, j] = clipped | self._stuck(j, Y[:, j], step)
        return bad | self.spikes(np.where(bad, np.nan, Y), step)

    def _stuck(self, j, y, step):
        same = np.r_[y[:1] == self.last[j], y[1:] == y[:-1]]      # equal to the sample before
        out = np.zeros(y.size, bool)
        before = self.repeat[j]                                   # identical samples that ended the chunk before
        found = runs(same)
        for a, b in found:
            # the identical samples: y[a-1 .. b-1], or with a = 0 the ``before`` ones of the chunk before too
            count, first = (b + before, step - before) if a == 0 else (b - a + 1, step + a - 1)
            if count >= self.settings.stuck_steps and float(y[b - 1]) not in self.rails[j]:   # at a rail: clipped
                out[max(a - 1, 0):b] = True
                self._add(j, "stuck", first, step + b, f"{count} identical samples ({y[b - 1]:.6g})")
        if y.size:
            last = found[-1] if len(found) and found[-1, 1] == y.size else None
            self.repeat[j] = 1 if last is None else (y.size + before if last[0] == 0 else y.size - last[0] + 1)
            self.last[j] = y[-1]
        return out

    def _clipped(self, j, y, step):
        seen = ~np.isnan(y)
        if not seen.any() or np.ptp(y[seen]) == 0:              # nothing, or a constant chunk (stuck, not clipped)
            return np.isin(y, list(self.rails[j])) if self.rails[j] else np.zeros(y.size, bool)
        values = y[seen]
        hi, lo = np.quantile(values, [1 - EXTREME_SHARE, EXTREME_SHARE]) if values.size >= 1 / EXTREME_SHARE else \
            (values.max(), values.min())
        candidates = self.candidates[j]
        extreme = np.flatnonzero(seen & ((y >= hi) | (y <= lo)))
        values, first_at, counts = np.unique(y[extreme], return_index=True, return_counts=True)
        known = np.isin(values, np.fromiter(candidates, float, len(candidates))) if candidates else np.zeros(len(values), bool)
        once = (counts == 1) & ~known
        for v, k in zip(values[once].tolist(), extreme[first_at[once]].tolist()):     # met once so far: remembered
            if v not in self.rails[j]:
                candidates[v] = [step + k]
        for v in values[~once].tolist():
            if v in self.rails[j]:
                continue
            steps = candidates.setdefault(v, [])
            steps += (step + extreme[y[extreme] == v]).tolist()
            separate = 1 + int(np.count_nonzero(np.diff(steps) > 1))
            # a value met again and again at the extremes, not in one long run (that is stuck)
            if len(steps) >= self.settings.clip_count and (separate > 1 or len(steps) < self.settings.stuck_steps):
                self.rails[j].add(v)
                for earlier in candidates.pop(v):
                    if earlier < step:                            # before this chunk: reported now
                        self._add(j, "clipped", earlier, earlier + 1, f"at the rail {v:.6g}")
        if len(candidates) > MAX_CANDIDATES:                      # forget the values met once
            self.candidates[j] = {v: s for v, s in candidates.items() if len(s) > 1}
        out = np.isin(y, list(self.rails[j])) if self.rails[j] else np.zeros(y.size, bool)
        for a, b in runs(out):
            self._add(j, "clipped", step + a, step + b, f"at the rail {y[a]:.6g}")
        return out

    def spikes(self, Y, step):
        """Isolated outliers of a chunk: samples that stand out of their neighbours' median by
        ``spike_sigma`` robust standard deviations of that residual, at most ``spike_width`` in a row.

        Parameters
        ----------
        Y : ndarray (k, m)
            The chunk's samples (NaN where missing or already found faulty).
        step : int
            The record step of its first row.

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
        padded = np.pad(Y, ((half, half), (0, 0)), mode="edge")
        k = Y.shape[0]
        neighbours = np.stack([padded[i:i + k] for i in range(2 * half + 1) if i != half], axis=-1)   # itself left out
        if np.isnan(neighbours).any():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)        # an all-missing window
                residual = Y - np.nanmedian(neighbours, axis=-1)
        else:                                                          # the middle two of its 2 half values
            part = np.partition(neighbours, [half - 1, half], axis=-1)
            residual = Y - 0.5 * (part[..., half - 1] + part[..., half])
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
            # about zero (a filter's innovations have zero mean), and the smallest so far: a drift only raises it
            scale = 1.4826 * np.median(np.abs(e[seen]))
            if scale > 0:
                self.scale[j] = min(self.scale[j], scale)
                bad[:, j] = self._drift(j, np.where(seen, e / self.scale[j], 0.0), step)
        return bad

    def _drift(self, j, nu, step):
        st = self.settings
        out = np.zeros(nu.size, bool)
        if not nu.size:
            return out
        for side, sign in enumerate((1.0, -1.0)):
            # g_k = max(0, g_k-1 + v_k) for all k at once: S_k - min(0, min_{i<=k} S_i), S the running sum from g
            S = self.g[side, j] + np.cumsum(sign * nu - st.cusum_drift)
            g = S - np.minimum(np.minimum.accumulate(S), 0.0)
            g[g < 0] = 0.0
            above = g > 0
            for a, b in runs(above):                       # excursions above zero
                first = self.g_zero[side, j] if a == 0 and self.g[side, j] > 0 else step + a
                if g[a:b].max() > st.cusum_threshold:
                    out[a:b] = True
                    self._add(j, "drift", int(first), step + int(b), f"CUSUM {'up' if sign > 0 else 'down'} above "
                                                                      f"{st.cusum_threshold:g}")
            last = runs(above)
            self.g_zero[side, j] = (self.g_zero[side, j] if len(last) and last[-1, 0] == 0 and self.g[side, j] > 0
                                    else step + int(last[-1, 0])) if len(last) and last[-1, 1] == nu.size else step + nu.size
            self.g[side, j] = g[-1]
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
        """What a checkpoint keeps (:meth:`restore` takes it back).

        Returns
        -------
        dict of str to ndarray
        """
        return {"fault_last": self.last.copy(), "fault_repeat": self.repeat.copy(),
                "fault_candidates": np.array([[j, v, k] for j, c in enumerate(self.candidates) for v, steps in c.items()
                                              for k in steps], float).reshape(-1, 3),
                "fault_g": self.g.copy(), "fault_g_zero": self.g_zero.copy(), "fault_scale": self.scale.copy(),
                "fault_rails": np.array([[j, v] for j, r in enumerate(self.rails) for v in sorted(r)], float).reshape(-1, 2),
                "fault_found": np.array([repr(asdict(f)) for f in self.found], str)}

    def restore(self, state):
        """Continue from a :meth:`state` (a checkpoint without one: from scratch).

        Parameters
        ----------
        state : mapping of str to ndarray

        Returns
        -------
        FaultDetector
            ``self``.
        """
        import ast

        if "fault_last" not in state:
            return self
        self.last, self.repeat = np.array(state["fault_last"], float), np.array(state["fault_repeat"], int)
        self.candidates = [{} for _ in self.labels]
        for j, v, k in np.asarray(state["fault_candidates"], float).reshape(-1, 3):
            self.candidates[int(j)].setdefault(float(v), []).append(int(k))
        self.g, self.g_zero = np.array(state["fault_g"], float), np.array(state["fault_g_zero"], int)
        self.scale = np.array(state["fault_scale"], float)
        self.rails = [set() for _ in self.labels]
        for j, v in np.asarray(state["fault_rails"], float).reshape(-1, 2):
            self.rails[int(j)].add(float(v))
        self.found = [Fault(**ast.literal_eval(str(s))) for s in np.asarray(state["fault_found"]).reshape(-1)]
        return self
