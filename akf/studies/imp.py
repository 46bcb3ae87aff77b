"""IMP studies behind ``akf study imp_cases`` and ``akf study imp_hit_rate``.

* ``imp_cases``: the paper's settings -- truss case 1 (strain AD) and case 2 (acceleration AD),
  each with absolute (1 µε, 1 mg) and 10 % relative noise, and the plate case -- through the
  whole identification (scan, covariance GA, reconstruction); one row per setting.
* ``imp_hit_rate``: impacts at *every* candidate node (and several noise seeds), located
  without tuning; one row per (example, node, seed) with the identified node, confidence and
  margin, and the hit rate per example.
"""
from __future__ import annotations

import logging
import os

import numpy as np

from core_akf.metrics import rms_error
from core_akf.outputs import write_csv
from impactloc.locate import locate
from impactloc.scan import candidate_locations

from ..examples import load_example
from ..examples.impact import EXAMPLES, example_scenario
from ..locating import write_outputs
from ._common import Progress, StudyResult, output_dir

log = logging.getLogger("akf")

SETTINGS = [("imp-truss-case1", "abs"), ("imp-truss-case1", "rel10"), ("imp-truss-case2", "abs"),
            ("imp-truss-case2", "rel10"), ("imp-plate", "abs"), ("imp-plate", "rel10")]


def _locate(sc, **kw):
    return locate(sc.structure, sc.sensors, sc.measurements, sc.dt, n_ad=sc.n_ad, ad_kinds=sc.ad_kinds,
                  direction=sc.direction, **kw)


def run_cases(out=None, quick=False, seed=0, n_jobs=1):
    """The paper's six settings, whole identification; writes ``imp_cases.csv`` and figures."""
    import pandas as pd

    out = output_dir("imp_cases", out)
    rows, files, data = [], {}, {}
    progress = Progress("imp_cases", len(SETTINGS))
    for name, noise in SETTINGS:
        progress.step(f"{name}, {noise} noise")
        sc = example_scenario(name, noise=noise, seed=seed)
        res = _locate(sc, seed=seed, n_jobs=n_jobs, max_splits=8 if quick else None,
                      tuning={"generations": 3, "population": 8} if quick else None)
        data[(name, noise)] = res
        f0, f1 = res.initial, res.reconstruction
        sim = sc.simulation
        rows.append({
            "example": name, "noise": noise, "true_node": sc.impact[0], "identified": res.identified[0],
            "confidence": res.scan.confidence, "margin": res.scan.margin, "n_splits": len(res.scan.splits),
            "n_locations": len(res.scan.locations),
            "ad_error_assumed": res.tuning.initial_error, "ad_error_tuned": res.tuning.tuned_error,
            "force_rms_error_assumed_N": rms_error(f0.force, sc.true_force),
            "force_rms_error_tuned_N": rms_error(f1.force, sc.true_force),
            "strain_error_assumed_ue": float(np.mean(rms_error(f0.estimate.strains, sim.strains))) * 1e6,
            "strain_error_tuned_ue": float(np.mean(rms_error(f1.estimate.strains, sim.strains))) * 1e6,
            "true_peak_N": float(sc.true_force.max()), "peak_N": f1.summary.peak,
            "seconds": res.seconds["total"]})
        sub = os.path.join(out, f"{name}-{noise}")
        for k, v in write_outputs(res, sub, sc).items():
            files[f"{name}-{noise}:{k}"] = v
    table = pd.DataFrame(rows)
    files["table"] = os.path.join(out, "imp_cases.csv")
    write_csv(table, files["table"])
    summary = (table.assign(hit=table["identified"] == table["true_node"])
               .groupby("example", sort=False)
               .agg(settings=("hit", "size"), hits=("hit", "sum"), min_confidence=("confidence", "min"),
                    mean_ad_error_assumed=("ad_error_assumed", "mean"), mean_ad_error_tuned=("ad_error_tuned", "mean"),
                    mean_force_rms_error_tuned_N=("force_rms_error_tuned_N", "mean"),
                    mean_seconds=("seconds", "mean"))
               .reset_index())
    files["summary"] = os.path.join(out, "imp_cases_summary.csv")
    write_csv(summary, files["summary"])
    log.info("IMP: impact localisation, paper settings (AD error: mean relative RMS error at the AD sensors)")
    log.info(table.drop(columns=["n_locations"]).round(4).to_string(index=False))
    log.info("summary per example:")
    log.info(summary.round(4).to_string(index=False))
    return StudyResult("imp_cases", table, summary, files, data)


def run_hit_rate(out=None, quick=False, seed=0, examples=None, seeds=None, n_jobs=1):
    """Impacts at every candidate node of each example (every third with ``quick``), two noise
    seeds (one with ``quick``); writes ``imp_hit_rate.csv``."""
    import pandas as pd

    out = output_dir("imp_hit_rate", out)
    seeds = seeds or ([seed] if quick else [seed, seed + 1])
    rows = []
    progress = Progress("imp_hit_rate", len(examples or EXAMPLES) * len(seeds))
    for name in examples or EXAMPLES:
        structure = example_scenario(name).structure
        nodes = [n for n, _ in candidate_locations(structure, load_example(name, "locate")["locate"]["direction"])]
        if quick:
            nodes = nodes[::3]
        for s in seeds:
            progress.step(f"{name}, seed {s}: impacts at {len(nodes)} nodes")
            for node in nodes:
                sc = example_scenario(name, impact_node=node, seed=s)
                res = _locate(sc, tune=False, seed=s, n_jobs=n_jobs, max_splits=8 if quick else None)
                second = res.scan.summary.iloc[1]
                rows.append({"example": name, "seed": s, "true_node": node, "identified": res.identified[0],
                             "hit": res.identified[0] == node, "confidence": res.scan.confidence,
                             "margin": res.scan.margin, "runner_up": int(second["node"]),
                             "peak_error": res.reconstruction.summary.peak / sc.true_force.max() - 1})
    table = pd.DataFrame(rows)
    summary = (table.groupby("example").agg(impacts=("hit", "size"), hits=("hit", "sum"),
                                            hit_rate=("hit", "mean"), min_margin_of_hits=("margin", "min"))
               .reset_index())
    files = {"table": os.path.join(out, "imp_hit_rate.csv"), "summary": os.path.join(out, "imp_hit_rate_summary.csv")}
    write_csv(table, files["table"])
    write_csv(summary, files["summary"])
    log.info("IMP: impacts at every candidate node, located without tuning")
    log.info(summary.round(3).to_string(index=False))
    misses = table[~table["hit"]]
    if len(misses):
        log.info("misses (true -> identified, confidence, margin):")
        log.info(misses[["example", "seed", "true_node", "identified", "confidence", "margin"]].round(3).to_string(index=False))
    return StudyResult("imp_hit_rate", table, summary, files)


class _Study:
    def __init__(self, name, description, fn):
        self.NAME, self.DESCRIPTION, self._fn = name, description, fn

    def run(self, out=None, quick=False, seed=0, n_jobs=1):
        return self._fn(out=out, quick=quick, seed=seed, n_jobs=n_jobs)


cases = _Study("imp_cases", "IMP impact localisation: truss cases 1-2 (abs / 10 % noise) and plate, scan + tuning",
               run_cases)
hit_rate = _Study("imp_hit_rate", "IMP: impacts at every candidate node and two seeds, hit rate per example",
                  run_hit_rate)
