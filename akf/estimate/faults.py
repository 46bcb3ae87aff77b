"""Sensor faults in a run (``[measurements] faults``): each chunk tested before the filter (stuck,
clipped, spikes) and after it (drift in the innovations); "drop" filters the chunk again with the
faulty samples missing.  The findings go to ``data_quality.csv``, the JSON and the warnings."""
from __future__ import annotations

import numpy as np

from core_akf.faults import FaultDetector, FaultSettings

#: columns of data_quality.csv
QUALITY_COLUMNS = ("channel", "kind", "start_s", "end_s", "samples", "evidence")
#: faults listed one by one in the warnings (the rest counted)
LISTED_FAULTS = 12


class FaultCheck:
    """The fault tests of one run.

    Parameters
    ----------
    job : akf.job.Job
        Its ``[measurements] faults`` and ``fault_thresholds``.
    labels : list of str
        The channels.
    """

    def __init__(self, job, labels):
        meas = job.spec.measurements
        self.mode = (meas.faults if meas is not None and meas.faults is not None else "flag")
        given = {} if meas is None or meas.fault_thresholds is None else meas.fault_thresholds.model_dump(exclude_none=True)
        self.detector = FaultDetector(labels, FaultSettings(**given))
        self.dt = job.dt

    @property
    def on(self):
        return self.mode != "off"

    def before(self, Y, step):
        """The chunk to filter: with "drop", the samples of the raw tests missing."""
        bad = self.detector.raw(Y, step)
        return np.where(bad, np.nan, Y) if self.mode == "drop" and bad.any() else Y

    def after(self, estimator, est, Y, saved):
        """The chunk's estimate; with "drop", filtered again without the samples the drift test found.

        Parameters
        ----------
        estimator : core_akf.filter.Estimator
            It has just filtered ``Y``; ``saved`` is its state before.
        est : Estimate
            What it returned (with a fixed-lag smoother, earlier steps: those are tested, and not
            filtered again).
        Y : ndarray (k, m)
            The chunk as filtered.
        saved : dict
            ``estimator.state()`` before the chunk.
        """
        step = estimator.n_returned - est.forces.shape[0]
        bad = self.detector.innovations(est.innovations, step, np.isnan(est.measurements))
        if self.mode != "drop" or not bad.any() or estimator.lagged is not None:
            return est
        estimator.restore(saved)
        return estimator.update(np.where(bad, np.nan, Y))

    def rows(self, t0):
        """The faults as table rows (times in s)."""
        return [f.row(self.dt, t0) for f in self.detector.faults()]

    def warnings(self, t0):
        """One line per fault (the first :data:`LISTED_FAULTS`), in the user's words."""
        rows = self.rows(t0)
        verb = "treated as missing" if self.mode == "drop" else "kept (faults = \"flag\")"
        out = [f"{r['channel']}: {r['kind']} at t = {r['start_s']:.6g}-{r['end_s']:.6g} s ({r['samples']} samples; "
               f"{r['evidence']}); {verb}" for r in rows[:LISTED_FAULTS]]
        if len(rows) > LISTED_FAULTS:
            out.append(f"... and {len(rows) - LISTED_FAULTS} more sensor faults: see data_quality.csv")
        return out

    def frame(self, t0):
        """data_quality.csv as a DataFrame."""
        import pandas as pd

        return pd.DataFrame(self.rows(t0), columns=list(QUALITY_COLUMNS))

    def state(self):
        return self.detector.state()

    def restore(self, state):
        self.detector.restore(state)


class _NoCheck:
    """The fault check of a simulated run: none."""

    on = False

    def state(self):
        return {}

    def restore(self, state):
        pass


NO_FAULT_CHECK = _NoCheck()
