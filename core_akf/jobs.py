"""Estimation jobs: one structure, sensors, force locations, filter settings and either a
simulated scenario or measured data -- from a TOML file or a built-in example.

A job file (TOML)::

    name = "my-truss"
    dt = 0.000244140625            # s
    sensors = ["acc:4:y", "strain:5"]
    forces = ["4:y"]

    [structure]
    model = "s17_truss"            # s17_truss | th_plate | imp_plate | plate (with its arguments)

    [filter]
    stiffness_factor = 1.05        # the filter's model is 5 % stiffer than the true one
    model_error_cov = 1e-16        # Q level
    force_increment_cov = 1e5      # S level, N^2 per step
    noise_cov = "simulated"        # R from the simulated noise, or {strain = 1e-14, acc = 1e-2}
    steady = true

    [simulation]                   # or [measurements] file = "data.csv" (time + one column per sensor)
    duration = 2.0
    relative_noise = 0.02
    seed = 0
    [[simulation.loads]]           # one table per force location, summing its components
    components = [{type = "band_noise", rms = 500, f_high = 200, seed = 1}]
"""
from __future__ import annotations

import copy
import difflib
import os
from dataclasses import dataclass, field

import numpy as np

from . import loads as L
from .akf import estimate
from .exceptions import AKFInputError
from .metrics import average_strain_error, rms_error
from .models import imp_plate, plate, s17_truss, th_plate
from .sensors import as_layout, parse_force_locations
from .simulate import MG, MICROSTRAIN, simulate

_MODELS = {"s17_truss": s17_truss, "th_plate": th_plate, "imp_plate": imp_plate, "plate": plate}
_LOADS = {
    "band_noise": lambda t, dt, c, seed: L.band_limited_white_noise(t.size, dt, c["rms"], c.get("f_low", 0.0), c.get("f_high"), seed),
    "white_noise": lambda t, dt, c, seed: L.white_noise(t.size, c["std"], seed),
    "pulse": lambda t, dt, c, seed: L.half_sine_pulse(t, c["start"], c["duration"], c["peak"]),
    "ramp": lambda t, dt, c, seed: L.ramp(t, c["start"], c["end"], c["peak"]),
    "half_sine": lambda t, dt, c, seed: L.half_sine(t, c["start"], c["end"], c["peak"]),
    "sine": lambda t, dt, c, seed: L.sine(t, c["frequency"], c["amplitude"], c.get("phase", 0.0)),
    "constant": lambda t, dt, c, seed: np.full(t.size, float(c["value"])),
}


def build_structure(spec):
    """A Structure from ``{"model": name, **arguments}``."""
    spec = dict(spec)
    name = spec.pop("model", None)
    if name not in _MODELS:
        raise AKFInputError(f"structure.model must be one of {sorted(_MODELS)}, got {name!r}")
    try:
        return _MODELS[name](**spec)
    except TypeError as exc:
        raise AKFInputError(f"bad arguments for structure model {name!r}: {exc}") from None


def build_loads(load_specs, n_steps, dt, n_forces):
    """Load histories (N, n_p) from one ``{"components": [...]}`` spec per force location."""
    if len(load_specs) != n_forces:
        raise AKFInputError(f"simulation.loads has {len(load_specs)} entries for {n_forces} force locations")
    t = L.time_grid(n_steps, dt)
    out = np.zeros((n_steps, n_forces))
    for j, spec in enumerate(load_specs):
        for c in spec.get("components", []):
            kind = c.get("type")
            if kind not in _LOADS:
                raise AKFInputError(f"unknown load type {kind!r}; use one of {sorted(_LOADS)}")
            try:
                out[:, j] += _LOADS[kind](t, dt, c, c.get("seed"))
            except KeyError as exc:
                raise AKFInputError(f"load {kind!r} for force {j + 1} needs parameter {exc}") from None
    return out


#: unit suffixes accepted in absolute noise levels: key -> (sensor kind, factor to SI)
_NOISE_UNITS = {"strain": ("strain", 1.0), "microstrain": ("strain", MICROSTRAIN), "acc": ("acc", 1.0),
                "acc_mg": ("acc", MG), "vel": ("vel", 1.0), "disp": ("disp", 1.0)}


def _absolute_noise(spec):
    """Absolute noise standard deviations per sensor kind in SI from a job's table, e.g.
    ``{microstrain = 1, acc_mg = 1}`` -> ``{"strain": 1e-6, "acc": 9.8e-3}``."""
    out = {}
    for key, value in spec.items():
        if key not in _NOISE_UNITS:
            raise AKFInputError(f"absolute_noise: unknown key {key!r}; use {sorted(_NOISE_UNITS)}")
        kind, factor = _NOISE_UNITS[key]
        out[kind] = float(value) * factor
    return out


def read_measurements(path, sensors, dt, time_column="time"):
    """Measured data from CSV or Parquet: a time column and one column per sensor label.

    Checks the sampling interval against ``dt`` and rejects missing columns and NaN samples.
    """
    import pandas as pd

    if not os.path.exists(path):
        raise AKFInputError(f"measurement file {path!r} not found")
    if str(path).endswith((".parquet", ".pq")):
        try:
            df = pd.read_parquet(path)
        except ImportError as exc:
            raise AKFInputError(f"reading Parquet needs pyarrow or fastparquet ({exc}); "
                                "pip install pyarrow, or give a CSV file") from None
    else:
        df = pd.read_csv(path)
    labels = [s.label for s in as_layout(sensors)]
    missing = [c for c in [time_column] + labels if c not in df.columns]
    if missing:
        raise AKFInputError(f"{path}: missing column(s) {missing}; found {list(df.columns)}")
    t = df[time_column].to_numpy(float)
    if t.size < 2:
        raise AKFInputError(f"{path}: fewer than two samples")
    steps = np.diff(t)
    if np.any(~np.isfinite(steps)) or np.max(np.abs(steps - dt)) > 1e-6 * dt + 1e-9:
        raise AKFInputError(f"{path}: sampling interval {np.median(steps):.6g} s does not match the job's dt = {dt:.6g} s")
    Y = df[labels].to_numpy(float)
    bad = np.argwhere(~np.isfinite(Y))
    if bad.size:
        r, c = bad[0]
        raise AKFInputError(f"{path}: {len(bad)} missing/NaN sample(s); first in column {labels[c]!r} at t = {t[r]:.6g} s")
    return Y


@dataclass
class JobResult:
    """Outcome of :func:`run_job`: the estimate, the simulation (if any) and metrics."""

    job: dict
    estimate: object
    simulation: object = None
    metrics: dict = field(default_factory=dict)

    def force_frame(self):
        """Tidy forces: one row per (time, force location)."""
        import pandas as pd

        est = self.estimate
        frames = []
        for j, (node, d) in enumerate(est.force_locations):
            ref = self.simulation.loads[:, j] if self.simulation is not None else np.nan
            frames.append(pd.DataFrame({"time": est.time, "quantity": "force", "channel": f"{node}:{d}",
                                        "unit": "N", "estimated": est.forces[:, j], "reference": ref}))
        return pd.concat(frames, ignore_index=True)

    def strain_frame(self, channels=None):
        """Tidy strains: one row per (time, strain channel); ``channels`` a list of labels (default all)."""
        import pandas as pd

        est = self.estimate
        labels = est.structure.strain_labels
        unknown = [c for c in (channels or []) if c not in labels]
        if unknown:
            raise AKFInputError(f"unknown strain channel(s) {unknown}; labels look like {labels[0]!r}, {labels[-1]!r}")
        idx = range(len(labels)) if channels is None else [labels.index(c) for c in channels]
        strains = est.strains
        ref = self.simulation.strains if self.simulation is not None else None
        frames = [pd.DataFrame({"time": est.time, "quantity": "strain", "channel": labels[i], "unit": "m/m",
                                "estimated": strains[:, i], "reference": ref[:, i] if ref is not None else np.nan})
                  for i in idx]
        return pd.concat(frames, ignore_index=True)

    def summary_frame(self):
        """One row per channel (forces and strains) with the RMS error against the reference."""
        import pandas as pd

        rows = []
        for k, v in self.metrics.get("rms_force", {}).items():
            rows.append({"quantity": "force", "channel": k, "unit": "N", "rms_error": v})
        for k, v in self.metrics.get("rms_strain", {}).items():
            rows.append({"quantity": "strain", "channel": k, "unit": "m/m", "rms_error": v})
        return pd.DataFrame(rows)


#: the keys a job may hold, per section (None: the top level)
JOB_KEYS = {
    None: {"name", "description", "dt", "sensors", "forces", "structure", "filter", "simulation",
           "measurements", "output"},
    "filter": {"stiffness_factor", "reduce_modes", "model_error_cov", "force_increment_cov", "noise_cov",
               "steady", "allow_undetectable"},
    "simulation": {"duration", "relative_noise", "absolute_noise", "seed", "loads"},
    "measurements": {"file", "time_column"},
    "output": {"strains"},
}


def check_keys(table, allowed, where):
    """Reject a key of ``table`` not in ``allowed``, naming the closest allowed one: a typo must
    not silently fall back to a default."""
    for key in table:
        if key not in allowed:
            hint = difflib.get_close_matches(key, allowed, n=1)
            raise AKFInputError(f"unknown key {key!r} in {where}"
                                + (f"; did you mean {hint[0]!r}?" if hint else f"; allowed: {sorted(allowed)}"))


def check_sections(job, keys, kind="job"):
    """:func:`check_keys` on the top level (``keys[None]``) and on each section of a job."""
    if not isinstance(job, dict):
        raise AKFInputError(f"a {kind} is a table of settings (a dict)")
    for section, allowed in keys.items():
        table = job if section is None else job.get(section, {})
        if not isinstance(table, dict):
            raise AKFInputError(f"[{section}] must be a table")
        check_keys(table, allowed, f"the {kind}" if section is None else f"[{section}]")


def validate_job(job):
    """Reject unknown keys (a typo must not silently fall back to a default) and missing ones."""
    check_sections(job, JOB_KEYS)
    for key in ("dt", "sensors", "forces", "structure"):
        if key not in job:
            raise AKFInputError(f"the job has no {key!r}")


def run_job(job, allow_undetectable=None, steady=None):
    """Run an estimation job (a dict as read from TOML, see the module docstring)."""
    job = copy.deepcopy(job)
    validate_job(job)
    dt = float(job["dt"])
    true_structure = build_structure(job["structure"])
    filt = dict(job.get("filter", {}))
    if steady is not None:
        filt["steady"] = steady
    if allow_undetectable is not None:
        filt["allow_undetectable"] = allow_undetectable
    model = true_structure.scaled(float(filt.get("stiffness_factor", 1.0)))
    if filt.get("reduce_modes"):
        model = model.reduce(int(filt["reduce_modes"]))
    sensors = as_layout(job["sensors"])
    forces = parse_force_locations(true_structure, job["forces"])

    sim = None
    if "measurements" in job:
        meas = job["measurements"]
        Y = read_measurements(meas["file"], sensors, dt, meas.get("time_column", "time"))
    elif "simulation" in job:
        sp = job["simulation"]
        if "duration" not in sp or not float(sp["duration"]) > 0:
            raise AKFInputError("[simulation] needs a positive duration (s)")
        n_steps = int(round(float(sp["duration"]) / dt))
        loads = build_loads(sp.get("loads", []), n_steps, dt, len(forces))
        absolute = _absolute_noise(sp["absolute_noise"]) if "absolute_noise" in sp else None
        sim = simulate(true_structure, sensors, forces, loads, dt, relative_noise=sp.get("relative_noise"),
                       absolute_noise=absolute, seed=sp.get("seed", 0))
        Y = sim.measurements
    else:
        raise AKFInputError("the job needs a [simulation] or a [measurements] section")

    noise_cov = filt.get("noise_cov", "simulated")
    if isinstance(noise_cov, str):
        if noise_cov != "simulated" or sim is None:
            raise AKFInputError("filter.noise_cov = 'simulated' needs a simulated job; give variances per sensor kind")
        noise_cov = np.diag(np.maximum(sim.noise_std, 1e-30) ** 2)
    est = estimate(model, sensors, forces, Y, dt, model_error_cov=filt.get("model_error_cov", 1e-16),
                   force_increment_cov=filt.get("force_increment_cov", 1.0), noise_cov=noise_cov,
                   steady=bool(filt.get("steady", True)), allow_undetectable=bool(filt.get("allow_undetectable", False)))
    metrics = {"detectable": est.detectability.detectable, "n_steps": int(Y.shape[0])}
    if sim is not None:
        rf = rms_error(est.forces, sim.loads)
        metrics["rms_force"] = {f"{n}:{d}": float(v) for (n, d), v in zip(forces, rf)}
        rs = rms_error(est.strains, sim.strains)
        metrics["rms_strain"] = dict(zip(true_structure.strain_labels, map(float, rs)))
        metrics["avg_strain_error"] = float(average_strain_error(est.strains, sim.strains))
    return JobResult(job=job, estimate=est, simulation=sim, metrics=metrics)
