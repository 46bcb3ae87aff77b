"""``akf locate``: impact localisation from a job file (measured data) or a built-in example."""
from __future__ import annotations

import json
import os
import sys

import numpy as np

from core_akf.checks import AKFInputError

from ..job import load_job
from ..outputs import OutputFolder
from ..parallel import add_scheduler_option, scheduler, workers
from .common import add_print_job, seed, worker_count


def _locate(args):
    from ..locating import write_outputs
    from .common import check_job_or_example, listing_or_template, print_written

    done = listing_or_template(args, "locate")
    if done is not None:
        return done
    check_job_or_example(args, "locate job file")
    if args.job is not None:
        job = load_job(args.job, "locate")
        from ..locating import is_event_folder

        if is_event_folder(job):
            return _locate_events(args, job)
    run, scenario, name, job = _prepare_locate(args, progress=not args.json)
    out = args.out or os.path.join("akf-out", "locate", name)
    figure_notes = []
    with OutputFolder(out, "--out"):          # checked and locked before the work starts
        with scheduler(args.scheduler, resume="run the same command again: the scan has no randomness and the "
                                              "seed repeats the tuning"):
            result = run()
        files = write_outputs(result, out, scenario, plot=not args.no_plot, notes=figure_notes)
        d = result.to_dict()
        if args.report:                       # after the results: a report that fails is a warning
            from ..report import write_report
            warnings = list(d["warnings"])
            path = write_report(out, "locate", job, d, files, warnings, source=args.job)
            figure_notes += warnings[len(d["warnings"]):]
            if path is not None:
                files["report"] = path
    if args.json:
        d["files"] = files
        if scenario is not None:
            d["true_node"] = int(scenario.impact[0])
            d["true_peak_force"] = float(scenario.true_force[np.argmax(np.abs(scenario.true_force))])
        d["warnings"] = list(d["warnings"]) + figure_notes
        print(json.dumps(d))
        for w in d["warnings"]:
            print(f"akf: warning: {w}", file=sys.stderr)
        return 0
    print(f"{name}: {len(result.scan.splits)} role splits x {len(result.scan.locations)} candidate locations")
    print("  rank  node    mean AD error    spread   votes")
    for r in result.scan.summary.head(8).itertuples():
        print(f"  {r.rank:4d}  {r.node:4d}    {r.mean:13.4f}  {r.std:8.4f}   {r.votes:5.2f}")
    print(f"  identified: node {d['identified']} ({d['direction']}), confidence {d['confidence']:.2f} "
          f"(share of splits that pick it), margin {d['margin'] if d['margin'] is not None else float('inf'):.2f} "
          "(runner-up distance in spreads)")
    print(f"  force: peak {d['peak_force'] / 1e3:.3f} kN at {d['time_of_peak']:.4f} s, duration {d['duration'] * 1e3:.1f} ms, "
          f"impulse {d['impulse']:.2f} N s")
    if result.tuning is not None:
        how = "maximum likelihood" if result.tuning.method == "ml" else "GA"
        print(f"  covariance tuning ({how}): AD error {d['ad_error_before_tuning']:.4f} -> "
              f"{d['ad_error_after_tuning']:.4f}")
        for gene, side in result.tuning.settled.items():
            print(f"    {gene} tuned to its {side} search bound, beyond which the error no longer changes "
                  f"({'the data need no more of it' if side == 'lower' else 'any larger level does the same'})")
    if scenario is not None:
        print(f"  truth: node {scenario.impact[0]}, peak {np.max(np.abs(scenario.true_force)) / 1e3:.3f} kN")
    for w in list(result.warnings) + figure_notes:
        print(f"  WARNING: {w}")
    print("  time: " + ", ".join(f"{k} {v:.2f} s" for k, v in result.seconds.items()))
    print_written(files)
    return 0


def _locate_events(args, job):
    """``akf locate JOB`` whose measurements are a folder or glob of impact records: one event per file."""
    from ..locating import locate_events
    from .common import print_written

    name = job.name
    out = args.out or os.path.join("akf-out", "locate", name)
    with OutputFolder(out, "--out"), scheduler(args.scheduler, resume="run the same command again"):
        if not args.json:
            print(f"{name}: locating the impact of every file of {job.spec.measurements.file}")
        frame, files = locate_events(job, out, n_jobs=workers(args), seed=args.seed, progress=not args.json,
                                     tune=_tune(args), plot=not args.no_plot)
    located = frame["node"].notna().sum()
    if args.json:
        print(json.dumps({"name": name, "events": json.loads(frame.to_json(orient="records")), "files": files}))
    else:
        print(f"  {located} of {len(frame)} impacts located")
        print_written(files)
    if len(frame) and not located:        # the files are written; the exit code says nothing was found
        errors = frame["error"].dropna().unique()
        raise AKFInputError(f"no impact located in any of the {len(frame)} file(s) (events.csv has each error); "
                            + (f"every file: {errors[0]}" if len(errors) == 1 else f"the first: {errors[0]}"))
    return 0


def _tune(args):
    """The tuning the command line asks for: False (--no-tune), "ga" or "ml" (--tune), None (the job's)."""
    if args.no_tune and args.tune:
        raise AKFInputError("--no-tune skips the tuning and --tune chooses how to tune: give one of them")
    return False if args.no_tune else args.tune


def _prepare_locate(args, progress):
    """What ``akf locate`` runs: ``(run, scenario or None, output name, job)``; ``run()`` does the
    identification and returns the :class:`~impactloc.locate.LocateResult`."""
    from ..examples.impact import example_scenario
    from ..locating import run_locate_job

    if args.example:        # the example's job, every [locate] key honoured; its simulation is the truth
        scenario = example_scenario(args.example, impact_node=args.impact_node, noise=args.noise, seed=args.seed)

        def run():
            return run_locate_job(scenario.job, n_jobs=workers(args), seed=args.seed, progress=progress,
                                  tune=_tune(args), simulation=scenario.simulation)
        return run, scenario, f"{args.example}-node{scenario.impact[0]}-{args.noise}", scenario.job
    if args.impact_node is not None:
        raise AKFInputError("--impact-node applies to the built-in examples (the data decide where a real impact hit)")
    job = load_job(args.job, "locate")

    def run():
        return run_locate_job(job, n_jobs=workers(args), seed=args.seed, progress=progress,
                              tune=_tune(args))
    return run, None, job.name, job


def register(sub):
    """Add ``locate`` to the ``akf`` sub-command parser."""
    from ..examples.impact import EXAMPLES, NOISE

    p = sub.add_parser("locate", help="locate an impact and reconstruct its force (IMP)")
    p.add_argument("job", nargs="?", help="locate job file (TOML) with measured data")
    p.add_argument("--example", choices=sorted(EXAMPLES), help="simulate a built-in IMP case and locate it")
    p.add_argument("--list-examples", action="store_true", help="list the built-in examples")
    p.add_argument("--impact-node", type=int, help="example: where the simulated impact hits (default the paper's)")
    p.add_argument("--noise", choices=NOISE, default="abs", help="example noise: abs (1 µε, 1 mg) or rel10 (10 %%)")
    p.add_argument("--seed", type=seed, default=0, help="noise, role-split sample and GA seed")
    p.add_argument("--n-jobs", type=worker_count, help="joblib workers (-1: all cores; default 1, every worker with --scheduler)")
    add_scheduler_option(p)
    p.add_argument("--no-tune", action="store_true", help="skip the covariance tuning")
    p.add_argument("--tune", choices=("ga", "ml"), help="tune the covariances with the paper's GA or by maximum "
                   "likelihood (instead of [locate] tune; default the GA)")
    p.add_argument("--json", action="store_true", help="print one JSON object (no progress bars)")
    p.add_argument("--out", help="output folder (default akf-out/locate/NAME)")
    p.add_argument("--no-plot", action="store_true", help="do not write PNG figures")
    p.add_argument("--report", action="store_true", help="also write report.html: the location, its ranking, the "
                   "force history's figures and the job, on one self-contained page")
    add_print_job(p)
    p.set_defaults(func=_locate)
