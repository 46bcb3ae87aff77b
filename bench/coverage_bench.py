"""Do the calibration's standard errors cover the truth?  ``python bench/coverage_bench.py [--seeds 20] [--csv PATH]``

Over many seeds (records with new loads and new noise), each fit's 90 % interval
``log(factor) +- 1.645 se`` either holds the true factor or not.  For each parameter the table gives
the share of seeds whose interval holds it with the observed-information standard errors and with
the robust (sandwich) ones, the median ratio of the two errors, and the median error of the fit in
standard errors (z, robust), and the share of seeds where a warning names the parameter as
leaning on a covariance level the fit held (``held_levels``: learning it would move the parameter
by more than ``HELD_MOVE`` robust errors) and where it is covered or so named.  Scenarios (all on the S17 truss):

1. ``case4``: the S17 case-4 job (9 channels, 4 forces, 2 s at 4096 Hz, the filter 5 % stiff): its
   loads (band noise, a pulse, a half sine, a ramp) with the seeds changed; ``stiffness_factor`` and
   ``noise_cov`` (per kind) from the random-walk prior of the job.  The loads are not a random walk.
2. ``case4-rw``: the same, with loads drawn from the filter's own random-walk prior (S = 1e5 N^2).
3. ``case4-q``: case 4 with ``model_error_cov = 1e-22`` instead of the job's 1e-16.  The truth has no
   model error, and 1e-16 m^2 on the displacements is seen by the accelerometers: with it, the
   horizontal accelerometer's innovations are half their predicted variance even under the true
   model, so ``noise_cov:acc`` fits a value the truth does not have.
4. ``case4-learn-q``: case 4 with ``model_error_cov`` learnt as well (from the job's 1e-16; it
   goes below 1e-19, its search reaching six decades down).
   ``case4-held-learn``: case 4 with ``calibrate_held = "learn"``: the levels the record rejects
   and a fitted parameter leans on (here Q and the random walk's S) learnt in a refit.
5. ``acc-matern``: five accelerometers, two loads drawn from a Matérn-3/2 process (500 N, 4 ms),
   ``force_std`` and ``force_timescale`` from 250 N and 8 ms.
6. ``acc-band``: the same job with band-limited loads (600 and 425 N RMS, 0-120 Hz) under the same
   Matérn-3/2 prior; the "true" std is the loads' RMS, and no Matérn time scale is true.
7. ``acc-band-bw``: the same loads under a Butterworth prior of order 4 (``force_std`` and
   ``force_band`` from 250 N and 0-300 Hz), whose std is the loads' RMS (no order-4 corner is the
   loads' brick wall at 120 Hz: the band has no true value).

Writes ``bench/coverage_results.csv`` (default) with a row per scenario and parameter.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np
from run_all import write_rows  # noqa: E402  (bench/ is the script's folder)

HERE = os.path.dirname(os.path.abspath(__file__))
Z90 = 1.6448536269514722
ACC = ["acc:4:y", "acc:6:y", "acc:8:y", "acc:12:y", "acc:6:x"]


def _case4(seed, random_walk, model_error_cov=None, learn_q=False, held="warn"):
    from akf.calibrating import calibrate_job
    from akf.examples import example_job
    from akf.job import Job

    data = example_job("s17-case4")
    data["simulation"]["seed"] = seed
    for load in data["simulation"]["loads"]:
        for c in load["components"]:
            if "seed" in c:
                c["seed"] = 100 * seed + c["seed"]
    data["filter"]["calibrate"] = ["stiffness_factor", "noise_cov"] + (["model_error_cov"] if learn_q else [])
    if model_error_cov is not None:
        data["filter"]["model_error_cov"] = model_error_cov
    data["filter"]["calibrate_held"] = held
    job = Job.from_dict(data, "estimate")
    if random_walk:
        from core_akf import simulate

        rng = np.random.default_rng(1000 + seed)
        n_steps = int(round(data["simulation"]["duration"] / job.dt))
        loads = np.cumsum(rng.normal(0.0, np.sqrt(job.force_increment_cov), (n_steps, len(job.forces))), axis=0)
        sim = simulate(job.structure, job.sensors, job.forces, loads, job.dt, relative_noise=0.02, seed=seed)
    else:
        sim = job.simulate()
    *_, report = calibrate_job(job, job.filter_model(), job.sensors, job.forces, sim.measurements, job.noise_cov(sim))
    truth = {"stiffness_factor": 1 / 1.05, "noise_cov:acc": 1.0, "noise_cov:strain": 1.0}
    return report, truth


def _acc_only(seed, matern, butterworth=False):
    from core_akf import simulate
    from core_akf.calibration import calibrate
    from core_akf.forcemodels import ForceModel
    from core_akf.loads import band_limited_white_noise
    from core_akf.models import s17_truss

    dt, n_steps, forces = 1 / 2048, 4096, ["6:y", "12:y"]
    if matern:
        true = ForceModel("matern32", std=500.0, timescale=4e-3)
        loads = true.sample(n_steps, dt, len(forces), seed)
        truth = {"force_std": 1.0 / 0.5, "force_timescale": 4e-3 / 8e-3}
    else:
        loads = np.column_stack([band_limited_white_noise(n_steps, dt, r, 0, 120, seed=100 * seed + j)
                                 for j, r in enumerate((600.0, 425.0))])
        truth = {"force_std": float(np.sqrt(np.mean(loads ** 2))) / 250.0}
    sim = simulate(s17_truss(), ACC, forces, loads, dt, relative_noise=0.02, seed=seed)
    if butterworth:         # the band's top from 300 Hz; no order-4 corner is the loads' brick wall at 120 Hz
        prior, learnt = ForceModel("butterworth", std=250.0, band=[0.0, 300.0], band_order=4), "force_band"
    else:
        prior, learnt = ForceModel("matern32", std=250.0, timescale=8e-3), "force_timescale"
    fit = calibrate(s17_truss(), ACC, forces, sim.measurements, dt, parameters=["force_std", learnt],
                    model_error_cov=1e-16, noise_cov=np.diag(sim.noise_std ** 2), force_model=prior)
    return fit.to_dict() | {"multipliers": fit.multipliers}, truth


SCENARIOS = {"case4": lambda s: _case4(s, False), "case4-rw": lambda s: _case4(s, True),
             "case4-q": lambda s: _case4(s, False, 1e-22),
             "case4-learn-q": lambda s: _case4(s, False, learn_q=True),
             "case4-held-learn": lambda s: _case4(s, False, held="learn"),
             "acc-matern": lambda s: _acc_only(s, True), "acc-band": lambda s: _acc_only(s, False),
             "acc-band-bw": lambda s: _acc_only(s, False, butterworth=True)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--only", nargs="*", choices=list(SCENARIOS), default=list(SCENARIOS))
    parser.add_argument("--csv", default=os.path.join(HERE, "coverage_results.csv"))
    args = parser.parse_args(argv)
    rows = []
    print(f"{'scenario':11s} {'parameter':18s} {'cover (observed)':>17s} {'cover (robust)':>15s} "
          f"{'robust/observed':>16s} {'median |z| robust':>18s} {'named':>6s} {'covered/named':>14s} {'s/fit':>6s}")
    from core_akf.calibration import HELD_MOVE

    for name in args.only:
        hits = {}
        t0 = time.perf_counter()
        for seed in range(args.seeds):
            report, truth = SCENARIOS[name](seed)
            for p, true in truth.items():
                z = np.log(report["multipliers"][p]) - np.log(true)
                se, rob = report["std_errors"][p], report["robust_std_errors"][p]
                named = any(abs(held["moves"].get(p, 0.0)) > HELD_MOVE for held in report["held_levels"].values())
                hits.setdefault(p, []).append((abs(z) <= Z90 * se, abs(z) <= Z90 * rob, rob / se, abs(z) / rob, named,
                                               named or abs(z) <= Z90 * rob))
        seconds = (time.perf_counter() - t0) / args.seeds
        for p, h in hits.items():
            a = np.array(h, float)
            row = {"scenario": name, "parameter": p, "seeds": args.seeds, "cover_observed": a[:, 0].mean(),
                   "cover_robust": a[:, 1].mean(), "median_ratio": float(np.median(a[:, 2])),
                   "median_abs_z_robust": float(np.median(a[:, 3])), "named": a[:, 4].mean(),
                   "cover_or_named": a[:, 5].mean(), "seconds_per_fit": seconds}
            rows.append(row)
            print(f"{name:11s} {p:18s} {row['cover_observed']:17.0%} {row['cover_robust']:15.0%} "
                  f"{row['median_ratio']:16.3g} {row['median_abs_z_robust']:18.3g} {row['named']:6.0%} "
                  f"{row['cover_or_named']:14.0%} {seconds:6.2f}", flush=True)
    write_rows(args.csv, rows)
    print(f"wrote {args.csv}")


if __name__ == "__main__":
    main()
