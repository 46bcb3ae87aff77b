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
import os
from dataclasses import dataclass, field

import numpy as np

from core_akf import loads as L
from core_akf.akf import estimate
from core_akf.checks import check_memory
from core_akf.defaults import default
from core_akf.diagnostics import CONSISTENCY_LIMIT, force_statistics, scale_check, sensor_diagnostics, warnings_for
from core_akf.exceptions import AKFInputError
from core_akf.metrics import average_strain_error, rms_error
from core_akf.models import imp_plate, plate, s17_truss, th_plate
from core_akf.sensors import as_layout, parse_force_locations, selection_matrices
from core_akf.simulate import MG, MICROSTRAIN, simulate

from .schema import parse_job

MODELS = {"s17_truss": s17_truss, "th_plate": th_plate, "imp_plate": imp_plate, "plate": plate}
_LOADS = {
    "band_noise": lambda t, dt, c, seed: L.band_limited_white_noise(t.size, dt, c["rms"], c.get("f_low", 0.0), c.get("f_high"), seed),
    "white_noise": lambda t, dt, c, seed: L.white_noise(t.size, c["std"], seed),
    "pulse": lambda t, dt, c, seed: L.half_sine_pulse(t, c["start"], c["duration"], c["peak"]),
    "ramp": lambda t, dt, c, seed: L.ramp(t, c["start"], c["end"], c["peak"]),
    "half_sine": lambda t, dt, c, seed: L.half_sine(t, c["start"], c["end"], c["peak"]),
    "sine": lambda t, dt, c, seed: L.sine(t, c["frequency"], c["amplitude"], c.get("phase", 0.0)),
    "constant": lambda t, dt, c, seed: np.full(t.size, float(c["value"])),
}


def load_job(path: str | os.PathLike, command: str) -> dict:
    """A job file read (:func:`load_job_file`), checked against the schema for ``command``
    (:func:`akf.schema.parse_job`, messages name the file) and with its data paths made relative
    to the job file's folder: the one place where job-relative paths are resolved."""
    job = load_job_file(path)
    parse_job(job, command, source=path)
    meas = job.get("measurements")
    if isinstance(meas, dict) and isinstance(meas.get("file"), str) and not os.path.isabs(meas["file"]):
        meas["file"] = os.path.join(os.path.dirname(os.path.abspath(path)), meas["file"])
    return job


def load_job_file(path: str | os.PathLike) -> dict:
    """A job (dict) from a TOML file, with clear errors for a missing, folder or invalid file."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python < 3.11
        import tomli as tomllib
    if not os.path.exists(path):
        raise AKFInputError(f"job file {path!r} not found")
    if os.path.isdir(path):
        raise AKFInputError(f"job file {path!r} is a folder; give the TOML file")
    with open(path, "rb") as fh:
        try:
            return tomllib.load(fh)
        except tomllib.TOMLDecodeError as exc:
            raise AKFInputError(f"{path}: not valid TOML: {exc}") from None


def build_structure(spec):
    """A Structure from ``{"model": name, **arguments}``."""
    spec = dict(spec)
    name = spec.pop("model", None)
    if not isinstance(name, str) or name not in MODELS:
        raise AKFInputError(f"structure.model must be one of {sorted(MODELS)}, got {name!r}")
    try:
        return MODELS[name](**spec)
    except AKFInputError:
        raise
    except (TypeError, ValueError) as exc:
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


#: a time stamp may lie off the uniform grid ``t_0 + k dt`` by this fraction of a step (a time
#: column rounded to 6 decimals is off by <= 5e-7 s: 0.2 % of a step at 4 kHz)
_TIME_GRID_RTOL = 0.01

#: a strain channel whose RMS exceeds this (m/m) is not in SI units: 1 % is five times the yield
#: strain of structural steel, far beyond the elastic range every model here assumes
_MAX_PLAUSIBLE_STRAIN = 0.01


def read_measurements(path, sensors, dt, time_column="time"):
    """Measured data (N x m, SI) from CSV or Parquet: a time column and one column per sensor label.

    Checks, each with a message naming the file, column and row: the file exists and is a file;
    it parses and has data rows; every column is numeric and finite; time stamps increase and lie
    on the grid ``t_0 + k dt`` (within :data:`_TIME_GRID_RTOL` of a step); no channel is constant
    (a disconnected or saturated sensor); strain channels are plausible in m/m.
    """
    import pandas as pd

    path = os.fspath(path)
    if not os.path.exists(path):
        raise AKFInputError(f"measurement file {path!r} not found")
    if os.path.isdir(path):
        raise AKFInputError(f"measurement file {path!r} is a folder; give the data file (CSV or Parquet)")
    if str(path).endswith((".parquet", ".pq")):
        try:
            df = pd.read_parquet(path)
        except ImportError as exc:
            raise AKFInputError(f"reading Parquet needs pyarrow ({exc}); pip install pyarrow, or give a CSV file") from None
        except Exception as exc:  # noqa: BLE001 -- pyarrow raises its own error types
            raise AKFInputError(f"{path}: not a readable Parquet file ({type(exc).__name__}: {exc})") from None
    else:
        try:
            df = pd.read_csv(path)
        except pd.errors.EmptyDataError:
            raise AKFInputError(f"{path}: the file is empty; expected a header row and one row per time step") from None
        except (pd.errors.ParserError, UnicodeDecodeError) as exc:
            raise AKFInputError(f"{path}: not a readable CSV file ({exc})") from None
    layout = as_layout(sensors)
    labels = [s.label for s in layout]
    missing = [c for c in [time_column] + labels if c not in df.columns]
    if missing:
        raise AKFInputError(f"{path}: missing column(s) {missing}; found {list(df.columns)}")
    if len(df) < 2:
        raise AKFInputError(f"{path}: {len(df)} data row(s); a record needs at least two time steps")
    for col in [time_column] + labels:
        values = pd.to_numeric(df[col], errors="coerce")
        bad = np.flatnonzero(values.isna().to_numpy())
        if bad.size:
            r = int(bad[0])
            raise AKFInputError(f"{path}: column {col!r} has {bad.size} missing/NaN or non-numeric sample(s); first "
                                f"{str(df[col].iloc[r])!r} in data row {r + 1}")
        df[col] = values
    t = df[time_column].to_numpy(float)
    Y = df[labels].to_numpy(float)
    inf = np.argwhere(~np.isfinite(np.column_stack([t, Y])))
    if inf.size:
        r, c = inf[0]
        raise AKFInputError(f"{path}: infinite value in column {([time_column] + labels)[c]!r}, data row {r + 1}")
    steps = np.diff(t)
    if np.any(steps <= 0):
        r = int(np.flatnonzero(steps <= 0)[0])
        what = "repeats" if steps[r] == 0 else "goes back"
        raise AKFInputError(f"{path}: time {what} at data row {r + 2} (t = {t[r + 1]:.9g} s after "
                            f"t = {t[r]:.9g} s in row {r + 1}); time stamps must increase by dt")
    median = float(np.median(steps))
    if abs(median - dt) > _TIME_GRID_RTOL * dt:
        raise AKFInputError(f"{path}: sampling interval {median:.9g} s (median step) does not match the job's "
                            f"dt = {dt:.9g} s ({median / dt:.4g} x dt)")
    off = np.abs(t - t[0] - dt * np.arange(t.size))
    if np.max(off) > _TIME_GRID_RTOL * dt:
        r = int(np.argmax(off > _TIME_GRID_RTOL * dt))
        raise AKFInputError(
            f"{path}: data row {r + 1} (t = {t[r]:.9g} s) is {off[r]:.3g} s ({off[r] / dt:.3g} steps) off the "
            f"uniform grid t0 + k dt (dt = {dt:.9g} s): the record has a gap or jitter there")
    for j, s in enumerate(layout):
        col = Y[:, j]
        if np.ptp(col) == 0:
            raise AKFInputError(f"{path}: channel {labels[j]!r} is constant ({col[0]:.9g}) over the whole record: "
                                "a disconnected, saturated or unmapped sensor gives no information; remove it from "
                                "the job's sensors")
        if s.kind == "strain":
            level = float(np.sqrt(np.mean(col ** 2)))
            if level > _MAX_PLAUSIBLE_STRAIN:
                raise AKFInputError(
                    f"{path}: strain channel {labels[j]!r} has an RMS of {level:.4g}, impossible in m/m (SI) for an "
                    f"elastic structure (> {_MAX_PLAUSIBLE_STRAIN:g}); it looks like microstrain: divide the column "
                    "by 1e6")
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
        idx = range(len(labels)) if channels is None else est.structure.strain_label_index(channels)
        strains = est.strains
        ref = self.simulation.strains if self.simulation is not None else None
        frames = [pd.DataFrame({"time": est.time, "quantity": "strain", "channel": labels[i], "unit": "m/m",
                                "estimated": strains[:, i], "reference": ref[:, i] if ref is not None else np.nan})
                  for i in idx]
        return pd.concat(frames, ignore_index=True)

    def summary_frame(self):
        """One row per channel: every force location (estimated RMS and peak, and the RMS error
        against the reference if there is one), every sensor (measured RMS and the innovation
        statistics of :mod:`core_akf.diagnostics`) and, with a reference, every strain output (RMS
        error).  Never empty: measured data without a reference still has forces and sensors."""
        import pandas as pd

        m = self.metrics
        errors = m.get("rms_force", {})
        rows = [dict(quantity="force", **f, rms_error=errors.get(f["channel"], np.nan)) for f in m.get("forces", [])]
        rows += [dict(quantity="sensor", channel=d["channel"], unit=d["unit"], rms=d["measured_rms"],
                      **{k: v for k, v in d.items() if k not in ("channel", "unit", "measured_rms")})
                 for d in m.get("sensors", [])]
        rows += [{"quantity": "strain", "channel": k, "unit": "m/m", "rms_error": v}
                 for k, v in m.get("rms_strain", {}).items()]
        columns = ["quantity", "channel", "unit", "rms_error", "rms", "peak", "time_of_peak", "innovation_rms",
                   "predicted_innovation_std", "consistency", "whiteness", "lag1_autocorrelation"]
        return pd.DataFrame(rows, columns=columns)


#: units of the numbers in :attr:`JobResult.metrics` (and the CLI's JSON)
METRIC_UNITS = {"rms_force": "N", "rms_strain": "m/m", "avg_strain_error": "m/m", "avg_strain_error_microstrain": "µε",
                "forces": {"rms": "N", "peak": "N", "time_of_peak": "s"},
                "sensors": "per channel: the sensor's SI unit (m/m, m/s^2, m/s, m); consistency and whiteness "
                           "are dimensionless"}


def simulate_job(job, per_step=None, structure=None):
    """Simulate the measurements of a job with a ``[simulation]`` section: the true structure
    (built from ``[structure]`` unless given), its sensors, the forces at ``forces`` with the
    loads of ``[[simulation.loads]]`` and the noise of ``relative_noise`` / ``absolute_noise``.

    ``per_step``: float64 values held per time step by the caller, to refuse a record that would
    not fit in memory before it is allocated.  Returns ``(structure, force locations,
    Simulation)``."""
    structure = build_structure(job["structure"]) if structure is None else structure
    sensors = as_layout(job["sensors"])
    forces = parse_force_locations(structure, job["forces"])
    sp = job["simulation"]
    dt = float(job["dt"])
    if sp.get("duration") is None:
        raise AKFInputError("[simulation] needs a positive duration (s)")
    n_steps = float(sp["duration"]) / dt
    per_step = per_step or (2 * 2 * structure.n + structure.n_strain + 2 * len(sensors))
    check_memory(n_steps, per_step, f"a {sp['duration']:g} s record at dt = {dt:g} s",
                 "shorten [simulation] duration (CLI: --duration) or check dt")
    n_steps = int(round(n_steps))
    if n_steps < 2:
        raise AKFInputError(f"[simulation] duration {sp['duration']:g} s is shorter than two steps of dt = {dt:g} s")
    loads = build_loads(sp.get("loads", []), n_steps, dt, len(forces))
    absolute = _absolute_noise(sp["absolute_noise"]) if "absolute_noise" in sp else None
    sim = simulate(structure, sensors, forces, loads, dt, relative_noise=sp.get("relative_noise"),
                   absolute_noise=absolute, seed=sp.get("seed", 0))
    return structure, forces, sim


def run_job(job: dict, allow_undetectable: bool | None = None, steady: bool | None = None) -> JobResult:
    """Run an estimation job (a dict as read from TOML, see the module docstring and
    :mod:`akf.schema`); ``steady`` and ``allow_undetectable`` override the job's ``[filter]``."""
    job = copy.deepcopy(job)
    spec = parse_job(job, "estimate")
    if spec.simulation is None and spec.measurements is None:
        raise AKFInputError("the job needs a [simulation] or a [measurements] section")
    dt = spec.dt
    true_structure = build_structure(job["structure"])
    filt = spec.filter
    steady = filt.steady if steady is None else steady     # None: core_akf.defaults, steady where it exists
    allow_undetectable = bool(filt.allow_undetectable if allow_undetectable is None else allow_undetectable)
    model = true_structure.scaled(default("stiffness_factor", filt.stiffness_factor))
    if filt.reduce_modes:
        model = model.reduce(filt.reduce_modes)
    sensors = as_layout(job["sensors"])
    selection_matrices(true_structure, sensors)      # every sensor exists on this structure
    forces = parse_force_locations(true_structure, job["forces"])

    # float64 values held per time step: simulated states, filter states and their products
    # (about 4 copies of the augmented state), strains of the truth and the estimate, channels
    n_a = 2 * model.n + len(forces)
    per_step = 4 * n_a + 2 * 2 * true_structure.n + 3 * true_structure.n_strain + 4 * len(sensors)
    sim = None
    if spec.measurements is not None:
        meas = spec.measurements
        if meas.file is None:
            raise AKFInputError("[measurements] needs file = 'data.csv'")
        Y = read_measurements(meas.file, sensors, dt, meas.time_column or "time")
    else:
        _, _, sim = simulate_job(job, per_step, true_structure)
        Y = sim.measurements

    noise_cov = "simulated" if filt.noise_cov is None else filt.noise_cov
    if isinstance(noise_cov, str):
        if sim is None:
            raise AKFInputError("filter.noise_cov = 'simulated' needs a simulated job; give variances per sensor kind")
        noise_cov = np.diag(np.maximum(sim.noise_std, default("noise_floor")) ** 2)
    est_kw = dict(model_error_cov=default("model_error_cov", filt.model_error_cov),
                  force_increment_cov=default("force_increment_cov", filt.force_increment_cov))
    est = estimate(model, sensors, forces, Y, dt, noise_cov=noise_cov, steady=steady,
                   allow_undetectable=allow_undetectable, **est_kw)
    metrics = {"detectable": est.detectability.detectable, "n_steps": int(Y.shape[0]), "units": METRIC_UNITS}
    if sim is not None:
        rf = rms_error(est.forces, sim.loads)
        metrics["rms_force"] = {f"{n}:{d}": float(v) for (n, d), v in zip(forces, rf)}
        rs = rms_error(est.strains, sim.strains)
        metrics["rms_strain"] = dict(zip(true_structure.strain_labels, map(float, rs)))
        metrics["avg_strain_error"] = float(average_strain_error(est.strains, sim.strains))
        metrics["avg_strain_error_microstrain"] = metrics["avg_strain_error"] / MICROSTRAIN
    metrics["forces"] = force_statistics(est)
    metrics["sensors"] = sensor_diagnostics(est)
    metrics["warnings"] = warnings_for(est, metrics["sensors"])
    if est.detectability.detectable and any(d["consistency"] > CONSISTENCY_LIMIT for d in metrics["sensors"]):
        # some channel does not fit: find out whether a unit or a sign is wrong
        metrics["warnings"] = scale_check(model, sensors, forces, Y, dt, model_error_cov=est_kw["model_error_cov"],
                                          force_increment_cov=est_kw["force_increment_cov"],
                                          noise_cov=noise_cov) + metrics["warnings"]
    return JobResult(job=job, estimate=est, simulation=sim, metrics=metrics)
