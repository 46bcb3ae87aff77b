"""Force models compared, run by hand: ``python bench/force_model_bench.py [--csv PATH] [--quick]``.

Per sensor set -- S17 cases 1, 2 and 4, the accelerometer-only truss job ``s17-acc``, an
accelerometer-only TH plate and the footbridge walk -- the force and strain errors of:

* ``random_walk``: the job's random walk (time-varying, ``allow_undetectable``, where the set is
  not detectable: the papers' cases 1 and 2); ``random_walk_smooth``: the same, smoothed, where
  the set is detectable;
* ``dummy``: the random walk with zero displacement pseudo-measurements at the force DOFs, their
  variance the likeliest of the record (the highest log-likelihood over 10^-2..10^4 times the
  square of the static displacement of a load of the loads' RMS);
* ``matern32_ml``: the Matérn-3/2 Gaussian-process force model with std and time scale learnt by
  maximum likelihood (``calibrate = ["force_std", "force_timescale"]``, starting at 300 N and
  10 ms), filtered; ``matern32_ml_smooth``: the same, smoothed;
* ``matern32_hand``: Matérn-3/2 with the std of the loads' RMS and a time scale of a quarter
  period of the highest load frequency, smoothed;
* ``butterworth_ml_smooth``: the Butterworth model (order 4) with std and band learnt by maximum
  likelihood (``calibrate = ["force_std", "force_band"]``, starting at 300 N and 0-300 Hz, capped
  below Nyquist), smoothed.

Every set runs three times, the ``hold`` column giving the loads' hold and the filter's:
``zero/zero``, loads held over each step (``[simulation] load_hold = "zero"``, as the filter
assumes by default and as the published numbers were made); ``linear/zero``, loads going linearly
from sample to sample (a continuous load) under the same filter; ``linear/linear``, continuous
loads and a filter that assumes them (``[filter] load_hold = "linear"``).

Written per row: the mean RMS force error (N) and relative to the loads' mean RMS, the average strain
error (µε), the drift (the force error RMS of the last quarter of the record over that of the
second quarter; > 1.5 drifts), the fitted hyperparameters (the time scale in ms, or a Butterworth
band's top in Hz) and the seconds.  Prints first, then
writes ``bench/force_model_results.csv``.
"""
from __future__ import annotations

import argparse
import copy
import csv
import os
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
#: the columns of the CSV (a row of a method that cannot run has set, method and error only)
FIELDS = ("set", "hold", "method", "force_error_N", "force_error_rel", "strain_error_microstrain", "drift", "force_std_N",
          "force_timescale_ms", "seconds", "loads_rms_N", "error")
PLATE_ACC = ["acc:111:w", "acc:116:w", "acc:121:w", "acc:100:w", "acc:89:w", "acc:60:w"]


def _jobs(quick):
    """(name, job dict, the highest load frequency in Hz) of each sensor set."""
    from akf.examples import example_job
    from core_akf.defaults import auto_modes
    from core_akf.models import th_plate

    out = []
    for name in ("s17-case1", "s17-case2", "s17-case4", "s17-acc"):
        out.append((name, example_job(name), 200.0))
    plate = example_job("th-case3")
    plate["name"], plate["sensors"] = "th-acc", PLATE_ACC
    plate["simulation"]["duration"] = 1.0
    plate["simulation"]["loads"] = [{"components": [{"type": "band_noise", "rms": 20.0, "f_high": 100.0, "seed": 31}]},
                                    {"components": [{"type": "band_noise", "rms": 15.0, "f_high": 100.0, "seed": 32}]}]
    plate["filter"]["stiffness_factor"] = 1.0
    # the filter keeps the modes below 10x the sampling rate (core_akf.defaults.auto_modes, as akf locate does),
    # with a static correction: the Mindlin plate's shear modes above 100 kHz only add round-off
    plate["filter"]["n_modes"] = auto_modes(th_plate(), plate["dt"], accelerations=True)
    out.append(("th-acc (plate, 6 acc)", plate, 100.0))
    out.append(("footbridge-walk", example_job("footbridge-walk"), 6.0))
    if quick:
        for _, data, _ in out:
            data["simulation"]["duration"] = min(data["simulation"]["duration"], 0.5 if data["dt"] < 1e-3 else 5.0)
    return out


def _likeliest_dummy(job, sim, disp, static_std):
    """The dummies' standard deviation of the highest log-likelihood of the record (steady filters)."""
    from core_akf import DummyMeasurements, estimate

    best = (-np.inf, static_std)
    for factor in 10.0 ** np.arange(-1.0, 2.01, 0.5):
        std = static_std * factor
        est = estimate(job.filter_model(), job.sensors, job.forces, sim.measurements, job.dt,
                       model_error_cov=job.model_error_cov, force_model=job.force_model, noise_cov=job.noise_cov(sim),
                       dummy=DummyMeasurements(disp, std ** 2))
        best = max(best, (est.loglik, std))
    return best[1]


def _filter_keys(data, method, loads_rms, f_high, static_std):
    f = data["filter"]
    for key in ("force_increment_cov", "steady", "allow_undetectable", "smooth", "force_model", "force_std",
                "force_timescale", "calibrate", "dummy"):
        f.pop(key, None)
    if method.startswith("random_walk") or method == "dummy":
        f["force_increment_cov"] = data["_S"]
        f["smooth"] = method == "random_walk_smooth"
        if method == "dummy":
            f["dummy"] = {"sensors": data["_dummy"], "variance": float(static_std ** 2)}
        return
    f["force_model"] = "matern32"
    if method.startswith("matern32_ml"):
        f.update(force_std=300.0, force_timescale=0.01, calibrate=["force_std", "force_timescale"])
    else:
        f.update(force_std=float(np.mean(loads_rms)), force_timescale=float(0.25 / f_high))
    f["smooth"] = method.endswith("smooth") or method == "matern32_hand"
    if method.startswith("butterworth"):
        f.pop("force_timescale")
        f.update(force_model="butterworth", force_std=300.0, force_band=[0.0, min(300.0, 0.4 / data["dt"])],
                 calibrate=["force_std", "force_band"])


def main(argv=None):
    from akf.estimate import estimate_job
    from akf.job import Job
    from core_akf.statespace import detectability, static_gain

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--csv", default=os.path.join(HERE, "force_model_results.csv"))
    parser.add_argument("--quick", action="store_true", help="short records (a smoke run)")
    args = parser.parse_args(argv)
    methods = ("random_walk", "random_walk_smooth", "dummy", "matern32_ml", "matern32_ml_smooth", "matern32_hand",
               "butterworth_ml_smooth")
    rows = []
    print(f"{'sensor set':24s} {'hold':13s} {'method':21s} {'force err N':>11s} {'x RMS':>7s} {'strain µε':>10s} {'drift':>6s} "
          f"{'std N':>8s} {'scale ms':>8s} {'s':>6s}")
    holds = (("zero", "zero"), ("linear", "zero"), ("linear", "linear"))
    for (name, base, f_high), (load_hold, filter_hold) in ((j, h) for j in _jobs(args.quick) for h in holds):
        hold = f"{load_hold}/{filter_hold}"
        base = copy.deepcopy(base)
        base["simulation"]["load_hold"] = load_hold
        base["filter"]["load_hold"] = filter_hold           # the jobs' random walk: the dummies' filter
        job0 = Job.from_dict(base, "estimate")
        sim = job0.simulate()
        loads_rms = np.sqrt(np.mean(sim.loads ** 2, axis=0))
        model = job0.structure
        disp = [f"disp:{node}:{d}" for node, d in job0.forces]
        # the static displacement at each force DOF of a load of the loads' RMS: the dummies' std
        gain = static_gain(model, disp, job0.forces).gain
        static_std = float(np.mean(np.abs(np.diag(gain)) * loads_rms))
        static_std = _likeliest_dummy(job0, sim, disp, static_std)
        base = copy.deepcopy(base)
        base["_S"] = float(base["filter"].get("force_increment_cov", job0.force_increment_cov))
        base["_dummy"] = disp
        for method in methods:
            data = copy.deepcopy(base)
            _filter_keys(data, method, loads_rms, f_high, static_std)
            data.pop("_S"), data.pop("_dummy")
            if method.startswith("random_walk") and not detectability(model, job0.sensors, job0.forces).detectable:
                if method == "random_walk_smooth":
                    rows.append(dict(set=name, hold=hold, method=method, error="not detectable"))
                    print(f"{name:24s} {hold:13s} {method:21s} not detectable")
                    continue
                data["filter"].update(steady=False, allow_undetectable=True)
            t = time.perf_counter()
            try:
                res = estimate_job(Job.from_dict(data, "estimate"))
            except Exception as exc:            # a method that cannot run on a set is a row, not a lost table
                print(f"{name:24s} {hold:13s} {method:21s} failed: {exc}")
                rows.append(dict(set=name, hold=hold, method=method, error=str(exc).splitlines()[0]))
                continue
            seconds = time.perf_counter() - t
            est, true = res.estimate.forces, sim.loads
            e = est - true
            q = e.shape[0] // 4
            drift = float(np.max(np.sqrt(np.mean(e[3 * q:] ** 2, 0)) / np.sqrt(np.mean(e[q:2 * q] ** 2, 0))))
            force_err = float(np.mean(list(res.metrics["rms_force"].values())))
            rel = force_err / float(np.mean(loads_rms))
            strain = float(res.metrics["avg_strain_error_microstrain"])
            cal = res.metrics.get("calibration", {})
            std = np.mean(cal.get("force_std", data["filter"].get("force_std", np.nan)))
            scale = 1e3 * np.mean(cal.get("force_timescale", data["filter"].get("force_timescale", np.nan)))
            if "force_band" in data["filter"]:           # a Butterworth model: the band's top instead (Hz)
                scale = float(np.max(cal.get("force_band", data["filter"]["force_band"])))
            print(f"{name:24s} {hold:13s} {method:21s} {force_err:11.4g} {rel:7.3f} {strain:10.4g} {drift:6.2f} {std:8.4g} "
                  f"{scale:8.3g} {seconds:6.1f}", flush=True)
            rows.append(dict(set=name, hold=hold, method=method, force_error_N=force_err, force_error_rel=rel,
                             strain_error_microstrain=strain, drift=drift, force_std_N=std, force_timescale_ms=scale,
                             seconds=seconds, loads_rms_N=float(np.mean(loads_rms)), error=""))
    with open(args.csv, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=FIELDS)
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {args.csv}")


if __name__ == "__main__":
    main()
