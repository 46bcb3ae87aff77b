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
from core_akf.models import footbridge, from_files, imp_plate, plate, s17_truss, th_plate
from core_akf.sensors import as_layout, parse_force_locations, selection_matrices
from core_akf.simulate import MG, MICROSTRAIN, simulate

from .schema import parse_job

MODELS = {"s17_truss": s17_truss, "th_plate": th_plate, "imp_plate": imp_plate, "plate": plate, "footbridge": footbridge,
          "matrices": from_files}
#: the keys of a ``model = "matrices"`` structure that name files (relative to the job file)
MATRIX_FILES = ("K", "M", "C", "dofs", "nodes", "strains", "extensometers")
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
    return resolve_paths(job, path)


def resolve_paths(job: dict, path: str | os.PathLike) -> dict:
    """The data paths of a job (its record, its model's files) made relative to the job file at
    ``path`` (in place; returns ``job``)."""
    here = os.path.dirname(os.path.abspath(path))
    meas = job.get("measurements")
    if isinstance(meas, dict) and isinstance(meas.get("file"), str) and not os.path.isabs(meas["file"]):
        meas["file"] = os.path.join(here, meas["file"])
    structure = job.get("structure")
    if isinstance(structure, dict) and structure.get("model") == "matrices":
        for k in MATRIX_FILES:
            if isinstance(structure.get(k), str) and not os.path.isabs(structure[k]):
                structure[k] = os.path.join(here, structure[k])
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
        raw = fh.read()
    try:
        return tomllib.loads(job_text(raw, path))
    except tomllib.TOMLDecodeError as exc:
        raise AKFInputError(f"{path}: not valid TOML: {exc}") from None


def job_text(raw: bytes, path) -> str:
    """The text of a job file: UTF-8, with or without a byte-order mark; any other encoding is an
    error that names it (UTF-16 from a Windows editor, Latin-1 / Windows-1252, or not text)."""
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]                               # UTF-8 with a BOM (Windows Notepad): the same text
    for bom, name in ((b"\xff\xfe\x00\x00", "UTF-32"), (b"\x00\x00\xfe\xff", "UTF-32"), (b"\xff\xfe", "UTF-16"),
                      (b"\xfe\xff", "UTF-16")):
        if raw.startswith(bom):
            raise AKFInputError(f"{path}: the job file is {name} text; TOML job files are UTF-8: save it as UTF-8 "
                                "(in Notepad: Save as, Encoding UTF-8)")
    if b"\x00" in raw:
        odd, even = raw[1::2].count(0), raw[0::2].count(0)
        if max(odd, even) > len(raw) // 4:
            raise AKFInputError(f"{path}: the job file looks like UTF-16 text without a byte-order mark; TOML job files "
                                "are UTF-8: save it as UTF-8")
        raise AKFInputError(f"{path}: not a text file (it holds NUL bytes); a job file is TOML text in UTF-8")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        guess = raw.decode("cp1252", errors="replace").splitlines()[line - 1] if line else ""
        raise AKFInputError(f"{path}: line {line} is not UTF-8 (byte 0x{raw[exc.start]:02x}); the file looks like "
                            f"Latin-1 / Windows-1252 text ({guess.strip()[:60]!r}): save it as UTF-8") from None


def build_structure(spec):
    """A Structure from ``{"model": name, **arguments}``."""
    spec = dict(spec)
    name = spec.pop("model", None)
    if not isinstance(name, str) or name not in MODELS:
        raise AKFInputError(f"structure.model must be one of {sorted(MODELS)}, got {name!r}")
    if name == "matrices":
        missing = [k for k in ("K", "M", "dofs", "nodes") if k not in spec]
        if missing:
            raise AKFInputError(f"[structure] model = \"matrices\" needs {', '.join(missing)} (files of K, M, the DOF map "
                                "and the node coordinates)")
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


def read_measurements(path, sensors, dt, time_column="time", **channel_map):
    """Measured data (N x m, SI) of ``sensors`` from a file, folder or glob pattern in any format
    :mod:`core_akf.io` reads, with the sampling interval checked against ``dt`` (s).
    ``channel_map``: the keys of :class:`core_akf.io.Record` (channels, units, gauge_factor,
    bridge, invert, remove_offset, format, group)."""
    from core_akf.io import Record

    record = Record(path, sensors, time_column=time_column, **channel_map)
    if record.n_steps < 2:
        raise AKFInputError(f"{record.files[0]}: {record.n_steps} data row(s); a record needs at least two time steps")
    record.check_dt(dt)
    return record.read()[1]


def open_record(meas, sensors):
    """The :class:`core_akf.io.Record` of a job's ``[measurements]`` (a :class:`akf.schema.Measurements`)."""
    from core_akf.io import Record

    if meas.file is None:
        raise AKFInputError("[measurements] needs file = 'data.csv' (a file, a folder or a glob pattern)")
    return Record(meas.file, sensors, channels=meas.channels, units=meas.units, gauge_factor=meas.gauge_factor,
                  bridge=meas.bridge, invert=meas.invert or (), remove_offset=meas.remove_offset or False,
                  format=meas.format, time_column=meas.time_column or "time", group=meas.group)


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
        if not frames:          # a model without strain outputs (point sensors on a model of one's own)
            return pd.DataFrame(columns=["time", "quantity", "channel", "unit", "estimated", "reference"])
        return pd.concat(frames, ignore_index=True)

    def summary_frame(self):
        """One row per channel (:func:`summary_frame` of the metrics)."""
        return summary_frame(self.metrics)


def summary_frame(metrics):
    """One row per channel of a job's metrics: every force location (estimated RMS and peak, and
    the RMS error against the reference if there is one), every sensor (measured RMS and the
    innovation statistics of :mod:`core_akf.diagnostics`) and, with a reference, every strain
    output (RMS error).  Never empty: measured data without a reference still has forces and sensors."""
    import pandas as pd

    m = metrics
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
    if filt.n_modes:
        model = model.reduce(filt.n_modes, static_correction=True)
    sensors = as_layout(job["sensors"])
    selection_matrices(true_structure, sensors)      # every sensor exists on this structure
    forces = parse_force_locations(true_structure, job["forces"])

    # float64 values held per time step: simulated states, filter states and their products
    # (about 4 copies of the augmented state), strains of the truth and the estimate, channels
    n_a = 2 * model.n + len(forces)
    per_step = 4 * n_a + 2 * 2 * true_structure.n + 3 * true_structure.n_strain + 4 * len(sensors)
    sim = None
    if spec.measurements is not None:
        record = open_record(spec.measurements, sensors)
        record.check_dt(dt)
        check_memory(record.n_steps, per_step, f"the record of {record.n_steps} steps",
                     "use akf estimate (it streams measured records in chunks) or core_akf.streaming.Estimator")
        Y = record.read()[1]
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
        if true_structure.n_strain:       # a model of one's own may have no strain outputs
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
