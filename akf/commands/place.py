"""``akf place``: sensor placement from a job file or a built-in example.

Every key of a place job: the job-file reference (``python -m akf.schema``); the built-in
problems are ``akf/examples/jobs/th-*.toml``.
"""
from __future__ import annotations

import json
import logging
import math
import os
import sys

from core_akf.checks import AKFInputError
from core_akf.outputs import write_csv

from ..outputs import OutputFolder
from ..parallel import add_scheduler_option, check_scheduler
from .common import add_print_job, finish, seed, worker_count

log = logging.getLogger("akf")


def _place(args):
    from sensoropt.ga import THESIS

    from ..job import Job
    from ..placement import problem_from_job, reference_layouts
    from .common import job_data, listing_or_template

    done = listing_or_template(args, "place")
    if done is not None:
        return done
    data = job_data(args, "place", "place job file")
    check_scheduler(args.scheduler)          # before the problem is built
    overrides = {f"place.{k}": getattr(args, k) for k in ("sensors", "window", "generations", "population", "operators")
                 if getattr(args, k) is not None}
    if args.sensors is not None and isinstance(data, dict) and "budget" in (data.get("place") or {}):
        raise AKFInputError("--sensors does not apply to a job with a budget per sensor type")
    job = Job.from_dict(data, "place", source=args.job, overrides=overrides)      # checked once
    problem, ga = problem_from_job(job)
    if args.example:
        problem.reference_layouts = reference_layouts(args.example)
    settings = dict(THESIS)
    settings.update(ga)
    out = args.out or os.path.join("akf-out", "place", f"{problem.name}-{problem.n_sensors or 'budget'}-seed{args.seed}")
    objectives = tuple(job.spec.place.objectives or ("error",))
    if objectives not in (("error",), ("error", "cost")):
        raise AKFInputError(f"[place] objectives = {list(objectives)}: give [\"error\"] (one layout) or "
                            "[\"error\", \"cost\"] (the front of error against cost)")
    with OutputFolder(out, "--out"):      # checked and locked before the work starts
        if objectives == ("error", "cost"):
            return _run_front(args, problem, settings, out, job)
        return _run_place(args, problem, settings, out, job)


def _run_front(args, problem, settings, out, job):
    """``objectives = ["error", "cost"]``: NSGA-II over layouts of 1 to ``sensors`` sensors, the
    front written (``front.csv``, with each layout's whole-record error), printed, then drawn."""
    import numpy as np

    from sensoropt.pareto import pareto
    from sensoropt.plots import plot_pareto

    from ..figures import draw
    from ..parallel import workers

    if problem.budget:
        raise AKFInputError("[place] objectives = [\"error\", \"cost\"] varies the number and kinds of the sensors: "
                            "give sensors = N (the largest layout) instead of a budget per sensor type")
    if args.resume:
        raise AKFInputError("the front of error against cost keeps no checkpoint: run it without --resume")
    enc = problem.encoding()
    obj = problem.objective(enc)
    costs = problem.constraints.costs(enc) if problem.constraints is not None else np.ones(len(enc.candidates))
    cost = {str(k): float(costs[enc.kind == k][0]) for k in enc.kinds}
    res = pareto(obj, candidates=enc, sizes=(1, enc.n_sensors), cost=cost, population=settings["population"],
                 generations=settings["generations"], crossover=settings["crossover"], seed=args.seed,
                 n_jobs=workers(args), progress=not args.json)
    front = res.front.rename(columns={"error": "window_error"})
    if front.empty:
        raise AKFInputError("no layout the GA tried is admissible (each is undetectable, fails its filter or breaks "
                            "the constraints)")
    # the GA's front and logbook first; the whole-record checks (a simulation each) then complete the front
    files = {"front": write_csv(front, os.path.join(out, "front.csv")),
             "logbook": write_csv(res.logbook, os.path.join(out, "logbook.csv"))}
    front["error"] = [problem.full_record_error(s.split()) for s in front["sensors"]]
    write_csv(front, files["front"])
    summary = {"front": json.loads(front.to_json(orient="records")), "evaluations": res.evaluations,
               "cost_per_kind": cost, "files": files,
               "units": {"error": "µε (average RMS strain error, full record)", "window_error": "µε",
                         "cost": "the units of [place.constraints] cost"}}
    if not args.json:
        print(f"{problem.name}: the front of error against cost, layouts of 1-{enc.n_sensors} sensors from "
              f"{len(enc.allowed_indices())} allowed positions ({', '.join(enc.kinds)}), seed {args.seed}")
        print(f"  {'cost':>8s} {'sensors':>7s} {'window µε':>10s} {'record µε':>10s}  layout")
        for r in front.itertuples():
            print(f"  {r.cost:8.4g} {r.n_sensors:7d} {r.window_error:10.4f} {r.error:10.4f}  {r.sensors}")
        sys.stdout.flush()
    figure_notes = []
    if not args.no_plot:
        draw(files, "front", figure_notes, plot_pareto, front, os.path.join(out, "front.png"),
             f"{problem.name}: whole-record error against cost")
    return finish(args, summary, files, figure_notes, [], report=("place", job, out))


def _run_place(args, problem, settings, out, job):

    from core_akf.evolution import is_checkpoint
    from core_akf.sensors import sensor_positions
    from sensoropt.ga import place
    from sensoropt.plots import plot_convergence, plot_layout

    from ..figures import draw
    from ..parallel import scheduler, workers

    checkpoint = args.checkpoint or os.path.join(out, "checkpoint.json")
    if args.overwrite and args.resume:
        raise AKFInputError("--overwrite starts anew and --resume continues: give one of them")
    if args.overwrite:
        for path in (checkpoint, f"{checkpoint}.bak"):
            if os.path.lexists(path):
                if not is_checkpoint(path):
                    raise AKFInputError(f"--overwrite replaces the run's own GA checkpoint, but {path} is not one (a "
                                        "file of yours?); it was left as it is: give --checkpoint a path of its own")
                os.remove(path)
    notes = window_notes(problem) + list(problem.notes)
    if notes and not args.json:
        for note in notes:
            print(f"akf: note: {note}", file=sys.stderr)
    enc = problem.encoding()
    obj = problem.objective(enc)
    resume = (f"the GA checkpoint {checkpoint} holds the generations done so far (saved every 5): run the same "
              "command with --resume to continue from it")
    with scheduler(args.scheduler, resume=resume):
        res = place(obj, enc, seed=args.seed, n_jobs=workers(args), checkpoint=checkpoint, resume=args.resume,
                    progress=not args.json, on_generation=_cost_report(problem, obj, settings, args.json), **settings)
    if not math.isfinite(obj.evaluate([res.sensors])[0]):       # the GA's best is a penalty: nothing admissible
        kinds = {str(k).split(":")[0] for k in (problem.kinds or ())} or {str(s).split(":")[0] for s in res.sensors}
        hint = ("accelerometer-only layouts cannot see the static response under the random-walk force model: set "
                "[filter] force_model = \"matern32\" (with force_std and force_timescale), or allow strain gauges in "
                "[place] kinds") if kinds <= {"acc", "vel"} and not (problem.force_model and problem.force_model.stationary) \
            else ("check the candidates, the covariances and the budget, and whether the [place.constraints] can be met"
                  if problem.constraints is not None else "check the candidates, the covariances and the budget")
        raise AKFInputError(f"no layout the GA tried is admissible (each is undetectable or its filter fails): {hint}")
    error = problem.full_record_error(res.sensors)
    refs = {name: problem.full_record_error(s) for name, s in problem.reference_layouts.items()
            if len(s) == enc.n_sensors and not problem.budget}
    fatigue = problem.objective_kind == "fatigue"
    window_unit = "% (mean relative DEL error of the targets)" if fatigue else "µε"
    # the results first: the layout table and the logbook, then the printout, then the figures
    positions = sensor_positions(problem.structure, res.sensors)
    files = {"layout_table": write_csv(positions, os.path.join(out, "layout.csv")),
             "logbook": write_csv(res.logbook, os.path.join(out, "logbook.csv")), "checkpoint": checkpoint}
    lb = res.logbook
    summary = {"layout": res.layout, "sensors": res.sensors, "error": error, "window_error": res.best_error,
               "positions": json.loads(positions.to_json(orient="records")),
               "generations": int(lb["generation"].iloc[-1]), "evaluations": res.evaluations,
               "cache_hits": res.cache_hits, "infeasible": res.infeasible, "stopped": res.stopped,
               "seconds": float(lb["seconds"].iloc[-1]), "reference_errors": refs, "files": files, "notes": notes,
               "objective": problem.objective_kind,
               "units": {"error": "µε (average RMS strain error, full record)", "window_error": window_unit,
                         "reference_errors": "µε", "seconds": "s", "positions": "m"}}
    if fatigue:
        summary["fatigue_error"] = problem.full_record_fatigue_error(res.sensors)
        summary["units"]["fatigue_error"] = "% (mean relative DEL error of the targets, full record)"
    summary |= robustness(problem, obj, enc, res.sensors, out, files)
    if not args.json:
        _print_placement(problem, enc, res, positions, summary, args.seed)
    figure_notes = []
    if not args.no_plot:
        draw(files, "convergence", figure_notes, plot_convergence, res.logbook, os.path.join(out, "convergence.png"),
             f"{problem.name}: {enc.n_sensors} sensors, seed {args.seed}")
        draw(files, "layout", figure_notes, plot_layout, enc, res.best, os.path.join(out, "layout.png"),
             f"best layout: window error {res.best_error:.3f} {'%' if fatigue else 'µε'}, full record {error:.3f} µε",
             forces=obj.model.forces)
    return finish(args, summary, files, figure_notes, notes, report=("place", job, out))


def robustness(problem, objective, enc, sensors, out, files):
    """How the layout holds: its error on each model of ``[place.uncertainty]`` (``uncertainty.csv``),
    after each loss of ``survive_failures`` sensors (``failures.csv``), its cost and the
    constraints it honours; written before anything is printed or drawn."""
    import numpy as np
    import pandas as pd

    from sensoropt.robust import combine

    found = {}
    u = problem.uncertainty
    if u is not None:
        window = objective.scenario_errors(sensors).reshape(u.n_models, u.seeds)
        rows = problem.model_errors(sensors)
        for row, w in zip(rows, window):
            row["window_error"] = float(combine(w, "mean"))
        table = pd.DataFrame(rows)
        files["uncertainty"] = write_csv(table, os.path.join(out, "uncertainty.csv"))
        found["uncertainty"] = {"measure": u.measure, "models": u.n_models, "seeds": u.seeds,
                                "window_measure": float(combine(window.ravel(), u.measure)),
                                "error_measure": float(combine(table["error"].to_numpy(), u.measure)),
                                "models_table": json.loads(table.to_json(orient="records"))}
    if problem.survive_failures:
        rows = []
        for lost, fit in objective.failure_errors(sensors, problem.survive_failures):
            rest = [s for s in sensors if s not in lost]
            full = problem.full_record_error(rest) if np.isfinite(fit) else math.inf
            rows.append({"lost": " ".join(lost), "window_error": fit, "error": full})
        table = pd.DataFrame(rows)
        files["failures"] = write_csv(table, os.path.join(out, "failures.csv"))
        found["failures"] = {"lost_at_once": problem.survive_failures, "measure": problem.failure_measure,
                             "worst_error": float(table["error"].max()),
                             "table": json.loads(table.to_json(orient="records"))}
    c = problem.constraints
    if c is not None:
        layout = enc.from_sensors(sensors)
        found["constraints"] = {"cost": c.cost_of(enc, layout), "budget": c.budget, "min_spacing": c.min_spacing,
                                "honoured": c.violation(enc, layout) is None}
    return found


def _print_placement(problem, enc, res, positions, summary, seed):
    """The placement's console report (the numbers of ``summary``)."""
    import pandas as pd

    lb, error, refs = res.logbook, summary["error"], summary["reference_errors"]
    fatigue = problem.objective_kind == "fatigue"
    print(f"{problem.name}: {enc.n_sensors} sensors from {len(enc.candidates)} admissible positions "
          f"({', '.join(enc.kinds)}), seed {seed}")
    print("  best layout:  " + ", ".join(res.sensors))
    for r in positions.itertuples():
        where = f"node {r.node}" if pd.isna(r.node_b) else f"nodes {r.node}-{r.node_b}"
        print(f"    {r.sensor:>16s}  {r.source:<14s} " + ("(no place: a strain operator row)" if pd.isna(r.node)
              else f"{where} at x {r.x:.4g}, y {r.y:.4g}, z {r.z:.4g} m"))
    if fatigue:
        print(f"  DEL error (m = {problem.del_slope:g}): {summary['fatigue_error']:.3f} % over the "
              f"{problem.loads.shape[0] * problem.dt:.3g} s record ({res.best_error:.3f} % on the {problem.window:g} s "
              f"fitness window); average strain error {error:.4f} µε")
    else:
        print(f"  average strain error: {error:.4f} µε over the {problem.loads.shape[0] * problem.dt:.3g} s record "
              f"({res.best_error:.4f} µε on the {problem.window:g} s fitness window)")
    for name, e in refs.items():
        print(f"  {name}: {e:.4f} µε")
    if "uncertainty" in summary:
        u = summary["uncertainty"]
        print(f"  over {u['models']} true structures (filter stiffness factor "
              f"{min(r['stiffness_factor'] for r in u['models_table']):.4g}-"
              f"{max(r['stiffness_factor'] for r in u['models_table']):.4g}) x {u['seeds']} noise draws: "
              f"{u['measure']} {u['window_measure']:.4f} on the window; whole record per model {u['measure']} "
              f"{u['error_measure']:.4f} µε (uncertainty.csv)")
    if "failures" in summary:
        f = summary["failures"]
        worst = max(f["table"], key=lambda r: r["error"])
        print(f"  with {f['lost_at_once']} sensor(s) lost: worst whole-record error {f['worst_error']:.4f} µε "
              f"(losing {worst['lost']}; failures.csv)")
    if "constraints" in summary:
        c = summary["constraints"]
        print(f"  cost {c['cost']:g}" + (f" of budget {c['budget']:g}" if c["budget"] is not None else "")
              + (f"; sensors at least {c['min_spacing']:g} m apart" if c["min_spacing"] is not None else "")
              + ("; every constraint honoured" if c["honoured"] else "; CONSTRAINTS BROKEN"))
    print(f"  {int(lb['generation'].iloc[-1])} generations ({res.stopped}), {res.evaluations} evaluations, "
          f"{res.cache_hits} cache hits, {res.infeasible} infeasible, {lb['seconds'].iloc[-1]:.1f} s")
    sys.stdout.flush()


def _cost_report(problem, objective, settings, json_output):
    """What the run costs, told once generation 0 is evaluated: the model, the filter's states and
    the seconds per generation (on a model of one's own the first thing to know).  On the
    terminal through the ``akf`` logger (``-q`` hides it); with ``--json`` on stderr."""
    def report(row):
        if row["generation"] != 0:
            return
        fm = objective.model
        modes = f"{fm.n_modes} modes + static correction" if fm.n_modes is not None else "all modes"
        message = (f"akf: {problem.name}: model of {problem.structure.n} DOFs, filter {modes} = {fm.n_a} states; "
                   f"generation 0: {row['evaluations']} evaluations in {row['seconds']:.1f} s (with the workers' "
                   f"start); a later generation evaluates only its new layouts, {settings.get('generations')} "
                   "generations at most ([place] n_modes sets the filter's modes)")
        if json_output:
            print(message, file=sys.stderr)
        else:
            log.info(message)
    return report


def window_notes(problem):
    """What a user should know about the fitness window: with accelerometers among the kinds, a
    window shorter than 1 s finds layouts that do not carry over to the full record; with
    ``survive_failures``, one shorter than :data:`SURVIVE_WINDOW` misjudges what a loss costs."""
    notes = []
    kinds = list(problem.kinds or ()) + list(problem.candidates or ())
    if any(str(k).startswith("acc") for k in kinds) and problem.window < 1.0:
        notes.append(f"multi-metric placement (accelerometers allowed) on a {problem.window:g} s fitness window: the "
                     "window from rest holds only the dynamic response, where an accelerometer looks better than "
                     "over the whole record, and the layouts found do not carry over to it; use --window 1 (1 s "
                     "costs little more: the Riccati solve dominates)")
    if problem.survive_failures and problem.window < SURVIVE_WINDOW:
        notes.append(f"survive_failures on a {problem.window:g} s fitness window: a window from rest holds little of "
                     "the static response, and that is what a lost gauge costs most, so the layout found may survive "
                     "a loss worse over the whole record than one placed without it; use --window "
                     f"{SURVIVE_WINDOW:g} or longer (on th-case5 the worst single-loss error over the record was 11.7 "
                     "µε against the nominal layout's 8.6 on 0.1 s, 3.7 against 8.0 on 0.5 s)")
    return notes


#: the shortest fitness window on which a failure-tolerant layout holds over the whole record (s)
SURVIVE_WINDOW = 0.5


def register(sub):
    from ..examples import example_names

    p = sub.add_parser("place", help="optimise sensor positions on a structure (GA, TH)")
    p.add_argument("job", nargs="?", help="place job file (TOML)")
    p.add_argument("--example", choices=example_names("place"), help="built-in problem")
    p.add_argument("--list-examples", action="store_true", help="list the built-in problems")
    p.add_argument("--sensors", type=int, help="number of sensors (overrides the example/job)")
    p.add_argument("--seed", type=seed, default=0, help="GA seed (the run repeats exactly)")
    p.add_argument("--generations", type=int, help="GA generations (default 100)")
    p.add_argument("--population", type=int, help="GA population (default 50)")
    p.add_argument("--operators", choices=["set", "thesis"], help="set-based (default) or the thesis' operators")
    p.add_argument("--window", type=float, help="seconds of response per fitness evaluation (default 0.1; "
                   "1 s generalises better to the full record, at little extra cost)")
    p.add_argument("--n-jobs", type=worker_count, help="joblib workers for the fitness (default 1; every worker with "
                   "--scheduler)")
    add_scheduler_option(p)
    p.add_argument("--checkpoint", help="checkpoint file (default OUT/checkpoint.json)")
    p.add_argument("--resume", action="store_true", help="continue from the checkpoint")
    p.add_argument("--overwrite", action="store_true", help="start anew, replacing an interrupted run's checkpoint")
    p.add_argument("--json", action="store_true", help="print one JSON object (no progress bar)")
    p.add_argument("--out", help="output folder (default akf-out/place/NAME-N-seedS)")
    p.add_argument("--no-plot", action="store_true", help="do not write PNG figures")
    p.add_argument("--report", action="store_true", help="also write report.html: the layout, its errors, the "
                   "logbook's figures and the job, on one self-contained page")
    add_print_job(p)
    p.set_defaults(func=_place)
