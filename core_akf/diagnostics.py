"""What an estimate can say about itself without a reference: innovation statistics per sensor,
force statistics, and warnings for results that should not be trusted.

On measured data there is no true force to compare with; what remains measurable is how well the
filter predicts each sensor one step ahead.  For a filter whose model and covariances fit the data,
the innovations ``e_k = y_k - G_a X_k^-`` are white with covariance ``S = G_a P G_a^T + R``
(Mehra 1970).  Per channel this module reports the innovation RMS, its ratio to the predicted
``sqrt(S_ii)`` (the *consistency*: about 1 when the noise levels fit, >> 1 when the channel is
off -- a wrong unit or sign, a broken sensor, too small a ``noise_cov``) and the share of the
first 20 autocorrelation lags inside the 95 % band of white noise (the *whiteness*).
"""
from __future__ import annotations

import numpy as np

from .checks import AKFInputError
from .filter.results import WHITENESS_LAGS, sensor_diagnostics, skipped
from .quality import HoleCounter
from .sensors import UNITS

#: a channel whose innovations are this many times their predicted size is flagged
CONSISTENCY_LIMIT = 10.0
#: ... and one whose innovations are this small a share of it
LOW_CONSISTENCY = 0.2
#: a record should be this many filter time constants long (transient plus a useful part)
TRANSIENT_MULTIPLE = 3.0
#: what a checkpoint keeps of the hole counts
HOLE_FIELDS = ("steps", "missing", "spans", "longest", "lead", "trail")


class RunningDiagnostics:
    """The diagnostics of a record estimated chunk by chunk, in constant memory.

    :func:`sensor_diagnostics` and :func:`force_statistics` of the whole record from the chunks of
    a :class:`core_akf.filter.streaming.Estimator`: sums, the extreme force, and the lag products of the
    innovations across chunk boundaries.  Feed each chunk's estimate to :meth:`update` in order.

    Parameters
    ----------
    n_steps : int or None
        The record's length, to leave out the same first 5 % as the one-piece functions (None:
        nothing is left out).
    lags : int
        Autocorrelation lags of the whiteness test.
    """

    def __init__(self, n_steps=None, lags=WHITENESS_LAGS):
        self.skip = 0 if n_steps is None else skipped(int(n_steps))
        self.lags = lags
        self.step = 0            # steps seen
        self.n = 0               # steps counted (after the skip)
        self.last = None

    def _start(self, est):
        m, p = est.measurements.shape[1], est.forces.shape[1]
        self.sum_y2, self.sum_e, self.sum_e2 = np.zeros(m), np.zeros(m), np.zeros(m)
        self.lag = np.zeros((self.lags, m))
        self.head, self.tail = np.zeros((0, m)), np.zeros((0, m))
        self.sum_f2, self.peak, self.peak_step = np.zeros(p), np.zeros(p), np.zeros(p, int)
        self.sum_loglik = np.zeros(m)
        self.n_obs = np.zeros(m, int)           # observed samples counted, per channel
        self.holes = HoleCounter(m)

    def update(self, est):
        """Add one chunk.

        Parameters
        ----------
        est : Estimate
            The chunk's :class:`~core_akf.filter.Estimate`, in record order.
        """
        if self.last is None:
            self._start(est)
        k = est.forces.shape[0]
        self._seen = self.n_seen + k
        self.sum_loglik += est.loglik_channels            # the likelihood of the whole record: no skip
        self.holes.update(est.measurements)               # every step: no skip
        cut = min(max(self.skip - self.step, 0), k)
        first = self.step + cut                      # record step of the first counted sample
        self.step += k
        self.last = est
        if cut == k:
            return
        Y, E, F = est.measurements[cut:], est.innovations[cut:], est.forces[cut:]
        seen = ~np.isnan(Y)
        self.n_obs += seen.sum(axis=0)
        if not seen.all():                       # a missing sample adds nothing to the sums
            Y, E = np.where(seen, Y, 0.0), np.where(seen, E, 0.0)
        self.sum_y2 += np.sum(Y ** 2, axis=0)
        self.sum_e += E.sum(axis=0)
        self.sum_e2 += np.sum(E ** 2, axis=0)
        ext = np.vstack([self.tail, E])
        t = self.tail.shape[0]
        for l in range(1, self.lags + 1):
            lo = max(t, l)
            if lo < ext.shape[0]:
                self.lag[l - 1] += np.sum(ext[lo - l:ext.shape[0] - l] * ext[lo:], axis=0)
        self.head = np.vstack([self.head, E[:self.lags - self.head.shape[0]]])
        self.tail = ext[-self.lags:]
        self.n += E.shape[0]
        self.sum_f2 += np.sum(F ** 2, axis=0)
        i = np.argmax(np.abs(F), axis=0)
        better = np.abs(F[i, range(F.shape[1])]) > np.abs(self.peak)
        self.peak = np.where(better, F[i, range(F.shape[1])], self.peak)
        self.peak_step = np.where(better, first + i, self.peak_step)

    def _whiteness(self, j):
        n = int(self.n_obs[j])
        if n < 2:
            return float("nan"), float("nan")
        mu = self.sum_e[j] / n
        denom = self.sum_e2[j] - n * mu ** 2
        lags = min(self.lags, n - 1)
        if denom <= 0 or lags < 1:
            return float("nan"), float("nan")
        rho = np.empty(lags)
        for l in range(1, lags + 1):
            first_l, last_l = self.head[:l, j].sum(), self.tail[-l:, j].sum()
            rho[l - 1] = (self.lag[l - 1, j] - mu * (2 * self.sum_e[j] - first_l - last_l) + (n - l) * mu ** 2) / denom
        return float(np.mean(np.abs(rho) < 1.96 / np.sqrt(n))), float(rho[0])

    def sensors(self):
        """:func:`sensor_diagnostics` of the whole record.

        Returns
        -------
        list of dict
        """
        est = self.last
        out = []
        for j, (s, holes) in enumerate(zip(est.sensors, self.holes.statistics(est.dt))):
            n = max(int(self.n_obs[j]), 1)
            irms = float(np.sqrt(self.sum_e2[j] / n)) if self.n_obs[j] else float("nan")
            std = float(np.sqrt(max(est.innovation_cov[j, j], 0.0)))
            white, lag1 = self._whiteness(j)
            out.append({"channel": s.label, "unit": UNITS[s.kind],
                        "measured_rms": float(np.sqrt(self.sum_y2[j] / n)) if self.n_obs[j] else float("nan"),
                        "innovation_rms": irms, "predicted_innovation_std": std,
                        "consistency": irms / std if std > 0 else float("inf"), "whiteness": white,
                        "lag1_autocorrelation": lag1, "loglik": float(self.sum_loglik[j]), **holes})
        return out

    def loglik(self):
        """The log-likelihood of the whole record's innovations (:attr:`core_akf.filter.Estimate.loglik`).

        Returns
        -------
        float
        """
        return float(self.sum_loglik.sum())

    def forces(self, t0=0.0):
        """:func:`force_statistics` of the whole record.

        Parameters
        ----------
        t0 : float
            Time of the record's first step (s); ``time_of_peak`` counts from it.

        Returns
        -------
        list of dict
        """
        est = self.last
        return [{"channel": f"{node}:{d}", "unit": "N", "rms": float(np.sqrt(self.sum_f2[j] / self.n)),
                 "peak": float(self.peak[j]), "time_of_peak": float(t0 + self.peak_step[j] * est.dt)}
                for j, (node, d) in enumerate(est.force_locations)]

    def starting_at(self, step: int) -> RunningDiagnostics:
        """Count a piece of the record that starts at record step ``step`` (for :meth:`merge`).

        Parameters
        ----------
        step : int
            The record step of the piece's first row.

        Returns
        -------
        RunningDiagnostics
            ``self``.
        """
        if self.last is not None:
            raise AKFInputError("starting_at comes before the first update")
        self.step = int(step)
        return self

    def merge(self, later: RunningDiagnostics) -> RunningDiagnostics:
        """Join the diagnostics of the piece that follows this one (counted apart,
        :meth:`starting_at` its first step): as if one had seen both, the lag products across the
        join included.

        Parameters
        ----------
        later : RunningDiagnostics
            The next piece's diagnostics.

        Returns
        -------
        RunningDiagnostics
            ``self``.
        """
        if later.last is None:
            return self
        if self.last is None:
            self.__dict__.update({k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in later.__dict__.items()})
            return self
        if later.step - later.n_seen != self.step:
            raise AKFInputError(f"the pieces do not join: this one ends at step {self.step}, the next starts at "
                                f"{later.step - later.n_seen}")
        T, H = self.tail.shape[0], later.head.shape[0]
        for l in range(1, self.lags + 1):          # pairs l steps apart across the join: the i-th last of the
            i = np.arange(max(0, l - H), min(l, T))  # left piece and the (l-1-i)-th first of the right one
            if i.size:
                self.lag[l - 1] += np.sum(self.tail[T - 1 - i] * later.head[l - 1 - i], axis=0)
        for k in ("sum_y2", "sum_e", "sum_e2", "lag", "sum_f2", "sum_loglik", "n_obs"):
            setattr(self, k, getattr(self, k) + getattr(later, k))
        self.holes.merge(later.holes)
        better = np.abs(later.peak) > np.abs(self.peak)
        self.peak = np.where(better, later.peak, self.peak)
        self.peak_step = np.where(better, later.peak_step, self.peak_step)
        self.head = np.vstack([self.head, later.head])[:self.lags]
        self.tail = np.vstack([self.tail, later.tail])[-self.lags:]
        self.n += later.n
        self.step = later.step
        self.last = later.last
        return self

    @property
    def n_seen(self):
        """Steps given to :meth:`update` (counted or skipped)."""
        return getattr(self, "_seen", 0)

    def state(self):
        """The accumulators, saved with a resumable run.

        Returns
        -------
        dict of str to ndarray
        """
        return {f"diag_{k}": np.asarray(getattr(self, k)) for k in
                ("skip", "step", "n", "sum_y2", "sum_e", "sum_e2", "lag", "head", "tail", "sum_f2", "peak", "peak_step",
                 "sum_loglik", "n_obs")} | {f"diag_holes_{k}": np.asarray(getattr(self.holes, k)) for k in HOLE_FIELDS}

    def restore(self, state, est):
        """Continue from a saved :meth:`state`.

        Parameters
        ----------
        state : mapping of str to ndarray
            What :meth:`state` returned (as loaded from a checkpoint).
        est : Estimate
            Any chunk estimate of the run (for its shapes).

        Returns
        -------
        RunningDiagnostics
            ``self``.
        """
        self._start(est)
        for k in ("sum_y2", "sum_e", "sum_e2", "lag", "head", "tail", "sum_f2", "peak", "peak_step", "sum_loglik"):
            setattr(self, k, np.array(state[f"diag_{k}"]))
        self.skip, self.step, self.n = (int(state[f"diag_{k}"]) for k in ("skip", "step", "n"))
        self.n_obs = np.array(state["diag_n_obs"]) if "diag_n_obs" in state else np.full(self.sum_e.shape, self.n)
        if "diag_holes_steps" in state:
            for k in HOLE_FIELDS:
                setattr(self.holes, k, np.array(state[f"diag_holes_{k}"]) if k != "steps" else int(state["diag_holes_steps"]))
        else:                                   # a checkpoint of a record without holes
            self.holes.steps = self.step
        self.last = est
        return self


def warnings_for(est, sensors=None, duration=None):
    """Plain-language warnings about an estimate.

    Parameters
    ----------
    est : Estimate
        The estimate, or the last chunk of a streamed record.
    sensors : list of dict, optional
        Its :func:`sensor_diagnostics` (computed if not given).
    duration : float, optional
        The record's length (s) when ``est`` is its last chunk (default the length of ``est``).

    Returns
    -------
    list of str
        Channels whose innovations are far larger or smaller than their predicted size, a filter whose error does not
        decay (an undetectable set), and a record shorter than the filter's transient.
    """
    sensors = sensor_diagnostics(est) if sensors is None else sensors
    notes = []
    off = sorted((d for d in sensors if d["consistency"] > CONSISTENCY_LIMIT), key=lambda d: -d["consistency"])
    if off:
        listed = ", ".join(f"{d['channel']} ({d['consistency']:.3g}x)" for d in off)
        notes.append(f"innovations larger than predicted at {listed}: the data do not fit the model and noise_cov "
                     "there; check each channel's unit (SI), sign and noise variance")
    low = sorted((d for d in sensors if d["consistency"] < LOW_CONSISTENCY), key=lambda d: d["consistency"])
    if low:
        listed = ", ".join(f"{d['channel']} ({d['consistency']:.2g}x)" for d in low)
        notes.append(f"innovations smaller than predicted at {listed}: the filter expects more than these channels "
                     "see. Most likely force_increment_cov (S) is larger than the loads' steps (an accelerometer "
                     "feels a force step at once, so S sets its predicted spread), else the channel's noise_cov, "
                     "else model_error_cov is too large; [filter] calibrate = [\"force_increment_cov\", "
                     "\"noise_cov\"] fits both")
    duration = est.forces.shape[0] * est.dt if duration is None else duration
    tau = est.transient_time
    if not np.isfinite(tau):
        notes.append("the filter's estimation error does not decay (its closed loop has a pole on or outside the "
                     "unit circle): the estimate drifts; add strain or displacement sensors")
    elif duration < TRANSIENT_MULTIPLE * tau:
        notes.append(f"the record ({duration:.3g} s) is shorter than {TRANSIENT_MULTIPLE:g} time constants of the "
                     f"filter's transient ({tau:.3g} s): the estimate has not settled; use a longer record or a "
                     "larger force_increment_cov")
    return notes


#: units a channel may have been given in by mistake: factor (data / SI) -> what it looks like
_UNIT_GUESSES = [
    (1 / 9.80665, "acceleration in g instead of m/s^2 (multiply by 9.81)"),
    (1e3, "millimetres (mm, mm/s, mm/s^2) instead of metres (divide by 1000)"),
    (1e-3, "kilo-units or a gain of 1/1000 (multiply by 1000)"),
    (1e6, "microstrain instead of m/m (divide by 1e6)"),
    (-1.0, "a flipped sign (multiply by -1)"),
]
#: a channel (or kind) whose data are this far from what the other sensors imply is reported
_SCALE_LIMIT = 3.0
#: ... if the data and that prediction are this well correlated (so a scale, not noise, differs)
_CORRELATION_MIN = 0.7
#: the filter ignores a channel whose noise variance is inflated by this factor
_IGNORE = 1e10


def _closest(c):
    """The unit mistake whose factor is closest to ``c`` (same sign), and the log-distance."""
    same = [g for g in _UNIT_GUESSES if np.sign(g[0]) == np.sign(c)] or _UNIT_GUESSES
    best = min(same, key=lambda g: abs(np.log(abs(c) / abs(g[0]))))
    return best, abs(np.log(abs(c) / abs(best[0])))


def _guess(c):
    """What a scale factor ``c`` (data / implied by the other sensors) looks like."""
    best, dist = _closest(c)
    return best[1] if dist < np.log(2.5) else "a wrong unit, gain or sign"


def scale_check(structure, sensors, forces, measurements, dt, *, model_error_cov, force_increment_cov=None, noise_cov,
                force_model=None):
    """Which channels or sensor kinds disagree with the rest by a scale factor (a wrong unit or sign).

    Each sensor kind (when there are several) and each single channel is held out in turn -- the
    filter ignores it (noise variance x 1e10) -- and the held-out data are regressed on what the
    other sensors imply for them (one-step predictions): ``y ~ c y_hat``.  A hold-out whose other
    sensors are not detectable (say, accelerations alone) is skipped.  A factor ``c`` outside
    [1/3, 3] (or negative) with a correlation above 0.7 is reported with the unit it looks like.
    All hold-outs run as one batched steady-state filter.

    Parameters
    ----------
    structure : Structure
        The filter's model.
    sensors : sequence of sensor specs
        The layout, m channels.
    forces : sequence of force specs
        The unknown force locations.
    measurements : array_like (N, m)
        The record (SI), columns in sensor order.
    dt : float
        Time step (s).
    model_error_cov, force_increment_cov, noise_cov
        Q, S and R as in :func:`core_akf.filter.estimate`.
    force_model : ForceModel, optional
        The force model, as in :func:`core_akf.filter.estimate`.

    Returns
    -------
    list of str
        One warning per channel or kind that looks scaled, naming the unit it looks like.
    """
    from .filter.kernels import steady_outputs
    from .filter.model import Filter
    from .statespace import detectability

    f = Filter(structure, [sensors], forces, dt, model_error_cov=model_error_cov,
               force_increment_cov=force_increment_cov, noise_cov=noise_cov, allow_undetectable=True,
               force_model=force_model)
    layout, locs, R = f.layouts[0], f.locs, f.R[0]
    Y = np.asarray(measurements, float)
    kinds = np.array([s.kind for s in layout])
    groups = [("kind", k, np.flatnonzero(kinds == k)) for k in dict.fromkeys(kinds)] if len(set(kinds)) > 1 else []
    groups += [("channel", s.label, np.array([j])) for j, s in enumerate(layout)]
    # a hold-out whose other sensors cannot see the forces has no steady-state filter (acceleration
    # only, say): nothing to compare with there
    groups = [g for g in groups if len(g[2]) < len(layout)
              and detectability(structure, [s for j, s in enumerate(layout) if j not in g[2]], locs,
                                f.force_model).detectable]
    if not groups:
        return []
    Rs = np.stack([R.copy() for _ in groups])
    for b, (_, _, idx) in enumerate(groups):
        Rs[b, idx, idx] *= _IGNORE
    # one-step predictions y_k^- = G_a A_a X_{k-1} of every hold-out, straight from the lifted
    # recursion (no state histories: memory of the order of the data, also for a large model)
    G = np.broadcast_to(f.G_a, (len(groups),) + f.G_a.shape[1:])
    predicted = np.zeros((len(groups),) + Y.shape)
    predicted[:, 1:] = steady_outputs(f.A_a, G, f.Q_a, Rs, np.broadcast_to(Y, (len(groups),) + Y.shape),
                                      f.G_a[0] @ f.A_a)[:, :-1]
    k0 = skipped(Y.shape[0])
    found = []                                   # (what, name, idx, c, r)
    for (what, name, idx), pred in zip(groups, predicted):
        y, yh = Y[k0:, idx].ravel(), pred[k0:, idx].ravel()
        if not np.any(yh) or np.ptp(y) == 0:
            continue
        c = float(yh @ y / (yh @ yh))
        r = float(np.corrcoef(yh, y)[0, 1])
        if abs(r) >= _CORRELATION_MIN and (c < 0 or not 1 / _SCALE_LIMIT <= c <= _SCALE_LIMIT):
            found.append((what, name, idx, c, r))
    kinds_off = [f for f in found if f[0] == "kind"]
    if len(kinds_off) > 1 and len(kinds_off) == len(set(kinds)):
        # every kind disagrees with the others: mirror images of one mistake; keep the best-explained
        kinds_off = [min(kinds_off, key=lambda f: _closest(f[3])[1])]
    off_kinds = {f[1] for f in kinds_off}
    notes = []
    for what, name, idx, c, r in kinds_off + [f for f in found if f[0] == "channel"]:
        if what == "channel" and kinds[idx[0]] in off_kinds:
            continue                             # the whole kind is off: said once
        label = f"the {name} channels" if what == "kind" else f"channel {name}"
        notes.append(f"{label} read {c:.3g} times what the other sensors imply (correlation {r:.2f}): "
                     f"this looks like {_guess(c)}")
    return notes
