"""``akf locate``: impact localisation from a job file (measured data) or a built-in example.

A locate job (TOML)::

    name = "truss-impact"
    dt = 0.001                      # s; must match the data's sampling interval
    sensors = ["strain:5", "strain:9", "acc:6:y"]

    [structure]
    model = "s17_truss"

    [locate]
    n_ad = 4                        # AD (held-back) sensors per role split
    ad_kinds = ["strain"]           # kinds that may be AD
    direction = "y"                 # force direction at the candidates
    candidates = [2, 3, 4]          # optional: node ids (default every free node)
    max_splits = 50                 # optional cap (seeded sample)
    tune = true                     # GA covariance tuning
    n_modes = "auto"                # filter reduction for scan/tuning ("auto", an int, or "full")

    [locate.covariances]            # optional assumed levels (default: from the data)
    model_error = 1e-16
    force_increment = 1e6
    noise = {strain = 1e-13, acc = 1e-3}

    [locate.tuning]                 # optional GA settings
    population = 12
    generations = 8

    [measurements]
    file = "impact.csv"             # time column + one column per sensor label
"""
from __future__ import annotations

import json
import os
import sys

import numpy as np

from core_akf import jobs as J
from core_akf.exceptions import AKFInputError
from core_akf.jobs import check_keys, check_sections, load_job_file
from core_akf.outputs import OutputFolder, write_csv

LOCATE_KEYS = {
    None: {"name": J.TEXT, "description": J.ANY, "dt": J.POSITIVE, "sensors": J.TEXTS, "structure": J.TABLE,
           "locate": J.TABLE, "measurements": J.TABLE},
    "locate": {"n_ad": J.COUNT, "ad_kinds": J.TEXTS, "direction": J.TEXT, "candidates": J.INTS,
               "max_splits": J.COUNT, "tune": J.BOOLEAN, "n_modes": J.MODES, "covariances": J.TABLE,
               "tuning": J.TABLE, "skip": J.NON_NEGATIVE},
    "measurements": {"file": J.TEXT, "time_column": J.TEXT},
}
TUNING_KEYS = {"population": J.COUNT, "generations": J.COUNT0, "n_splits": J.COUNT, "decades": J.POSITIVE,
               "crossover": J.FRACTION, "mutation": J.FRACTION}


def validate_locate_job(job):
    check_sections(job, LOCATE_KEYS, "locate job")
    check_keys(job.get("locate", {}).get("tuning", {}), TUNING_KEYS, "[locate.tuning]")
    for key in ("dt", "sensors", "structure", "measurements"):
        if key not in job:
            raise AKFInputError(f"the locate job has no {key!r}")
    for key in ("n_ad", "direction"):
        if key not in job.get("locate", {}):
            raise AKFInputError(f"[locate] needs {key!r}")


def _covariances(spec):
    from .scan import Covariances

    if spec is None:
        return None
    check_keys(spec, {"model_error": J.NON_NEGATIVE, "force_increment": J.POSITIVE, "noise": J.POSITIVE_TABLE},
               "[locate.covariances]")
    try:
        return Covariances(float(spec["model_error"]), float(spec["force_increment"]),
                           {k: float(v) for k, v in spec["noise"].items()})
    except KeyError as exc:
        raise AKFInputError(f"[locate.covariances] needs {exc}") from None


def run_locate_job(job, job_dir=".", n_jobs=1, seed=0, progress=False, tune=None):
    """Run a locate job (dict from TOML); returns the :class:`~impactloc.locate.LocateResult`."""
    from core_akf.jobs import build_structure, read_measurements
    from core_akf.sensors import selection_matrices

    from .locate import locate

    validate_locate_job(job)
    structure = build_structure(job["structure"])
    meas = job["measurements"]
    path = meas.get("file")
    if path is None:
        raise AKFInputError("[measurements] needs file = 'data.csv'")
    if not os.path.isabs(path):
        path = os.path.join(job_dir, path)
    dt = float(job["dt"])
    selection_matrices(structure, job["sensors"])     # every sensor exists on this structure
    Y = read_measurements(path, job["sensors"], dt, meas.get("time_column", "time"))
    spec = job["locate"]
    n_modes = spec.get("n_modes", "auto")
    n_modes = None if n_modes == "full" else n_modes
    res = locate(structure, job["sensors"], Y, dt, n_ad=int(spec["n_ad"]), direction=spec["direction"],
                 ad_kinds=tuple(spec.get("ad_kinds", ["strain"])), candidates=spec.get("candidates"),
                 covariances=_covariances(spec.get("covariances")), tune=spec.get("tune", True) if tune is None else tune,
                 max_splits=spec.get("max_splits"), n_modes=n_modes, skip=float(spec.get("skip", 0.0)),
                 n_jobs=n_jobs, seed=seed, progress=progress, tuning=spec.get("tuning"))
    return res


def write_outputs(result, out, scenario=None, plot=True):
    """Write ranking.csv, scan.csv, force.csv, response.csv, tuning.csv and the figures; returns {name: path}."""
    import pandas as pd

    from .locate import plot_locate

    os.makedirs(out, exist_ok=True)
    files = {"ranking": os.path.join(out, "ranking.csv"), "scan": os.path.join(out, "scan.csv"),
             "force_history": os.path.join(out, "force.csv")}
    write_csv(result.scan.summary, files["ranking"])
    write_csv(result.scan.frame, files["scan"])
    est = result.reconstruction.estimate
    cols = {"time": est.time, "force_assumed": result.initial.force, "force_tuned": result.reconstruction.force}
    if scenario is not None:
        cols["force_true"] = scenario.true_force
    write_csv(pd.DataFrame(cols), files["force_history"])
    files["response"] = os.path.join(out, "response.csv")   # strain at every member / node component
    strains = pd.DataFrame(est.strains, columns=est.structure.strain_labels)
    strains.insert(0, "time", est.time)
    write_csv(strains, files["response"], float_format="%.6e")
    if result.tuning is not None:
        files["tuning"] = os.path.join(out, "tuning.csv")
        write_csv(result.tuning.logbook, files["tuning"])
    if plot:
        files.update(plot_locate(result, out, true_force=None if scenario is None else scenario.true_force,
                                 true_strains=None if scenario is None else scenario.simulation.strains))
    return files


def _locate(args):
    from .examples import EXAMPLES, example_scenario
    from .locate import locate

    if args.list_examples:
        for name, spec in EXAMPLES.items():
            print(f"{name:16s} impact at node {spec['impact_node']}, {len(spec['sensors'])} sensors, "
                  f"{spec['n_ad']} {'/'.join(spec['ad_kinds'])} AD")
        return 0
    if (args.job is None) == (args.example is None):
        raise AKFInputError("give a locate job file or --example NAME (see --list-examples)")
    if args.n_jobs == 0:
        raise AKFInputError("--n-jobs must be a positive number of workers, or negative (-1: all cores), not 0")
    progress = not args.json
    scenario = None
    if args.example:
        scenario = example_scenario(args.example, impact_node=args.impact_node, noise=args.noise, seed=args.seed)
        result = locate(scenario.structure, scenario.sensors, scenario.measurements, scenario.dt, n_ad=scenario.n_ad,
                        ad_kinds=scenario.ad_kinds, direction=scenario.direction, tune=not args.no_tune,
                        n_jobs=args.n_jobs, seed=args.seed, progress=progress)
        name = f"{args.example}-node{scenario.impact[0]}-{args.noise}"
    else:
        if args.impact_node is not None:
            raise AKFInputError("--impact-node applies to the built-in examples (the data decide where a real impact hit)")
        job = load_job_file(args.job)
        result = run_locate_job(job, os.path.dirname(os.path.abspath(args.job)), n_jobs=args.n_jobs,
                                   seed=args.seed, progress=progress, tune=False if args.no_tune else None)
        name = job.get("name", os.path.splitext(os.path.basename(args.job))[0])
    out = args.out or os.path.join("akf-out", "locate", name)
    with OutputFolder(out, "--out"):
        files = write_outputs(result, out, scenario, plot=not args.no_plot)
    d = result.to_dict()
    if args.json:
        d["files"] = files
        if scenario is not None:
            d["true_node"] = int(scenario.impact[0])
            d["true_peak_force"] = float(scenario.true_force[np.argmax(np.abs(scenario.true_force))])
        print(json.dumps(d))
        for w in result.warnings:
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
        print(f"  covariance tuning: AD error {d['ad_error_before_tuning']:.4f} -> {d['ad_error_after_tuning']:.4f}")
    if scenario is not None:
        print(f"  truth: node {scenario.impact[0]}, peak {np.max(np.abs(scenario.true_force)) / 1e3:.3f} kN")
    for w in result.warnings:
        print(f"  WARNING: {w}")
    print("  time: " + ", ".join(f"{k} {v:.2f} s" for k, v in result.seconds.items()))
    for k, v in files.items():
        print(f"  wrote {k}: {v}")
    return 0


def register(sub):
    """Add ``locate`` to the ``akf`` sub-command parser."""
    from .examples import EXAMPLES, NOISE

    p = sub.add_parser("locate", help="locate an impact and reconstruct its force (IMP)")
    p.add_argument("job", nargs="?", help="locate job file (TOML) with measured data")
    p.add_argument("--example", choices=sorted(EXAMPLES), help="simulate a built-in IMP case and locate it")
    p.add_argument("--list-examples", action="store_true", help="list the built-in examples")
    p.add_argument("--impact-node", type=int, help="example: where the simulated impact hits (default the paper's)")
    p.add_argument("--noise", choices=NOISE, default="abs", help="example noise: abs (1 µε, 1 mg) or rel10 (10 %%)")
    p.add_argument("--seed", type=int, default=0, help="noise, role-split sample and GA seed")
    p.add_argument("--n-jobs", type=int, default=1, help="joblib workers (-1: all cores)")
    p.add_argument("--no-tune", action="store_true", help="skip the covariance GA")
    p.add_argument("--json", action="store_true", help="print one JSON object (no progress bars)")
    p.add_argument("--out", help="output folder (default akf-out/locate/NAME)")
    p.add_argument("--no-plot", action="store_true", help="do not write PNG figures")
    p.set_defaults(func=_locate)
