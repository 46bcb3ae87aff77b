"""Locate jobs: impact localisation from a job file (measured data), and the output files.

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

import os

from core_akf.exceptions import AKFInputError
from core_akf.outputs import write_csv

from .schema import parse_job


def run_locate_job(job, n_jobs=1, seed=0, progress=False, tune=None):
    """Run a locate job (a dict from TOML, see :mod:`akf.schema`; a relative data path is taken
    from the working folder: :func:`akf.jobs.load_job` makes it relative to the job file);
    returns the :class:`~impactloc.locate.LocateResult`."""
    from core_akf.sensors import selection_matrices
    from impactloc.locate import locate
    from impactloc.scan import Covariances

    from .jobs import build_structure, simulate_job
    from .streaming import open_record

    spec = parse_job(job, "locate")
    structure = build_structure(job["structure"])
    selection_matrices(structure, spec.sensors)     # every sensor exists on this structure
    meas = spec.measurements
    if meas is not None:
        record = open_record(meas, spec.sensors)
        record.check_dt(spec.dt)
        Y = record.read()[1]
    elif spec.simulation is not None:
        if spec.forces is None:
            raise AKFInputError("a simulated locate job needs forces = ['NODE:DIR'] (where the impact hits)")
        Y = simulate_job(job, structure=structure)[2].measurements
    else:
        raise AKFInputError("the locate job needs a [measurements] section (or a [simulation] to try the method)")
    loc = spec.locate
    c = loc.covariances
    covariances = None if c is None else Covariances(c.model_error, c.force_increment, dict(c.noise))
    tuning = None if loc.tuning is None else loc.tuning.model_dump(exclude_none=True)
    return locate(structure, spec.sensors, Y, spec.dt, n_ad=loc.n_ad, direction=loc.direction,
                  ad_kinds=tuple(loc.ad_kinds or ["strain"]), candidates=loc.candidates, covariances=covariances,
                  tune=(True if loc.tune is None else loc.tune) if tune is None else tune, max_splits=loc.max_splits,
                  n_modes=None if loc.n_modes == "full" else (loc.n_modes or "auto"), skip=loc.skip or 0.0,
                  n_jobs=n_jobs, seed=seed, progress=progress, tuning=tuning)


def write_outputs(result, out, scenario=None, plot=True):
    """Write ranking.csv, scan.csv, force.csv, response.csv, tuning.csv and the figures; returns {name: path}."""
    import pandas as pd

    from impactloc.locate import plot_locate

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


