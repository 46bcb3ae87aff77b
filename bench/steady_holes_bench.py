"""The steady filter through holes on layouts it was not built on: random S17 layouts, random holes.

Run by hand (``python bench/steady_holes_bench.py [trials] [seed]``, default 100 trials, seed 0);
prints one row per detectable layout, then a summary.

Each trial draws 1-3 gauges and 1-3 accelerometers (vertical) at random members and nodes of the
S17 truss, 1-2 vertical forces at random nodes, and a 3 s record (1 kHz, 2 % noise) of random-walk
loads -- then one of three kinds of holes:

- ``blocks``: 60 random blocks of 1-80 missing samples in random channels;
- ``dead``: one channel dead for 0.1-1.2 s, and 30 blocks of 1-30 samples;
- ``mixed``: the gauges at every 8th step (mixed rates) and 20 blocks of 1-60 samples.

Against the exact (time-varying) filter on the same record: the steady filter's largest force over
the exact filter's (``peak``; above one: the cached gains overshoot), and the RMS of their
difference after the first 0.5 s over the loads' peak (``rms``).  The record is also streamed in
seven random chunks with a checkpoint (``state``/``restore``) between each; ``stream`` is the
largest difference from the whole record's forces over their peak.  Layouts that are not
detectable are refused by the filter and skipped.
"""
import os
import sys
import time
import warnings

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from core_akf import estimate, simulate  # noqa: E402
from core_akf.checks import AKFInputError  # noqa: E402
from core_akf.filter import Estimator  # noqa: E402
from core_akf.models import s17_truss  # noqa: E402

DT, N = 1e-3, 3000
COV = dict(model_error_cov=1e-16, force_increment_cov=1e4)
KINDS = ("blocks", "dead", "mixed")


def _holes(Y, labels, kind, rng):
    n = len(Y)
    if kind == "blocks":
        blocks = [(60, 80)]
    elif kind == "dead":
        j, a = rng.integers(Y.shape[1]), rng.integers(0, n - 1200)
        Y[a:a + rng.integers(100, 1200), j] = np.nan
        blocks = [(30, 30)]
    else:
        slow = [i for i, label in enumerate(labels) if label.startswith("strain")]
        Y[np.ix_(np.arange(n) % 8 != 0, slow)] = np.nan
        blocks = [(20, 60)]
    for count, longest in blocks:
        for _ in range(count):
            j, a = rng.integers(Y.shape[1]), rng.integers(0, n - longest)
            Y[a:a + rng.integers(1, longest), j] = np.nan
    return Y


def trial(structure, rng, kind):
    """One random layout and record; None when the layout is not detectable."""
    members, nodes = np.arange(1, 30), np.arange(2, 17)
    sensors = [f"strain:{m}" for m in rng.choice(members, rng.integers(1, 4), replace=False)] + \
        [f"acc:{k}:y" for k in rng.choice(nodes, rng.integers(1, 4), replace=False)]
    forces = [f"{k}:y" for k in rng.choice(nodes, rng.integers(1, 3), replace=False)]
    loads = 200.0 * rng.standard_normal((N, len(forces))).cumsum(axis=0) / np.sqrt(N)
    sim = simulate(structure, sensors, forces, loads, DT, relative_noise=0.02, seed=int(rng.integers(1 << 30)))
    Y = _holes(sim.measurements.copy(), sensors, kind, rng)
    kw = dict(noise_cov=np.diag(sim.noise_std ** 2), **COV)
    try:
        exact = estimate(structure, sensors, forces, Y, DT, steady=False, **kw)
    except AKFInputError:
        return None
    t = time.perf_counter()
    fast = estimate(structure, sensors, forces, Y, DT, steady=True, **kw)
    seconds = time.perf_counter() - t
    cuts = np.sort(rng.choice(np.arange(1, N), 6, replace=False))
    bounds, state, parts = [0, *cuts.tolist(), N], None, []
    for a, b in zip(bounds[:-1], bounds[1:]):
        stream = Estimator(structure, sensors, forces, DT, steady=True, **kw)
        if state is not None:
            stream.restore(state)
        parts.append(stream.update(Y[a:b]).forces)
        state = stream.state()
    peak = np.abs(fast.forces).max() / np.abs(exact.forces).max()
    rms = np.sqrt(np.mean((fast.forces[500:] - exact.forces[500:]) ** 2)) / np.abs(loads).max()
    stream = np.abs(np.vstack(parts) - fast.forces).max() / np.abs(fast.forces).max()
    return sensors, forces, peak, rms, stream, seconds


def main(trials=100, seed=0):
    rng = np.random.default_rng(seed)
    structure = s17_truss()
    rows = []
    print(f"{'kind':7s} {'sensors':55s} {'forces':12s} {'peak':>6s} {'rms':>7s} {'stream':>8s} {'time (s)':>8s}")
    for i in range(trials):
        kind = KINDS[i % 3]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            row = trial(structure, rng, kind)
        if row is None:
            continue
        sensors, forces, peak, rms, stream, seconds = row
        rows.append((kind, peak, rms, stream))
        print(f"{kind:7s} {' '.join(sensors):55s} {' '.join(forces):12s} {peak:6.3f} {rms:7.4f} {stream:8.1e} "
              f"{seconds:8.2f}", flush=True)
    peaks, rmss, streams = (np.array([r[j] for r in rows]) for j in (1, 2, 3))
    print(f"\n{len(rows)} detectable layouts of {trials}: peak at most {peaks.max():.3f} (median {np.median(peaks):.3f}); "
          f"rms median {np.median(rmss):.4f}, at most {rmss.max():.4f}; stream vs whole at most {streams.max():.1e}")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
