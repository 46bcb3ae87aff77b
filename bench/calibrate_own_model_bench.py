"""Calibrating a model of one's own, timed by hand: ``python bench/calibrate_own_model_bench.py [--seconds 60]``.

Issue 34's case, as a new user meets it: a 3-D truss of 147 DOFs (the footbridge generator with 12
panels) exported as Matrix Market files with a DOF map and node coordinates, a measured record of
60 s at 512 Hz (CSV, ten accelerometers, two band-limited loads of 300 and 200 N RMS to 100 Hz,
2 % noise) made by the true truss, and a job whose filter starts 3 % too stiff with
``calibrate = ["stiffness_factor", "noise_cov"]`` under a Matérn-1/2 prior.

1. ``akf calibrate job.toml`` in a fresh process, timed whole (read, model, window rule, OMA-free
   fit on the band-reduced filter, curvature, written job): the stiffness factor, the window and
   the filter's modes it reports.
2. The same fit in this process on the full 147-mode filter over the same window
   (``core_akf.calibration.calibrate`` with ``n_modes=None``): the reference the reduced fit must
   match within 0.1 %.

Targets (issue 34): step 1 <= 60 s on the 2-core machine, the stiffness within 0.1 % of step 2's.
Prints a table, then writes ``bench/calibrate_own_model_results.csv``.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from run_all import write_rows  # noqa: E402  (bench/ is the script's folder)

HERE = os.path.dirname(os.path.abspath(__file__))
DT = 1 / 512
START = 1.03
SENSORS = [f"acc:{n}:z" for n in (5, 9, 14, 18, 22, 27, 31, 35, 40, 44)] + ["acc:22:y", "acc:27:y"]
FORCES = ["17:z", "33:z"]
TARGET_S, TARGET_REL = 60.0, 1e-3


def write_case(folder, seconds):
    """The truss' files, the record and the job in ``folder``; returns the job's path."""
    import pandas as pd
    import scipy.io

    from core_akf import simulate
    from core_akf.loads import band_limited_white_noise
    from core_akf.models import footbridge_matrices, from_matrices

    parts = footbridge_matrices(n_panels=12)
    fixed = set(parts["fixed"])
    rows = np.array([r for r, d in enumerate(parts["dofs"]) if d not in fixed])
    for key in ("K", "M"):
        scipy.io.mmwrite(os.path.join(folder, f"{key}.mtx"), parts[key][rows][:, rows].tocoo(), symmetry="symmetric")
    with open(os.path.join(folder, "dofs.csv"), "w") as fh:
        fh.write("node,direction\n")
        fh.writelines(f"{parts['dofs'][r][0]},{parts['dofs'][r][1]}\n" for r in rows)
    with open(os.path.join(folder, "nodes.csv"), "w") as fh:
        fh.write("node,x,y,z\n")
        fh.writelines(f"{k},{x!r},{y!r},{z!r}\n" for k, (x, y, z) in parts["nodes"].items())
    truss = from_matrices(parts["K"][rows][:, rows], parts["M"][rows][:, rows], [parts["dofs"][r] for r in rows],
                          parts["nodes"], damping=0.005)
    n = int(round(seconds / DT))
    loads = np.column_stack([band_limited_white_noise(n, DT, r, 0, 100, seed=3 + j) for j, r in enumerate((300.0, 200.0))])
    sim = simulate(truss, SENSORS[:10], FORCES, loads, DT, relative_noise=0.02, seed=1)
    frame = pd.DataFrame(sim.measurements, columns=SENSORS[:10])
    frame.insert(0, "time", np.arange(n) * DT)
    frame.to_csv(os.path.join(folder, "rec.csv"), index=False, float_format="%.10g")
    noise = {s: float(v) ** 2 for s, v in zip(SENSORS[:10], sim.noise_std)}
    job = f"""name = "own-truss"
dt = {DT!r}
sensors = {json.dumps(SENSORS[:10])}
forces = {json.dumps(FORCES)}

[structure]
model = "matrices"
K = "K.mtx"
M = "M.mtx"
dofs = "dofs.csv"
nodes = "nodes.csv"
damping = 0.005

[filter]
stiffness_factor = {START}
model_error_cov = 1e-16
force_model = "matern12"
force_std = 300.0
force_timescale = 0.005
noise_cov = [{", ".join(repr(noise[s]) for s in SENSORS[:10])}]
calibrate = ["stiffness_factor", "noise_cov"]

[measurements]
file = "rec.csv"
"""
    path = os.path.join(folder, "job.toml")
    with open(path, "w") as fh:
        fh.write(job)
    return path, truss, noise


def main(argv=None):
    from akf.calibrating import calibration_record
    from akf.job import load_job
    from core_akf.calibration import calibrate

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--csv", default=os.path.join(HERE, "calibrate_own_model_results.csv"))
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        path, truss, noise = write_case(folder, args.seconds)
        t0 = time.perf_counter()
        run = subprocess.run([sys.executable, "-m", "akf", "-q", "calibrate", path, "--out", os.path.join(folder, "out"),
                              "--json"], capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if run.returncode:
            sys.exit(f"akf calibrate failed ({run.returncode}):\n{run.stderr}")
        report = json.loads(run.stdout)["calibration"]
        job = load_job(path, "estimate")
        model = job.filter_model()
        Y = calibration_record(job, job.open_record(), model)
        t1 = time.perf_counter()
        full = calibrate(model, job.sensors, job.forces, Y, job.dt, parameters=job.calibrate,
                         model_error_cov=job.model_error_cov, force_model=job.force_model, noise_cov=job.noise_cov())
        full_s = time.perf_counter() - t1
    reduced_k, full_k = report["stiffness_factor"], START * full.values["stiffness_factor"]
    rows = [{"what": "akf calibrate (band-reduced filter), whole command", "seconds": wall, "stiffness_factor": reduced_k,
             "filter_modes": report.get("filter_modes"), "window_steps": report["record_steps"],
             "noise_cov_acc_factor": report["multipliers"].get("noise_cov:acc")},
            {"what": "calibrate on the full filter, same window", "seconds": full_s, "stiffness_factor": full_k,
             "filter_modes": truss.n, "window_steps": int(Y.shape[0]),
             "noise_cov_acc_factor": full.multipliers.get("noise_cov:acc")}]
    print(f"{'what':52s} {'s':>7s} {'stiffness':>10s} {'modes':>6s} {'window':>7s} {'R acc':>7s}")
    for r in rows:
        print(f"{r['what']:52s} {r['seconds']:7.1f} {r['stiffness_factor']:10.6f} {r['filter_modes']!s:>6s} "
              f"{r['window_steps']:7d} {r['noise_cov_acc_factor']:7.3f}")
    rel = abs(reduced_k - full_k) / full_k
    print(f"window: {report['window']}")
    print(f"stiffness: reduced against full {rel:.2e} (target <= {TARGET_REL:g}: {'met' if rel <= TARGET_REL else 'NOT met'}); "
          f"whole command {wall:.1f} s (target <= {TARGET_S:g} s: {'met' if wall <= TARGET_S else 'NOT met'}); "
          f"full filter {full_s:.1f} s ({full_s / wall:.1f}x)")
    write_rows(args.csv, rows)


if __name__ == "__main__":
    main()
