"""S17 truss study: force estimation with acceleration-only, strain-only and multi-metric
sensors (Khodabandeloo et al. 2017, cases 1-4 and the four configurations of Fig. 20).

Cases (loads vertical at joints 4, 6, 8, 12; see :mod:`akf.examples` for the amplitudes):

======  ======================================================  =========================
case    sensors                                                 loads / errors
======  ======================================================  =========================
1a      accelerations only (10 vertical + 4 horizontal)         zero-mean; no errors
1b      accelerations only                                      zero-mean; 5 % model, 2 % noise
2a      accelerations only                                      slow + non-zero-mean; no errors
2b      accelerations only                                      slow + non-zero-mean; errors
3       strains only (members 4, 5, 9, 12, 13, 16, 21, 24, 26)  slow; errors
4       multi-metric = set 1 (Fig. 20a)                         slow; errors
set2-4  other multi-metric configurations (Fig. 20b-d)          slow; errors
======  ======================================================  =========================

The acceleration-only cases are not detectable (PBH at s = 0): they run with the time-varying
filter, forced.  The others use the steady-state filter.

Configurations of Fig. 20 (the paper shows them only as a drawing; ours follow its idea,
"sensors close to the force locations estimate those forces better"):

* set 1 (= case 4): accelerometers at all four loaded joints (+ horizontal at 6), strain gauges
  in verticals 5, 9, 13, 26;
* set 2: as set 1 but the accelerometer at the loaded joint 12 moved to joint 16 (far from 12);
* set 3: everything at the loads: accelerometers as set 1, gauges in the verticals at the loaded
  joints (9 at joint 4, 13 at 6, 17 at 8, 22 at 12);
* set 4: away from the loads: accelerometers at joints 2, 10, 14, 16 (+ horizontal at 10),
  gauges in verticals 5, 19, 26 and bottom chord 14 (between loaded joints 6 and 8).  With
  vertical 30 instead of chord 14 the set is *undetectable*: the self-equilibrated load group
  f4 - 2 f6 + f8 strains only the members between joints 4 and 8, so no static sensor sees it.
"""
from __future__ import annotations

import logging
import os

import numpy as np

from core_akf.figures import subplots
from core_akf.outputs import write_csv

from ..estimate import estimate_job
from ..examples import S17_ACC_ONLY, S17_MULTI, S17_STRAIN_ONLY, s17_job
from ..job import Job
from ._common import Progress, StudyResult, drift_ratio, output_dir, psd, save

log = logging.getLogger("akf")

NAME = "s17_truss"
DESCRIPTION = "S17 truss: force RMS error per case and load, Fig. 19-21 configurations, force spectra"

SETS = {
    "set2": ["acc:4:y", "acc:6:y", "acc:8:y", "acc:16:y", "acc:6:x", "strain:5", "strain:9", "strain:13", "strain:26"],
    "set3": ["acc:4:y", "acc:6:y", "acc:8:y", "acc:12:y", "acc:6:x", "strain:9", "strain:13", "strain:17", "strain:22"],
    "set4": ["acc:2:y", "acc:10:y", "acc:14:y", "acc:16:y", "acc:10:x", "strain:5", "strain:14", "strain:19", "strain:26"],
}

#: case -> (description, sensors, slow loads, errors)
CASES = {
    "1a": ("accelerations only, zero-mean loads, no errors", S17_ACC_ONLY, False, False),
    "1b": ("accelerations only, zero-mean loads, 5 % model error + 2 % noise", S17_ACC_ONLY, False, True),
    "2a": ("accelerations only, slow/non-zero-mean loads, no errors", S17_ACC_ONLY, True, False),
    "2b": ("accelerations only, slow/non-zero-mean loads, 5 % model error + 2 % noise", S17_ACC_ONLY, True, True),
    "3": ("strains only (members 4, 5, 9, 12, 13, 16, 21, 24, 26), errors", S17_STRAIN_ONLY, True, True),
    "4": ("multi-metric, set 1 = Fig. 20a (acc at the loads, gauges 5, 9, 13, 26), errors", S17_MULTI, True, True),
    "set2": ("multi-metric, set 2: accelerometer at 12 moved to 16, errors", SETS["set2"], True, True),
    "set3": ("multi-metric, set 3: all sensors at the loaded joints, errors", SETS["set3"], True, True),
    "set4": ("multi-metric, set 4: sensors away from the loads (one chord gauge between 6 and 8), errors", SETS["set4"], True, True),
}


def run_case(case, duration=2.0, seed=0):
    """Run one S17 case; returns the :class:`~akf.estimate.EstimateResult`."""
    description, sensors, slow, errors = CASES[case]
    job = s17_job(f"s17-{case}", description, sensors, slow=slow, model_error=errors, noise=errors)
    job["simulation"].update(duration=duration, seed=seed)
    acc_only = all(s.startswith("acc") for s in sensors)
    forced = {"filter.allow_undetectable": True, "filter.steady": False} if acc_only else {}
    return estimate_job(Job.from_dict(job, "estimate", overrides=forced))


def run(out=None, quick=False, seed=0, cases=None):
    """Run the cases (all by default), write ``s17_truss.csv`` and the figures, print the table."""
    import pandas as pd

    duration = 1.0 if quick else 2.0
    out = output_dir(NAME, out)
    results, rows = {}, []
    progress = Progress(NAME, len(cases or CASES))
    for case in cases or CASES:
        progress.step(f"case {case}")
        res = run_case(case, duration, seed)
        results[case] = res
        est, sim = res.estimate, res.simulation
        drift = drift_ratio(est.forces - sim.loads)
        for j, load in enumerate(res.metrics["rms_force"]):
            rows.append({"case": case, "description": CASES[case][0], "load": load,
                         "detectable": res.metrics["detectable"],
                         "filter": "steady-state" if est.gain is not None else "time-varying",
                         "rms_error_N": res.metrics["rms_force"][load], "reference_rms_N": float(np.sqrt(np.mean(sim.loads[:, j] ** 2))),
                         "drift_ratio": float(drift[j]), "avg_strain_error_ue": res.metrics["avg_strain_error"] * 1e6,
                         "duration_s": duration})
    table = pd.DataFrame(rows)
    summary = (table.groupby("case", sort=False)
               .agg(mean_rms_error_N=("rms_error_N", "mean"), max_drift_ratio=("drift_ratio", "max"),
                    avg_strain_error_ue=("avg_strain_error_ue", "first"), detectable=("detectable", "first"))
               .reset_index())
    files = {"table": os.path.join(out, f"{NAME}.csv"), "summary": os.path.join(out, f"{NAME}_summary.csv")}
    write_csv(table, files["table"])
    write_csv(summary, files["summary"])
    _figures(results, table, out, files)
    _report(table, summary)
    return StudyResult(NAME, table, summary, files, results)


def _report(table, summary):
    wide = table.pivot(index="case", columns="load", values="rms_error_N").reindex(summary["case"])
    log.info("S17 truss: RMS force error (N) per case and load (eq. 38)")
    log.info(wide.round(1).to_string())
    log.info(summary.round(3).to_string(index=False))


def _figures(results, table, out, files):
    loads = list(dict.fromkeys(table["load"]))
    # Fig. 19/21: RMS error per case and load
    for key, cases, title in (("fig19_rms", ["1b", "2b", "3", "4"], "acceleration only vs strain only vs multi-metric"),
                              ("fig21_configs", ["4", "set2", "set3", "set4"], "multi-metric configurations (set 1 = case 4)")):
        cases = [c for c in cases if c in results]
        if not cases:
            continue
        fig, ax = subplots(figsize=(7, 3.5))
        w = 0.8 / len(cases)
        for i, c in enumerate(cases):
            vals = table[table["case"] == c].set_index("load").loc[loads, "rms_error_N"]
            ax.bar(np.arange(len(loads)) + i * w, vals, w, label=f"case {c}")
        ax.set_xticks(np.arange(len(loads)) + 0.4 - w / 2, [f"joint {l.split(':')[0]}" for l in loads])
        ax.set_yscale("log")
        ax.set_ylabel("RMS force error (N)")
        ax.set_title(f"S17: {title}", fontsize=9)
        ax.legend(fontsize=7)
        save(fig, os.path.join(out, f"{key}.png"), files, key)
    # force histories, estimated vs applied (Figs. 8-17, 22)
    for case, res in results.items():
        est, sim = res.estimate, res.simulation
        fig, axes = subplots(len(loads), 1, figsize=(8, 1.8 * len(loads)), sharex=True)
        for j, ax in enumerate(np.atleast_1d(axes)):
            ax.plot(est.time, sim.loads[:, j] / 1e3, "k:", lw=1, label="applied")
            ax.plot(est.time, est.forces[:, j] / 1e3, "r-", lw=0.7, label="AKF")
            ax.set_ylabel(f"joint {loads[j].split(':')[0]}\n(kN)")
        np.atleast_1d(axes)[0].legend(fontsize=7, loc="upper right")
        np.atleast_1d(axes)[0].set_title(f"S17 case {case}: {CASES[case][0]}", fontsize=9)
        np.atleast_1d(axes)[-1].set_xlabel("time (s)")
        save(fig, os.path.join(out, f"forces_case{case}.png"), files, f"forces_case{case}")
    # Figs. 12 and 18: spectra at joints 4 and 12
    cases = [c for c in ("2a", "2b", "3", "4") if c in results]
    if cases:
        fig, axes = subplots(1, 2, figsize=(9, 3.5))
        for ax, joint in zip(axes, ("4:y", "12:y")):
            j = loads.index(joint)
            ref = results[cases[0]].simulation
            n = ref.loads.shape[0]  # one segment: the slow loads need the finest resolution
            f, p = psd(ref.loads[:, j], results[cases[0]].estimate.dt, nperseg=n)
            ax.loglog(f[1:], p[1:], "k", lw=1.2, label="applied")
            for c in cases:
                f, p = psd(results[c].estimate.forces[:, j], results[c].estimate.dt, nperseg=n)
                ax.loglog(f[1:], p[1:], lw=0.8, label=f"case {c}")
            ax.set_title(f"force spectrum, joint {joint.split(':')[0]}", fontsize=9)
            ax.set_xlabel("frequency (Hz)")
            ax.set_ylabel("PSD (N²/Hz)")
            ax.legend(fontsize=7)
        save(fig, os.path.join(out, "spectra_joints_4_12.png"), files, "spectra")
