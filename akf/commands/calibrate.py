"""``akf calibrate``: learn a job's ``[filter] calibrate`` keys from its record by maximum
likelihood, print the fit and write ``calibrated.toml``: the job with the fitted values (its
comments and layout kept), to estimate day after day without calibrating again."""
from __future__ import annotations

import json
import os
import sys

from core_akf.checks import AKFInputError

from ..outputs import OutputFolder
from .common import add_print_job, print_written


def _calibrate(args):
    from ..calibrating import calibrate_job, calibration_record
    from ..examples import example_path
    from ..job import Job
    from .common import job_data, listing_or_template

    done = listing_or_template(args, "estimate")
    if done is not None:
        return done
    data = job_data(args, "estimate")
    overrides = {"filter.calibrate": args.parameters} if args.parameters else {}
    job = Job.from_dict(data, "estimate", source=args.job, overrides=overrides)
    if not job.calibrate:
        raise AKFInputError("nothing to calibrate: list the [filter] keys to learn in [filter] calibrate = "
                            "[\"stiffness_factor\", ...] or give --parameters")
    out = args.out or os.path.join("akf-out", job.name)
    with OutputFolder(out, "--out"):
        sim = record = None
        if job.spec.measurements is not None:
            record = job.open_record()
            Y = calibration_record(job, record)
            noise_cov = job.noise_cov()
        else:
            sim = job.simulate()
            Y = sim.measurements
            noise_cov = job.noise_cov(sim)
        *_, report = calibrate_job(job, job.filter_model(), job.sensors, job.forces, Y, noise_cov)
        path = os.path.join(out, "calibrated.toml")
        source = args.job or example_path(args.example)
        write_calibrated(source, report, path)
    if args.json:
        print(json.dumps({"name": job.name, "calibration": report, "files": {"calibrated_job": path}}))
        for w in report["warnings"]:
            print(f"akf: warning: {w}", file=sys.stderr)
        return 0
    print(f"{job.name}: calibrated {', '.join(job.calibrate)} on {report['record_steps']} steps "
          f"({report['seconds']:.2f} s, {report['evaluations']} filters)")
    print(f"  log-likelihood: {report['loglik_before']:.8g} -> {report['loglik_after']:.8g}")
    print("  parameter                 factor     std error (relative)")
    for name, factor in report["multipliers"].items():
        print(f"    {name:22s} {factor:10.5g}   {report['std_errors'][name]:10.3g}")
    if "stiffness_factor" in report:
        print(f"  stiffness_factor = {report['stiffness_factor']:.6g} (relative to [structure])")
    if "frequency_factors" in report:
        print("  frequency_factors = [" + ", ".join(f"{f:.5g}" for f in report["frequency_factors"]) + "] ("
              + ", ".join(f"{f:.4g}" for f in report["frequencies_hz"]) + " Hz)")
    print("  consistency (innovation / predicted; ~1 is good):      before     after")
    for channel, before in report["consistency_before"].items():
        print(f"    {channel:>14s}                                  {before:8.3g}  {report['consistency_after'][channel]:8.3g}")
    for w in report["warnings"]:
        print(f"  WARNING: {w}")
    print_written({"calibrated_job": path})
    return 0


#: the [filter] keys akf calibrate writes (and the ones it removes: the fit is done)
WRITTEN = ("stiffness_factor", "frequency_factors", "noise_cov", "force_increment_cov", "model_error_cov", "force_std",
           "force_timescale")


def write_calibrated(source, report, path):
    """Write the job file ``source`` with the fitted ``[filter]`` values of ``report`` (and without
    ``calibrate``, ``calibrate_window`` and ``calibrate_modes``) to ``path``; comments and layout
    are kept (tomlkit)."""
    import tomlkit

    from core_akf.outputs import atomic_path

    with open(source, encoding="utf-8-sig") as fh:
        doc = tomlkit.parse(fh.read())
    if "filter" not in doc:
        doc["filter"] = tomlkit.table()
    table = doc["filter"]
    for key in ("calibrate", "calibrate_window", "calibrate_modes"):
        if key in table:
            del table[key]
    for key in WRITTEN:
        if key in report:
            table[key] = report[key]
    if "damping" in report:            # the model's own damping: [structure] of a job on measured data
        if "measurements" in doc and "structure" in doc:
            doc["structure"]["damping"] = report["damping"]
        else:
            table.add(tomlkit.comment(f"fitted modal damping ratio {report['damping']}: not written into [structure], "
                                      "which also makes the simulated truth"))
    table.add(tomlkit.comment(f"fitted by akf calibrate: log-likelihood {report['loglik_before']:.8g} -> "
                              f"{report['loglik_after']:.8g}"))
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(tomlkit.dumps(doc))
    return path


def register(sub):
    """Add ``calibrate`` to the ``akf`` sub-command parser."""
    p = sub.add_parser("calibrate", help="learn the filter's model and covariances from a job's record (maximum "
                       "likelihood) and write calibrated.toml")
    p.add_argument("job", nargs="?", help="job file (TOML) of akf estimate")
    p.add_argument("--example", help="built-in estimate example, e.g. s17-case4 (see --list-examples)")
    p.add_argument("--list-examples", action="store_true", help="list the built-in examples")
    p.add_argument("--parameters", nargs="+", metavar="KEY", help="the [filter] keys to learn (instead of [filter] "
                   "calibrate): stiffness_factor, frequencies, damping, noise_cov (noise_cov:<kind>, noise_cov:channels), "
                   "force_increment_cov, model_error_cov; force_std, force_timescale (a Matérn force_model)")
    p.add_argument("--out", help="output folder (default akf-out/NAME)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    add_print_job(p)
    p.set_defaults(func=_calibrate)
