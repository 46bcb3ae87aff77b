"""``akf estimate``: estimate forces and strains for a job file or a built-in example."""
from __future__ import annotations

import json
import os
import sys

from core_akf.exceptions import AKFInputError
from core_akf.outputs import write_csv

from ..jobs import load_job
from ..outputs import OutputFolder
from ..writers import draw
from .common import add_print_job, print_job, print_written, seed

#: above this many (channel x step) rows, "all" strain histories are not written to the CSV
_MAX_STRAIN_ROWS = 2_000_000


def _plot(result, path):
    from ..plots import plot_estimate

    est, sim = result.estimate, result.simulation
    return plot_estimate(est.time, est.forces, [f"{n}:{d}" for n, d in est.force_locations], path,
                         result.job.get("name", "AKF estimate"), reference=None if sim is None else sim.loads,
                         strain_errors=result.metrics.get("rms_strain"))


def _plot_sensors(result, path):
    from ..plots import plot_sensors

    est = result.estimate
    return plot_sensors(est.time, est.measurements, est.predicted, est.sensors, path,
                        f"{result.job.get('name', 'AKF estimate')}: measured vs. predicted at the sensors")


def _estimate(args):
    from ..examples import example_job
    from ..jobs import run_job
    from .common import check_job_or_example, print_examples

    if args.list_examples:
        print_examples("estimate")
        return 0
    if args.print_job:
        return print_job(args)
    check_job_or_example(args)
    job = example_job(args.example) if args.example else load_job(args.job, "estimate")
    if args.duration is not None:
        job.setdefault("simulation", {})["duration"] = args.duration
    if args.seed is not None:
        job.setdefault("simulation", {})["seed"] = args.seed
    steady = {"steady": True, "time-varying": False, None: None}[args.filter]
    name = job.get("name", os.path.splitext(os.path.basename(args.job or "job"))[0])
    out = args.out or os.path.join("akf-out", str(name))
    if "measurements" in job:
        if args.duration is not None or args.seed is not None:
            raise AKFInputError("--duration and --seed apply to simulated jobs; this job reads measured data")
        with OutputFolder(out, "--out"):
            return _stream(args, job, name, out, steady)
    if args.resume:
        raise AKFInputError("--resume continues a streamed run of measured data; this job simulates its data")
    with OutputFolder(out, "--out"):      # checked and locked before the work starts
        result = run_job(job, allow_undetectable=args.allow_undetectable or None, steady=steady)
        return _write_estimate(args, job, result, name, out)


def _stream(args, job, name, out, steady):
    """A job with measured data: read, filtered and written chunk by chunk (:mod:`akf.streaming`)."""
    from ..streaming import stream_job

    res = stream_job(job, out, resume=args.resume, overwrite=args.overwrite,
                     allow_undetectable=args.allow_undetectable or None, steady=steady,
                     plot=not args.no_plot, progress=not args.json and sys.stderr.isatty())
    m = res.metrics
    if args.json:
        print(json.dumps({"name": name, "complete": res.complete, "detectable": m.get("detectable"),
                          "n_steps": m.get("n_steps"), "rms_force": None, "avg_strain_error": None,
                          "forces": m.get("forces"), "sensors": m.get("sensors"), "warnings": m.get("warnings", []),
                          "channels": res.channels, "resumed_at_step": res.resumed_at, "units": m.get("units"),
                          "files": res.files, "notes": res.notes}))
        for w in m.get("warnings", []):
            print(f"akf: warning: {w}", file=sys.stderr)
        return 0
    print(f"{name}: {job.get('description', '')}")
    print("  channels: " + "; ".join(res.channels))
    if res.resumed_at:
        print(f"  resumed at step {res.resumed_at}")
    if not res.complete:
        print_written(res.files, res.notes)
        return 0
    print(f"  {len(m['sensors'])} sensors, {len(m['forces'])} unknown forces, {m['n_steps']} steps, "
          f"{'detectable' if m['detectable'] else 'NOT detectable (forced)'}")
    _print_diagnostics(m)
    print_written(res.files, res.notes)
    return 0


def _print_diagnostics(m):
    print("  estimated forces (N):            RMS          peak   at (s)")
    for f in m["forces"]:
        print(f"    {f['channel']:>8s}           {f['rms']:10.4g}   {f['peak']:11.4g}   {f['time_of_peak']:.4f}")
    print("  sensors: measured RMS, innovation RMS (SI), consistency (innovation / predicted; ~1 is good), whiteness")
    for d in m["sensors"]:
        print(f"    {d['channel']:>14s}  {d['measured_rms']:10.4g}  {d['innovation_rms']:10.4g}  {d['consistency']:8.3g}"
              f"  {d['whiteness']:6.2f}")
    for w in m["warnings"]:
        print(f"  WARNING: {w}")


def _write_estimate(args, job, result, name, out):
    files = {}
    import pandas as pd

    frames = [result.force_frame()]
    wanted = job.get("output", {}).get("strains", "all")
    est = result.estimate
    notes = []
    if wanted == "all":
        if est.structure.n_strain * est.forces.shape[0] <= _MAX_STRAIN_ROWS:
            wanted = None
        else:
            wanted = []
            notes.append(f"strain histories not written ({est.structure.n_strain} channels x {est.forces.shape[0]} "
                         "steps); list the channels you want in [output] strains (summary.csv has all RMS errors)")
    if wanted != [] and est.structure.n_strain:
        frames.append(result.strain_frame(wanted))
    files["timeseries"] = os.path.join(out, "timeseries.csv")
    write_csv(pd.concat(frames, ignore_index=True), files["timeseries"])
    files["summary"] = os.path.join(out, "summary.csv")
    write_csv(result.summary_frame(), files["summary"])
    m = result.metrics
    if not args.json:       # the results first, then the figures
        print(f"{name}: {job.get('description', '')}")
        print(f"  {len(est.sensors)} sensors, {len(est.force_locations)} unknown forces, {m['n_steps']} steps, "
              f"{'detectable' if m['detectable'] else 'NOT detectable (forced)'}")
        if "rms_force" in m:
            print("  RMS force error (N):")
            for k, v in m["rms_force"].items():
                print(f"    {k:>8s}  {v:10.2f}")
            if "avg_strain_error" in m:
                print(f"  average strain error: {m['avg_strain_error_microstrain']:.4f} µε over {est.structure.n_strain} "
                      "strain outputs")
            else:
                print("  no strain outputs on this model (give extensometers or strain rows for strains everywhere)")
        _print_diagnostics(m)
        sys.stdout.flush()
    figure_notes = []
    if not args.no_plot:
        draw(files, "figure", figure_notes, _plot, result, os.path.join(out, "estimate.png"))
        draw(files, "sensors_figure", figure_notes, _plot_sensors, result, os.path.join(out, "sensors.png"))
    if args.json:
        print(json.dumps({"name": name, "detectable": m["detectable"], "n_steps": m["n_steps"],
                          "rms_force": m.get("rms_force"), "avg_strain_error": m.get("avg_strain_error"),
                          "avg_strain_error_microstrain": m.get("avg_strain_error_microstrain"),
                          "forces": m["forces"], "sensors": m["sensors"], "warnings": m["warnings"] + figure_notes,
                          "units": m["units"], "files": files, "notes": notes}))
        for w in m["warnings"] + figure_notes:
            print(f"akf: warning: {w}", file=sys.stderr)
        return 0
    for w in figure_notes:
        print(f"  WARNING: {w}")
    print_written(files, notes)
    return 0


def register(sub):
    """Add ``estimate`` to the ``akf`` sub-command parser."""
    p = sub.add_parser("estimate", help="estimate forces and strains for a job (TOML) or a built-in example")
    p.add_argument("job", nargs="?", help="job file (TOML)")
    p.add_argument("--example", help="built-in example, e.g. s17-case4 (see --list-examples)")
    p.add_argument("--list-examples", action="store_true", help="list the built-in examples")
    p.add_argument("--out", help="output folder (default akf-out/NAME)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    p.add_argument("--filter", choices=["steady", "time-varying"], help="override the job's filter form")
    p.add_argument("--allow-undetectable", action="store_true", help="run even if the PBH test fails")
    p.add_argument("--duration", type=float, help="override the simulated record length (s)")
    p.add_argument("--seed", type=seed, help="override the noise seed")
    p.add_argument("--no-plot", action="store_true", help="do not write the PNG figure")
    p.add_argument("--resume", action="store_true", help="measured data: continue an interrupted run in --out from its "
                   "last written chunk")
    p.add_argument("--overwrite", action="store_true", help="measured data: start anew in --out, replacing an "
                   "interrupted run's checkpoint and partial output")
    add_print_job(p)
    p.set_defaults(func=_estimate)
