"""Placement GA benchmark (run by hand: python bench/place_bench.py).

TH case 5 -- 3 strain gauges on the thesis plate -- with the thesis GA settings (population 50,
100 generations, elite 2, crossover 0.8, mutation 0.16, tournament 4) on 1 and 2 joblib
workers: wall time, evaluations, evaluations per second, cache hits.  Target on a 2-core
machine: the whole GA in <= 60 s.  Also the time of one fitness evaluation (0.1 s window) with
the full model against the reduced model, alone and in a batch of 50.
"""
import time

import numpy as np

from akf.examples import TH_CASE2
from akf.placement import example_problem
from sensoropt import THESIS, StrainErrorObjective, place


def main():
    p = example_problem("th-case5")
    enc = p.encoding()
    t0 = time.perf_counter()
    obj = p.objective(enc)
    prep = time.perf_counter() - t0
    print(f"TH case 5: {enc.n_sensors} strain gauges, {len(enc.candidates)} admissible positions, "
          f"objective set-up {prep:.2f} s (filter model {obj.model.n_a} states)")
    print(f"{'workers':>7s} {'wall (s)':>9s} {'gens':>5s} {'evals':>6s} {'evals/s':>8s} {'cache hits':>10s}  "
          "best layout (window / full record µε)")
    best = {}
    for n_jobs in (1, 2):
        t0 = time.perf_counter()
        res = place(obj, enc, seed=0, n_jobs=n_jobs, **THESIS)
        wall = time.perf_counter() - t0
        best[n_jobs] = res.best
        gens = int(res.logbook["generation"].iloc[-1])
        print(f"{n_jobs:7d} {wall:9.2f} {gens:5d} {res.evaluations:6d} {res.evaluations / wall:8.1f} {res.cache_hits:10d}  "
              f"{' '.join(res.sensors)} ({res.best_error:.3f} / {p.full_record_error(res.sensors):.3f})")
    print(f"same layout on 1 and 2 workers: {best[1] == best[2]}")
    print(f"TH case 2 (trial and error) on the full record: {p.full_record_error(TH_CASE2):.3f} µε")

    rng = np.random.default_rng(0)
    batch = [enc.sensors(enc.random_layout(rng)) for _ in range(50)]
    print("\none fitness evaluation (0.1 s window, 200 steps)")
    for label, n_modes in (("full model (330 modes, 662 states)", None), ("reduced: 80 modes + static correction", 80)):
        o = StrainErrorObjective(p.structure, p.forces, p.loads, p.dt, enc, n_modes=n_modes)
        t0 = time.perf_counter()
        o.evaluate([TH_CASE2])
        one = time.perf_counter() - t0
        if n_modes is None:
            print(f"  {label:40s} alone {one * 1e3:8.1f} ms")
            continue
        t0 = time.perf_counter()
        o.evaluate(batch)
        many = (time.perf_counter() - t0) / len(batch)
        print(f"  {label:40s} alone {one * 1e3:8.1f} ms, in a batch of 50 {many * 1e3:6.1f} ms each")


if __name__ == "__main__":
    main()
