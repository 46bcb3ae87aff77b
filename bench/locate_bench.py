"""Impact identification benchmark (run by hand: python bench/locate_bench.py).

The whole identification -- role-split scan over every candidate location, covariance GA,
force reconstruction -- for the IMP truss (case 1, 35 splits x 16 locations) and the IMP plate
(35 splits x 30 locations), on 1 and 2 joblib workers.  Targets on a 2-core machine: truss
<= 10 s, plate <= 30 s.  IMP reports about 20 minutes per identification (MATLAB, Xeon
E5-2630 v3).  Also: the scan on the plate with the full filter model against the
static-corrected reduced one.
"""
import os
import time

os.environ.setdefault("PYTHONWARNINGS", "ignore")

from akf.examples.impact import example_scenario  # noqa: E402
from impactloc import candidate_locations, default_covariances, locate, role_splits, scan  # noqa: E402

PAPER_SECONDS = 20 * 60


def run(name, n_jobs):
    sc = example_scenario(name)
    t0 = time.perf_counter()
    res = locate(sc.structure, sc.sensors, sc.measurements, sc.dt, n_ad=sc.n_ad, ad_kinds=sc.ad_kinds,
                 direction=sc.direction, n_jobs=n_jobs)
    wall = time.perf_counter() - t0
    assert res.identified[0] == sc.impact[0]
    return wall, res


def main():
    print(f"{'example':18s} {'workers':>7s} {'scan':>7s} {'tuning':>7s} {'recon':>7s} {'total':>7s}  "
          f"{'filters':>7s}  vs IMP's 20 min")
    for name in ("imp-truss-case1", "imp-plate"):
        for n_jobs in (1, 2):
            run(name, n_jobs)  # warm-up: worker start-up, imports
            wall, res = run(name, n_jobs)
            s = res.seconds
            n_filters = len(res.scan.splits) * len(res.scan.locations)
            print(f"{name:18s} {n_jobs:7d} {s['scan']:7.2f} {s['tuning']:7.2f} {s['reconstruction']:7.2f} "
                  f"{wall:7.2f}  {n_filters:7d}  {PAPER_SECONDS / wall:6.0f}x faster")
    sc = example_scenario("imp-plate")
    splits = role_splits(sc.sensors, 4, "strain")
    cov = default_covariances(sc.sensors, sc.measurements)
    cands = candidate_locations(sc.structure, "w")
    for label, n_modes in (("full model (90 modes, 181 states)", None), ("auto: 30 modes + static correction", "auto")):
        t0 = time.perf_counter()
        r = scan(sc.structure, sc.sensors, sc.measurements, sc.dt, splits, candidates=cands, covariances=cov,
                 n_modes=n_modes)
        print(f"plate scan, {label:36s} {time.perf_counter() - t0:6.2f} s, identified node {r.identified[0]}, "
              f"margin {r.margin:.1f}")


if __name__ == "__main__":
    main()
