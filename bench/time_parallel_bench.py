"""Months of data on many cores (run by hand: ``python bench/time_parallel_bench.py [--hours H]``).

The steady-state AKF over a record cut into pieces (10-minute files), the pieces filtered at the
same time (:func:`core_akf.filter.parallel.estimate_in_parallel`): every piece's zero-state end state,
a pass over the boundaries, then every piece from its start state, with the fatigue of all 34
members counted per piece and merged.  The S17 case-4 set at 1 kHz; each worker reads its own
piece from a ``.npy`` file.  Printed: the sequential stream (one process, which already keeps
every core of a small machine busy: BLAS and the lifted recursion's own threads), the same pieces
through the builtin ``map`` (one process: the price of the extra pass), and a 2-worker dask
``LocalCluster`` (one thread per worker); the time of each step on one core, and what they predict
for N single-core workers (``(ends + runs) / N + boundaries`` plus the 2-worker run's overhead).
The parallel result is checked against the sequential stream: forces to 1e-9, cycle counts
exactly.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np

os.environ.setdefault("PYTHONWARNINGS", "ignore")

DT, PIECE_SECONDS = 1e-3, 600


class _Piece:
    def __init__(self, path):
        self.path = path

    def __call__(self):
        return np.load(self.path)


class _Fatigue:
    def __init__(self, W):
        self.W = W

    def __call__(self, est, i):
        from core_akf.fatigue import FatigueAccumulator, SNCurve

        acc = FatigueAccumulator(self.W.shape[0], SNCurve.ec3(36))
        acc.update(est.strains @ self.W.T)
        return est.forces[::1000].copy(), acc          # a decimated force record and the counts travel back


def main(argv=None):
    import distributed

    from core_akf import simulate
    from core_akf.fatigue import FatigueAccumulator, SNCurve, stress_operator
    from core_akf.filter import Estimator, TimeParallel, estimate_in_parallel
    from core_akf.loads import band_limited_white_noise
    from core_akf.models import s17_truss

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=1.0)
    args = parser.parse_args(argv)
    sensors = ["acc:4:y", "acc:6:y", "acc:8:y", "acc:12:y", "acc:6:x", "strain:5", "strain:9", "strain:13", "strain:26"]
    forces = ["4:y", "6:y", "8:y", "12:y"]
    truss = s17_truss()
    n = int(args.hours * 3600 / DT)
    folder = tempfile.mkdtemp(prefix="akf-tp-")
    pieces, rng = [], np.random.default_rng(0)
    for i, start in enumerate(range(0, n, int(PIECE_SECONDS / DT))):
        k = min(int(PIECE_SECONDS / DT), n - start)
        loads = np.column_stack([band_limited_white_noise(k, DT, 500.0, 0.0, 50.0, seed=int(rng.integers(1 << 30)))
                                 for _ in forces])
        Y = simulate(truss, sensors, forces, loads, DT, relative_noise=0.02, seed=i).measurements
        path = os.path.join(folder, f"piece{i:03d}.npy")
        np.save(path, Y)
        pieces.append(_Piece(path))
    kw = dict(model_error_cov=1e-16, force_increment_cov=1e5, noise_cov={"acc": 1e-4, "strain": 1e-12}, steady=True)
    W = stress_operator(truss, range(truss.n_strain))

    def estimator():
        return Estimator(truss.scaled(1.05), sensors, forces, DT, **kw)

    def sequential():
        seq, counts, seq_forces = estimator(), FatigueAccumulator(W.shape[0], SNCurve.ec3(36)), []
        for p in pieces:
            est = seq.update(p())
            counts.update(est.strains @ W.T)
            seq_forces.append(est.forces[::1000])
        return counts, np.vstack(seq_forces)
    t_seq = np.inf
    for _ in range(2):                                        # the sequential stream, best of two
        t0 = time.perf_counter()
        counts, seq_forces = sequential()
        t_seq = min(t_seq, time.perf_counter() - t0)

    # the steps one by one, timed in one process on one core (as a dask worker of one thread runs them)
    from threadpoolctl import threadpool_limits

    tp = TimeParallel(estimator())
    os.environ["AKF_NUM_THREADS"] = "1"
    with threadpool_limits(1):
        t0 = time.perf_counter()
        ends = [tp.end_state(p()) for p in pieces]
        t_ends = time.perf_counter() - t0
        t0 = time.perf_counter()
        starts = tp.starts(ends)
        t_bound = time.perf_counter() - t0
        t0 = time.perf_counter()
        for s, p in zip(starts, pieces):
            _Fatigue(W)(tp.run(s, p()), 0)
        t_runs = time.perf_counter() - t0
    del os.environ["AKF_NUM_THREADS"]

    def check(out, label, wall):
        f = np.vstack([o[0] for o in out])
        merged = out[0][1]
        for _, acc in out[1:]:
            merged.merge(acc)
        ok_f = np.allclose(f, seq_forces, rtol=1e-9, atol=1e-9 * np.abs(seq_forces).max())
        ok_c = np.array_equal(merged.summary().cycles, counts.summary().cycles)
        print(f"{label:34s} {wall:7.1f} s  {t_seq / wall:5.2f}x the sequential stream;  forces to 1e-9: {ok_f}, "
              f"cycle counts exactly: {ok_c}")
        return wall
    print(f"S17 case-4 set, {args.hours:g} h at 1 kHz ({n:,} steps, {len(pieces)} pieces of {PIECE_SECONDS} s), "
          "fatigue of 34 members")
    print(f"{'sequential stream':34s} {t_seq:7.1f} s  (one process; its BLAS and its own threads use every core)")
    print(f"  the steps on one core: ends {t_ends:.1f} s, boundaries {t_bound:.3f} s, runs {t_runs:.1f} s")
    t0 = time.perf_counter()
    out = estimate_in_parallel(estimator(), pieces, on_piece=_Fatigue(W))
    check(out, "pieces, builtin map (1 process)", time.perf_counter() - t0)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as client:
        client.run(lambda: __import__("core_akf.filter.streaming") and __import__("core_akf.fatigue"))   # warm workers
        t0 = time.perf_counter()
        out = estimate_in_parallel(estimator(), pieces, lambda f, xs: client.gather(client.map(f, xs, pure=False)),
                                   on_piece=_Fatigue(W))
        t_two = check(out, "pieces, 2-worker LocalCluster", time.perf_counter() - t0)
    # the 2-worker run's time beyond its share of the work: start-up, transfers, the driver's part
    overhead = max(t_two - (t_ends + t_runs) / 2 - t_bound, 0.0)
    print(f"  the 2-worker run's overhead beyond half the one-core work: {overhead:.1f} s; predicted for N workers of "
          "one core each, (ends + runs) / N + boundaries + that overhead, with at least N pieces:")
    for workers in (2, 4, 8, 16, 64):
        predicted = (t_ends + t_runs) / workers + t_bound + overhead
        print(f"  {workers:3d} workers: {predicted:7.1f} s, {t_seq / predicted:5.1f}x the sequential stream, "
              f"{n * DT / predicted:7.0f}x real time")


if __name__ == "__main__":
    main()
