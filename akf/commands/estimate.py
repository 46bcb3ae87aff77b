"""``akf estimate``: estimate forces and strains for a job file or a built-in example."""
from __future__ import annotations

import json
import os
import sys

from core_akf.checks import AKFInputError

from ..outputs import OutputFolder
from ..parallel import add_scheduler_option, scheduler, workers
from .common import add_print_job, print_written, seed, worker_count

#: the captions of the figures in report.html
FIGURES = {"figure": "the estimated forces (with the reference of a simulation, the ±2σ bands of a smoothed "
                     "estimate and a zoom where they can be seen), the strain errors and each channel's consistency",
           "sensors_figure": "every sensor's measured signal against the filter's one-step prediction",
           "fatigue_figure": "the fatigue damage on the structure and the ten most damaged outputs"}


def _estimate(args):
    from ..estimate import estimate_job
    from ..job import Job
    from .common import job_data, listing_or_template

    done = listing_or_template(args, "estimate")
    if done is not None:
        return done
    data = job_data(args, "estimate")
    overrides = {}
    if args.duration is not None or args.seed is not None:
        if isinstance(data, dict) and "measurements" in data:
            raise AKFInputError("--duration and --seed apply to simulated jobs; this job reads measured data")
        overrides |= {"simulation.duration": args.duration} if args.duration is not None else {}
        overrides |= {"simulation.seed": args.seed} if args.seed is not None else {}
    if args.filter is not None:
        overrides["filter.steady"] = args.filter == "steady"
    if args.allow_undetectable:
        overrides["filter.allow_undetectable"] = True
    job = Job.from_dict(data, "estimate", source=args.job, overrides=overrides)     # checked once
    out = args.out or os.path.join("akf-out", job.name)
    shown = []             # warnings printed with the results, before the figures are drawn
    parallel = args.n_jobs is not None or args.scheduler is not None
    with OutputFolder(out, "--out"), scheduler(args.scheduler, resume="run the same command again"):
        res = estimate_job(job, out, resume=args.resume, overwrite=args.overwrite, plot=not args.no_plot,
                           progress=not args.json and sys.stderr.isatty(),
                           on_result=None if args.json else lambda r: shown.extend(_print_results(job, r)),
                           n_jobs=workers(args) if parallel else None)
        if args.report and res.complete:        # after the results: a report that fails is a warning
            from ..report import write_report
            path = write_report(out, "estimate", job, res.metrics, res.files, res.metrics.setdefault("warnings", []),
                                source=args.job, figures=FIGURES)
            if path is not None:
                res.files["report"] = path
    m = res.metrics
    if args.json:
        print(json.dumps({"name": job.name, "complete": res.complete, "detectable": m.get("detectable"),
                          "n_steps": m.get("n_steps"), "loglik": m.get("loglik"), "calibration": m.get("calibration"),
                          "rms_force": m.get("rms_force"),
                          "avg_strain_error": m.get("avg_strain_error"),
                          "avg_strain_error_microstrain": m.get("avg_strain_error_microstrain"),
                          "forces": m.get("forces"), "sensors": m.get("sensors"), "warnings": m.get("warnings", []),
                          "channels": res.channels, "resumed_at_step": res.resumed_at, "units": m.get("units"),
                          "files": res.files, "notes": res.notes}))
        for w in m.get("warnings", []):
            print(f"akf: warning: {w}", file=sys.stderr)
        return 0
    if not res.complete:
        _print_results(job, res)
    for w in m.get("warnings", [])[len(shown):]:          # a figure that failed
        print(f"  WARNING: {w}")
    print_written(res.files, res.notes)
    return 0


def _print_results(job, res):
    """The table of a run's results; returns the warnings it printed."""
    m = res.metrics
    print(f"{job.name}: {job.description}")
    if res.channels:
        print("  channels: " + "; ".join(res.channels))
    if res.resumed_at:
        print(f"  resumed at step {res.resumed_at}")
    if not res.complete:
        return []
    print(f"  {len(m['sensors'])} sensors, {len(m['forces'])} unknown forces, {m['n_steps']} steps, "
          f"{'detectable' if m['detectable'] else 'NOT detectable (forced)'}")
    if "calibration" in m:
        c = m["calibration"]
        print(f"  calibrated on {c['record_steps']} steps ({c['seconds']:.2f} s): log-likelihood {c['loglik_before']:.8g} "
              f"-> {c['loglik_after']:.8g}; factors " + ", ".join(f"{k} {v:.5g}" for k, v in c["multipliers"].items())
              + (f"; stiffness_factor = {c['stiffness_factor']:.6g}" if "stiffness_factor" in c else ""))
        whittle = c.get("method") == "whittle" and f"force prior by the Whittle likelihood: {c['method_reason']}"
        print("\n".join(f"    {note}" for note in (c["window"], c.get("model_note"), whittle) if note))
    if "rms_force" in m:
        print("  RMS force error (N):")
        for k, v in m["rms_force"].items():
            print(f"    {k:>8s}  {v:10.2f}")
        if "avg_strain_error" in m:
            print(f"  average strain error: {m['avg_strain_error_microstrain']:.4f} µε over "
                  f"{len(m['rms_strain'])} strain outputs")
        else:
            print("  no strain outputs on this model (give extensometers or strain rows for strains everywhere)")
    print("  estimated forces (N):            RMS          peak   at (s)")
    for f in m["forces"]:
        print(f"    {f['channel']:>8s}           {f['rms']:10.4g}   {f['peak']:11.4g}   {f['time_of_peak']:.4f}")
    print("  sensors: measured RMS, innovation RMS (SI), consistency (innovation / predicted; ~1 is good), whiteness, "
          "log-likelihood")
    for d in m["sensors"]:
        print(f"    {d['channel']:>14s}  {d['measured_rms']:10.4g}  {d['innovation_rms']:10.4g}  {d['consistency']:8.3g}"
              f"  {d['whiteness']:6.2f}  {d['loglik']:12.6g}")
    print(f"  log-likelihood of the innovations: {m['loglik']:.8g}")
    if "fatigue" in m:
        rows = sorted(m["fatigue"]["outputs"], key=lambda r: (-r["damage"], -r["del_MPa"]))
        f = m["fatigue"]
        print(f"  fatigue ({f['curve']}; DEL with m = {f['del_slope']:g}, N_eq = {f['del_cycles']:g}), the 5 outputs "
              f"most damaged of {len(rows)}:")
        print("    output           cycles   max range (MPa)   DEL (MPa)    damage     per year")
        for r in rows[:5]:
            print(f"    {r['channel']:>14s}  {r['cycles']:8.1f}   {r['max_range_MPa']:12.4g}   {r['del_MPa']:10.4g}"
                  f"   {r['damage']:9.3g}   {r['damage_per_year']:9.3g}")
        if not rows[0]["damage"]:
            print("    (every range below the curve's cut-off: no damage; ranked by DEL)")
        print(f"    ({f['per_year']})")
    for w in m["warnings"]:
        print(f"  WARNING: {w}")
    sys.stdout.flush()
    return list(m["warnings"])


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
    p.add_argument("--report", action="store_true", help="also write report.html: one self-contained page of the run "
                   "(job, model, warnings, results with their bands, figures) to hand on")
    p.add_argument("--n-jobs", type=worker_count, help="a measured record of many files: filter its files at the same time on "
                   "this many workers (time-parallel steady-state filter; -1: all cores)")
    add_scheduler_option(p)
    p.add_argument("--resume", action="store_true", help="measured data: continue an interrupted run in --out from its "
                   "last written chunk")
    p.add_argument("--overwrite", action="store_true", help="measured data: start anew in --out, replacing an "
                   "interrupted run's checkpoint and partial output")
    add_print_job(p)
    p.set_defaults(func=_estimate)
