"""Thesis plate study: strain estimation at every node of a cantilever plate from a few
sensors (TH cases 1-5).

======  ==============================================================  =====================
case    sensors                                                         errors
======  ==============================================================  =====================
1       accelerations (w) at nodes 12, 58, 100                          5 % model + 2 % noise
2       strains g_xy at 2, e_x at 58, g_xy at 100                       both
3a-3d   g_xy at 2 and 100 + acceleration at 12                          none / noise / model / both
4       e_x at 23, e_y at 103 ("arbitrary"; see below)                  both
5a-5d   flexible plate: case-2 set / case-3 set / g_xy 2 + acc 12 /     both
        g_xy at 2 and 100
======  ==============================================================  =====================

Choices the thesis leaves open (also in ``studies/README.md``):

* case 2's strain components appear only in a figure; we take the g_xy gauges at nodes 2 and
  100 that case 3 keeps, and e_x at node 58;
* case 4's accelerometer "at node 2" sits on the clamped edge (nodes 1-11), where it records
  exactly zero: the filter effectively gets the two strain gauges, which is what we run;
* case 5: the thesis lists 5a = three strains, 5b = two strains + one acceleration (its figure
  captions swap them); 5c = one strain + one acceleration we take as g_xy at 2 + acceleration
  at 12, 5d = two strains as g_xy at 2 and 100;
* load amplitudes of the band-limited noise and the covariance levels are ours (see
  :func:`akf.examples.th_job`); Q = 1e-16 per DOF and S = 1 N^2 for the stiff plate
  (the best of a grid for cases 2 and 3d), scaled with the 1000x smaller loads on the flexible
  plate.

The filter uses a modally reduced model (80 modes stiff plate, 150 modes flexible plate; the
tests show the 80-mode filter within 0.3 % of the full one); the simulation uses the full model.
Undetectable sets (cases 1 and 5c) run the time-varying filter, forced.
"""
from __future__ import annotations

import logging
import os

import numpy as np

from core_akf.figures import figure
from core_akf.outputs import write_csv

from ..estimate import estimate_job
from ..examples import TH_CASE1, TH_CASE2, TH_CASE3, TH_CASE4, TH_FLEXIBLE_PLATE, th_job
from ..job import Job
from ._common import Progress, StudyResult, drift_ratio, output_dir, psd, save

log = logging.getLogger("akf")

NAME = "th_plate"
DESCRIPTION = "TH plate: average strain error over all 363 components, cases 1, 2, 3a-d, 4, 5a-d"

#: published average strain errors ("micro-strain" in the thesis); None where it gives none
PUBLISHED = {"1": "diverges", "2": 0.00666, "3a": 0.00091, "3b": 0.00106, "3c": 0.00456, "3d": 0.00459,
             "4": "~1000 x case 3", "5a": 0.00118, "5b": 0.00125, "5c": 0.00923, "5d": 0.00125}

_STIFF = dict(model_error_cov=1e-16, force_increment_cov=1.0)
_FLEX = dict(structure=TH_FLEXIBLE_PLATE, load_scale=1e-3, model_error_cov=1e-12, force_increment_cov=1e-6)

#: case -> (description, sensors, model error, noise, job options)
CASES = {
    "1": ("accelerations at 12, 58, 100", TH_CASE1, True, True, _STIFF),
    "2": ("strains g_xy 2, e_x 58, g_xy 100", TH_CASE2, True, True, _STIFF),
    "3a": ("g_xy 2, g_xy 100, acc 12; no errors", TH_CASE3, False, False, _STIFF),
    "3b": ("g_xy 2, g_xy 100, acc 12; noise only", TH_CASE3, False, True, _STIFF),
    "3c": ("g_xy 2, g_xy 100, acc 12; model error only", TH_CASE3, True, False, _STIFF),
    "3d": ("g_xy 2, g_xy 100, acc 12; model error + noise", TH_CASE3, True, True, _STIFF),
    "4": ("arbitrary: e_x 23, e_y 103 (acc at clamped node 2 reads zero)", TH_CASE4, True, True, _STIFF),
    "5a": ("flexible plate, three strains (case-2 set)", TH_CASE2, True, True, _FLEX),
    "5b": ("flexible plate, two strains + acc (case-3 set)", TH_CASE3, True, True, _FLEX),
    "5c": ("flexible plate, g_xy 2 + acc 12", ["strain:2:gxy", "acc:12:w"], True, True, _FLEX),
    "5d": ("flexible plate, g_xy 2 and 100", ["strain:2:gxy", "strain:100:gxy"], True, True, _FLEX),
}

#: strain channels the thesis plots (histories at node 70 e_x and node 1 g_xy, spectrum at node 1)
CHANNELS = ("strain:70:ex", "strain:1:gxy")


def run_case(case, duration=6.0, seed=0, n_modes=None):
    """Run one thesis case; returns the :class:`~akf.estimate.EstimateResult`."""
    description, sensors, model_error, noise, options = CASES[case]
    job = th_job(f"th-{case}", description, sensors, model_error=model_error, noise=noise, **options)
    job["simulation"].update(duration=duration, seed=seed)
    flexible = options is _FLEX
    job["filter"]["n_modes"] = n_modes or (150 if flexible else 80)
    try:
        return estimate_job(Job.from_dict(job, "estimate"))
    except Exception as exc:  # undetectable: force the time-varying filter, as the thesis does
        from core_akf.checks import UndetectableError

        if not isinstance(exc, UndetectableError):
            raise
        return estimate_job(Job.from_dict(job, "estimate", overrides={"filter.allow_undetectable": True,
                                                                      "filter.steady": False}))


def run(out=None, quick=False, seed=0, cases=None):
    """Run the cases (all by default), write ``th_plate.csv`` (one row per case and strain
    component), ``th_plate_summary.csv`` and the figures, print the table."""
    import pandas as pd

    duration = 2.0 if quick else 6.0
    out = output_dir(NAME, out)
    results, rows, summary = {}, [], []
    progress = Progress(NAME, len(cases or CASES))
    for case in cases or CASES:
        progress.step(f"case {case}")
        res = run_case(case, duration, seed)
        results[case] = res
        est, sim = res.estimate, res.simulation
        labels = est.structure.strain_labels
        errors = np.array([res.metrics["rms_strain"][lab] for lab in labels])
        ref_rms = np.sqrt(np.mean(sim.strains ** 2, axis=0))
        rows.append(pd.DataFrame({"case": case, "component": labels, "rms_error_ue": errors * 1e6,
                                  "reference_rms_ue": ref_rms * 1e6}))
        drift = drift_ratio(est.strains - sim.strains)
        summary.append({"case": case, "description": CASES[case][0], "detectable": res.metrics["detectable"],
                        "filter": "steady-state" if est.gain is not None and res.metrics["detectable"] else "time-varying",
                        "avg_strain_error_ue": errors.mean() * 1e6, "max_strain_error_ue": errors.max() * 1e6,
                        "worst_component": labels[int(errors.argmax())], "median_drift_ratio": float(np.median(drift)),
                        "published_avg_error": PUBLISHED[case], "duration_s": duration})
    table = pd.concat(rows, ignore_index=True)
    summary = pd.DataFrame(summary)
    files = {"table": os.path.join(out, f"{NAME}.csv"), "summary": os.path.join(out, f"{NAME}_summary.csv")}
    write_csv(table, files["table"])
    write_csv(summary, files["summary"])
    _figures(results, table, out, files)
    log.info("TH plate: average strain error over all strain components (µε; thesis values in 'µ-strain')")
    log.info(summary[["case", "description", "detectable", "avg_strain_error_ue", "worst_component",
                   "median_drift_ratio", "published_avg_error"]].round(4).to_string(index=False))
    return StudyResult(NAME, table, summary, files, results)


def _figures(results, table, out, files):
    for case, res in results.items():
        est, sim = res.estimate, res.simulation
        labels = est.structure.strain_labels
        errs = table[table["case"] == case]["rms_error_ue"].to_numpy()
        fig = figure(figsize=(10, 6.5))
        ax = fig.add_subplot(3, 1, 1)
        ax.bar(np.arange(1, errs.size + 1), errs, width=1.0, color="tab:blue")
        ax.set_xlabel("strain component (e_x nodes 1-121, e_y, g_xy)")
        ax.set_ylabel("RMS error (µε)")
        ax.set_title(f"TH case {case}: {CASES[case][0]} -- average error {errs.mean():.4g} µε", fontsize=9)
        for k, ch in enumerate(CHANNELS):
            i = labels.index(ch)
            ax = fig.add_subplot(3, 2, 3 + k)
            ax.plot(est.time, sim.strains[:, i] * 1e6, "k:", lw=1, label="reference")
            ax.plot(est.time, est.strains[:, i] * 1e6, "r-", lw=0.6, label="AKF")
            ax.set_title(f"strain {ch}", fontsize=8)
            ax.set_xlabel("time (s)")
            ax.set_ylabel("µε")
            ax.legend(fontsize=6)
        i = labels.index("strain:1:gxy")
        ax = fig.add_subplot(3, 2, 6)
        for sig, style, lab in ((sim.strains[:, i], "k", "reference"), (est.strains[:, i], "r", "AKF")):
            f, p = psd(sig, est.dt)
            ax.loglog(f[1:], p[1:], style, lw=0.8, label=lab)
        ax.set_title("spectrum of g_xy at node 1", fontsize=8)
        ax.set_xlabel("frequency (Hz)")
        ax.legend(fontsize=6)
        ax = fig.add_subplot(3, 2, 5)
        ax.axis("off")
        ax.text(0, 0.5, "sensors: " + ", ".join(s.label for s in est.sensors), fontsize=8, wrap=True)
        save(fig, os.path.join(out, f"case{case}.png"), files, f"case{case}")
