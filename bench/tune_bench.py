"""Covariance tuning of impact identification, GA against maximum likelihood (run by hand:
``python bench/tune_bench.py [--csv PATH]``).

On the built-in IMP cases (truss cases 1 and 2, the plate), with the two noise settings of the
examples (1 µε and 1 mg absolute; 10 % of each channel's RMS) and three noise seeds each, the
whole identification (:func:`impactloc.locate`) runs with ``tune="ga"`` (the paper's GA, the
default) and with ``tune="ml"`` (:func:`impactloc.tune_covariances_ml`).  It prints and writes
(default ``bench/tune_results.csv``) per run: the identified node against the truth, the peak
force error (%), the RMS error of the whole force history (N) against the assumed covariances',
the AD error after tuning, and the tuning time.  Times are single runs on a shared machine.
"""
from __future__ import annotations

import argparse
import csv
import os
import time

import numpy as np

os.environ.setdefault("PYTHONWARNINGS", "ignore")

HERE = os.path.dirname(os.path.abspath(__file__))
CASES = ("imp-truss-case1", "imp-truss-case2", "imp-plate")


def run(name, noise, seed, tune):
    from akf.examples.impact import example_scenario
    from impactloc import locate

    sc = example_scenario(name, noise=noise, seed=seed)
    t0 = time.perf_counter()
    res = locate(sc.structure, sc.sensors, sc.measurements, sc.dt, n_ad=sc.n_ad, ad_kinds=sc.ad_kinds,
                 direction=sc.direction, tune=tune, seed=seed, **sc.options)
    wall = time.perf_counter() - t0
    true_peak = sc.true_force[np.argmax(np.abs(sc.true_force))]
    force = res.reconstruction.force
    return {"case": name, "noise": noise, "seed": seed, "tune": tune, "identified": res.identified[0],
            "true_node": sc.impact[0], "peak_error_pct": 100 * (res.reconstruction.summary.peak - true_peak) / true_peak,
            "force_rms_error": float(np.sqrt(np.mean((force - sc.true_force) ** 2))),
            "force_rms_error_assumed": float(np.sqrt(np.mean((res.initial.force - sc.true_force) ** 2))),
            "ad_error_after": res.tuning.tuned_error, "tuning_s": res.seconds["tuning"], "total_s": wall}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--csv", default=os.path.join(HERE, "tune_results.csv"))
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args(argv)
    rows = []
    print(f"{'case':16s} {'noise':6s} seed tune  node  peak err %  force RMS (assumed)  AD after  tuning s")
    for name in CASES:
        for noise in ("abs", "rel10"):
            for seed in range(args.seeds):
                for tune in ("ga", "ml"):
                    r = run(name, noise, seed, tune)
                    rows.append(r)
                    print(f"{name:16s} {noise:6s} {seed:4d} {tune:4s} {r['identified']:3d}/{r['true_node']:<3d}"
                          f" {r['peak_error_pct']:9.2f}  {r['force_rms_error']:8.2f} ({r['force_rms_error_assumed']:8.2f})"
                          f"  {r['ad_error_after']:8.4f}  {r['tuning_s']:7.2f}")
    with open(args.csv, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print("\nmean over the seeds:")
    print(f"{'case':16s} {'noise':6s} tune  located  |peak err| %  force RMS N  tuning s")
    for name in CASES:
        for noise in ("abs", "rel10"):
            for tune in ("ga", "ml"):
                sel = [r for r in rows if r["case"] == name and r["noise"] == noise and r["tune"] == tune]
                print(f"{name:16s} {noise:6s} {tune:4s}  {sum(r['identified'] == r['true_node'] for r in sel)}/{len(sel)}"
                      f"      {np.mean([abs(r['peak_error_pct']) for r in sel]):8.2f}  "
                      f"{np.mean([r['force_rms_error'] for r in sel]):10.2f}  {np.mean([r['tuning_s'] for r in sel]):7.2f}")


if __name__ == "__main__":
    main()
