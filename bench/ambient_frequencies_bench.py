"""Frequency calibration on an ambient record, timed by hand: ``python bench/ambient_frequencies_bench.py``.

The ambient S17 case: ten accelerometers, three random loads band-limited to 300 Hz (600, 425 and
300 N RMS), 60 s at 1024 Hz, a filter model 5 % too stiff and a Matérn-1/2 prior of 500 N and
5 ms.  For the loads held over each step (``load_hold = "zero"``) and continuous ones
(``"linear"``, in the simulation and in the filter), it runs ``akf calibrate`` with
``calibrate = ["frequencies"]`` as a user would (a new process, the whole command timed) and
prints, per mode 1-4 and for the other modes' common factor, the error against the truth (%)
and in robust standard errors, with the command's and the fit's seconds.  It writes
``bench/ambient_frequencies_results.csv`` (``--csv PATH``).

Options: ``--duration SECONDS`` (default 60), ``--holds zero linear``.
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
TRUTH = 1 / np.sqrt(1.05)      # the truth's frequencies against the 5 % stiff filter model's


def ambient_job(hold, duration):
    """The job file's contents (a dict) of the ambient case with loads held ``hold``."""
    from akf.examples import example_job

    data = example_job("s17-acc")
    data["name"] = f"ambient-{hold}"
    data["dt"] = 1 / 1024
    data["forces"] = ["4:y", "6:y", "12:y"]
    data["filter"] |= {"stiffness_factor": 1.05, "force_model": "matern12", "force_std": 500.0,
                       "force_timescale": 5e-3, "smooth": False, "calibrate": ["frequencies"], "load_hold": hold}
    data["simulation"] |= {"duration": duration, "load_hold": hold}
    data["simulation"]["loads"] = [{"components": [{"type": "band_noise", "rms": rms, "f_high": 300.0, "seed": s}]}
                                   for rms, s in ((600.0, 21), (425.0, 22), (300.0, 23))]
    data["output"] = {"strains": []}
    return data


def run(hold, duration, folder):
    """One ``akf calibrate`` in a new process: its report and the command's wall time (s)."""
    import tomlkit

    path = os.path.join(folder, f"ambient-{hold}.toml")
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(tomlkit.dumps(ambient_job(hold, duration)))
    out = os.path.join(folder, f"out-{hold}")
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "akf", "-q", "calibrate", path, "--out", out, "--json"],
                          capture_output=True, text=True, check=True)
    return json.loads(done.stdout)["calibration"], time.perf_counter() - t0


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--csv", default=os.path.join(HERE, "ambient_frequencies_results.csv"))
    parser.add_argument("--duration", type=float, default=60.0)
    parser.add_argument("--holds", nargs="+", default=["zero", "linear"])
    args = parser.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for hold in args.holds:
            report, wall = run(hold, args.duration, folder)
            errors = report["robust_std_errors"]
            for name, factor in report["multipliers"].items():
                if not name.startswith("frequencies:"):
                    continue
                rows.append({"hold": hold, "parameter": name, "error_percent": 100 * (factor / TRUTH - 1),
                             "robust_errors": float(np.log(factor / TRUTH) / errors[name]),
                             "command_s": wall, "fit_s": report["seconds"], "filters": report["evaluations"],
                             "warnings": len(report["warnings"])})
            # print as soon as a record is done: a later one cannot lose it
            print(f"{hold:>6s}: {wall:.1f} s for the command ({report['seconds']:.1f} s fit, {report['evaluations']} "
                  f"filters, {len(report['warnings'])} warnings)")
            for r in rows:
                if r["hold"] == hold:
                    print(f"        {r['parameter']:18s} {r['error_percent']:+8.4f} %  {r['robust_errors']:+6.1f} robust "
                          "errors")
    write_rows(args.csv, rows)
    print(f"wrote {args.csv}")


if __name__ == "__main__":
    main()
