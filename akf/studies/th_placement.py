"""Thesis placement studies behind ``akf study th_placement`` (TH §4, cases 5 and 6, plus the
multi-metric placement TH names as future work, plus the NSGA-II "how many sensors" front).

* case 5: 3 strain gauges, 4 independent GA runs (seeds 0-3), against the trial-and-error
  layout of TH case 2, on the full 6 s record;
* case 6: 3, 4, 5 and 8 gauges (one run each): diminishing returns;
* multi-metric: 2 gauges + 1 accelerometer, and 3 gauges + 1 accelerometer, with the 0.1 s
  fitness window and with a 1 s window (and 3 gauges alone on the 1 s window for comparison);
* operators: the set-based operators against the thesis' intermediate crossover and adaptive
  mutation (case 5, 4 seeds each);
* Pareto: error vs number of gauges (1-8) in one NSGA-II run.
"""
from __future__ import annotations

import logging
import os

from core_akf.outputs import write_csv
from core_akf.sensors import parse_force_locations
from sensoropt.encoding import STRAIN_KINDS
from sensoropt.ga import THESIS, independent_runs, place
from sensoropt.pareto import pareto
from sensoropt.plots import plot_convergence, plot_layout, plot_pareto

from ..figures import draw
from ..placement import example_problem
from ._common import Progress, StudyResult, output_dir

log = logging.getLogger("akf")

NAME = "th_placement"
DESCRIPTION = "TH placement GA: case 5 (3 gauges, 4 runs), case 6 (3/4/5/8 gauges), multi-metric, Pareto front"

#: published average strain errors ("micro-strain" in TH)
PUBLISHED = {"case 2 (trial and error)": 0.00666, 3: 0.00360, 4: 0.00286, 5: 0.00241, 8: 0.00183}


def compare_operators(seeds=(0, 1, 2, 3), n_jobs=1, **ga):
    """Set-based operators against the thesis' intermediate crossover + adaptive mutation on
    TH case 5 (same seeds, same GA settings): one row per (operators, seed)."""
    import pandas as pd

    p = example_problem("th-case5")
    enc = p.encoding()
    obj = p.objective(enc)
    settings = dict(THESIS)
    settings.update(ga)
    rows = []
    for ops in ("set", "thesis"):
        for sd in seeds:
            res = place(obj, enc, seed=sd, n_jobs=n_jobs, **dict(settings, operators=ops))
            lb = res.logbook
            within = lb.index[lb["best"] <= res.best_error * 1.01]
            rows.append({"operators": ops, "seed": sd, "best_window_error_ue": res.best_error,
                         "full_record_error_ue": p.full_record_error(res.sensors), "sensors": " ".join(res.sensors),
                         "generation_within_1pct": int(lb["generation"][within[0]]), "evaluations": res.evaluations,
                         "final_diversity": float(lb["diversity"].iloc[-1]), "seconds": float(lb["seconds"].iloc[-1])})
    return pd.DataFrame(rows)


def run(out=None, quick=False, seed=0, n_jobs=2):
    import pandas as pd

    out = output_dir(NAME, out)
    ga = dict(THESIS)
    if quick:
        ga.update(population=16, generations=6)
    files, rows, notes = {}, [], []
    n_runs = (2 if quick else 4) + (2 if quick else 4) + 5 + 2
    progress = Progress(NAME, n_runs)

    def record(study, label, problem, res, enc):
        progress.step(f"{study}: {label}")
        full = problem.full_record_error(res.sensors)
        rows.append({"study": study, "label": label, "n_sensors": enc.n_sensors, "seed": res.seed,
                     "sensors": " ".join(res.sensors), "window_error_ue": res.best_error, "full_record_error_ue": full,
                     "generations": int(res.logbook["generation"].iloc[-1]), "evaluations": res.evaluations,
                     "cache_hits": res.cache_hits, "seconds": float(res.logbook["seconds"].iloc[-1])})
        key = f"{study}-{label}".replace(" ", "_")
        draw(files, f"{key}:layout", notes, plot_layout, enc, res.best, os.path.join(out, f"{key}_layout.png"),
                                             f"{study} {label}: full record {full:.3f} µε",
                                             forces=parse_force_locations(problem.structure, problem.forces))
        draw(files, f"{key}:convergence", notes, plot_convergence, res.logbook, os.path.join(out, f"{key}_convergence.png"),
                                                       f"{study} {label}")
        return full

    # case 5: 3 gauges, 4 independent runs
    p5 = example_problem("th-case5")
    enc5 = p5.encoding()
    obj5 = p5.objective(enc5)
    runs, agreement = independent_runs(obj5, enc5, runs=2 if quick else 4, seed=seed, n_jobs=n_jobs, **ga)
    for r in runs:
        record("case 5", f"seed {r.seed}", p5, r, enc5)
    case2 = p5.full_record_error(p5.reference_layouts["TH case 2 (trial and error)"])
    rows.append({"study": "case 5", "label": "TH case 2 (trial and error)", "n_sensors": 3, "seed": None,
                 "sensors": " ".join(p5.reference_layouts["TH case 2 (trial and error)"]),
                 "window_error_ue": obj5.evaluate([p5.reference_layouts["TH case 2 (trial and error)"]])[0],
                 "full_record_error_ue": case2})
    write_csv(agreement, os.path.join(out, "case5_agreement.csv"))
    files["case5_agreement"] = os.path.join(out, "case5_agreement.csv")
    # case 6: 3, 4, 5, 8 gauges
    for n in ((3, 4) if quick else (3, 4, 5, 8)):
        p = example_problem("th-case6", n)
        enc = p.encoding()
        res = place(p.objective(enc), enc, seed=seed, n_jobs=n_jobs, **ga)
        record("case 6", f"{n} gauges", p, res, enc)
    # multi-metric: gauges + one accelerometer.  The 0.1 s window from rest holds only the dynamic
    # response, where an accelerometer looks better than over the whole record; a 1 s window
    # (which costs little more: the Riccati solve dominates) is compared for both sensor mixes.
    for window in (0.1, 1.0):
        for budget in ({"strain": 2, "acc": 1}, {"strain": 3, "acc": 1}, {"strain": 3}):
            if window == 0.1 and budget == {"strain": 3}:
                continue            # = case 5 above
            p = example_problem("th-multi")
            p.budget, p.window = budget, window
            if "acc" not in budget:
                p.kinds = STRAIN_KINDS
            enc = p.encoding()
            res = place(p.objective(enc), enc, seed=seed, n_jobs=n_jobs, **ga)
            mix = f"{budget['strain']} gauges" + (" + 1 acc" if "acc" in budget else "")
            record("multi-metric", f"{mix}, {window:g} s window", p, res, enc)
    # the thesis' operators as the baseline
    progress.step("operators: set-based vs thesis")
    ops = compare_operators(seeds=(seed,) if quick else (seed, seed + 1, seed + 2, seed + 3), n_jobs=n_jobs,
                            **({"population": 16, "generations": 6} if quick else {}))
    write_csv(ops, os.path.join(out, "operators.csv"))
    files["operators"] = os.path.join(out, "operators.csv")
    # Pareto: error vs number of gauges
    pp = example_problem("th-case6", 3)
    front = pareto(pp.objective(pp.encoding()), pp.structure, sizes=(1, 4 if quick else 8),
                   population=16 if quick else 60, generations=4 if quick else 40, seed=seed, n_jobs=n_jobs).front
    write_csv(front, os.path.join(out, "pareto_front.csv"))
    files["pareto_front"] = os.path.join(out, "pareto_front.csv")
    draw(files, "pareto", notes, plot_pareto, front, os.path.join(out, "pareto.png"))
    progress.step("Pareto front (NSGA-II)")
    table = pd.DataFrame(rows)
    summary = _summary(table, case2)
    files["summary"] = os.path.join(out, f"{NAME}_summary.csv")
    write_csv(summary, files["summary"])
    files["table"] = os.path.join(out, f"{NAME}.csv")
    write_csv(table, files["table"])
    log.info("TH placement: average strain error (µε) of the GA layouts; full record = 6 s, window = 0.1 s fitness")
    log.info(table[["study", "label", "sensors", "window_error_ue", "full_record_error_ue", "generations",
                 "evaluations", "seconds"]].round(4).to_string(index=False))
    log.info("summary (best layout per part, against TH case 2 and the thesis' numbers):")
    log.info(summary.round(4).to_string(index=False))
    log.info("case 5 agreement across runs:")
    log.info(agreement.round(4).to_string(index=False))
    log.info("set-based vs thesis operators (case 5):")
    log.info(ops.drop(columns=["sensors"]).round(4).to_string(index=False))
    log.info("Pareto front (NSGA-II, window error):")
    log.info(front.round(4).to_string(index=False))
    for note in notes:
        log.warning(f"  WARNING: {note}")
    return StudyResult(NAME, table, summary, files, {"front": front, "agreement": agreement})


def _summary(table, case2):
    """One row per part and sensor count: the best full-record error, its gain over TH case 2 and
    the thesis' published error and gain where it gives them."""
    import pandas as pd

    rows = []
    runs = table[table["label"] != "TH case 2 (trial and error)"]
    runs = runs.assign(part=runs["label"].where(runs["study"] != "case 5", "best of runs"))
    for (study, label), g in runs.groupby(["study", "part"], sort=False):
        best = g.loc[g["full_record_error_ue"].idxmin()]
        n = int(best["n_sensors"])
        published = PUBLISHED.get(n) if study in ("case 5", "case 6") else None
        rows.append({"study": study, "label": label, "n_sensors": n, "best_sensors": best["sensors"],
                     "full_record_error_ue": best["full_record_error_ue"],
                     "gain_over_case2": case2 / best["full_record_error_ue"],
                     "published_error": published,
                     "published_gain_over_case2": PUBLISHED["case 2 (trial and error)"] / published if published else None})
    return pd.DataFrame(rows)
