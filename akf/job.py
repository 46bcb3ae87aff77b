"""A job, read once: one structure, its sensors and unknown forces, the filter's settings and a
simulated scenario or measured data, from a TOML file or a built-in example, for one command.

:func:`load_job` (a file) or :meth:`Job.from_dict` (a dict) checks it against the schema
(:mod:`akf.schema`) once, makes its data paths relative to the job file and applies every
default once: the runners (:func:`akf.estimate.estimate_job`, :func:`akf.locating.run_locate_job`,
:func:`akf.placement.problem_from_job`) take the :class:`Job` and resolve nothing again.

>>> from akf.examples import example
>>> job = example("s17-case4", overrides={"simulation.duration": 0.5})
>>> job.command, job.stiffness_factor, job.n_modes, job.steady
('estimate', 1.05, None, True)

An estimate job file (TOML)::

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
import inspect
import os
import warnings
from collections.abc import Mapping
from functools import cached_property

import numpy as np

from core_akf import loads as L
from core_akf.checks import AKFInputError, check_memory
from core_akf.covariances import noise_covariance
from core_akf.defaults import default
from core_akf.forcemodels import DummyMeasurements, ForceModel
from core_akf.models import footbridge, from_files, imp_plate, plate, s17_truss, th_plate
from core_akf.sensors import (
    MAX_READABLE,
    SENSOR_NAMES,
    UNITS,
    as_layout,
    parse_force_locations,
    readable_limits,
    selection_matrices,
)
from core_akf.simulate import MG, MICROSTRAIN, check_noise, simulate

from .schema import Job as JobSpec
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


def load_job(path: str | os.PathLike, command: str, overrides: dict | None = None) -> Job:
    """The job file at ``path`` for ``command`` ("estimate", "place", "locate"): read
    (:func:`load_job_file`), its data paths made relative to the file's folder, ``overrides``
    applied (see :meth:`Job.from_dict`) and checked once against the schema (messages name the
    file).  Returns a :class:`Job`."""
    return Job.from_dict(load_job_file(path), command, source=os.fspath(path), overrides=overrides)


def data_path_keys(job) -> list[tuple[str, str]]:
    """The ``(section, key)`` of every data path a job dict (or a parsed TOML document) holds: its
    record's ``[measurements] file`` and the files of a ``model = "matrices"`` structure."""
    keys = []
    meas = job.get("measurements")
    if isinstance(meas, Mapping) and isinstance(meas.get("file"), str):
        keys.append(("measurements", "file"))
    structure = job.get("structure")
    if isinstance(structure, Mapping) and structure.get("model") == "matrices":
        keys += [("structure", k) for k in MATRIX_FILES if isinstance(structure.get(k), str)]
    return keys


def resolve_paths(job: dict, base: str | os.PathLike) -> dict:
    """The data paths of a job dict (its record, its model's files) made relative to the folder
    ``base`` (in place; returns ``job``): the one place where job-relative paths are resolved."""
    here = os.path.abspath(base)
    for section, k in data_path_keys(job):
        if not os.path.isabs(job[section][k]):
            job[section][k] = os.path.join(here, job[section][k])
    return job


#: the largest force standard deviation a job may give (N): a giga-newton load is a typing slip
MAX_FORCE_STD = 1e9
#: a force time scale may be this many times below the time step (shorter is white noise at this rate)
TIMESCALE_BELOW_DT = 1e3
#: ... and at most this long (s): about three years, far beyond any record
MAX_TIMESCALE = 1e8


#: the largest model-error variance a job may give (m^2 or rad^2 per step at every DOF: 3 cm per
#: step): beyond it a typing slip (1e-2 on S17 ended in a failed steady-state gain, 1e6 took 30 s
#: of Riccati solvers on the plate and gave forces of 1e-5 N)
MAX_MODEL_ERROR_COV = 1e-3


#: a factor on the model's stiffness (or on a mode's frequency, squared) beyond this either way
#: makes another structure, not a calibration of this one: a typing slip (1e-12 ended in "the
#: innovation covariance is not positive definite", 1e12 in a failed steady-state gain)
MAX_STIFFNESS_FACTOR = 100.0


def check_stiffness_factors(stiffness, frequencies=(), key="[filter] stiffness_factor"):
    """``stiffness_factor`` (one or a list) and ``frequency_factors`` checked to within
    :data:`MAX_STIFFNESS_FACTOR` of 1 (frequency factors squared), named by their key."""
    for value in np.atleast_1d(np.asarray(stiffness, float)):
        if not 1 / MAX_STIFFNESS_FACTOR <= value <= MAX_STIFFNESS_FACTOR:
            raise AKFInputError(f"{key} = {value:.4g} multiplies the model's stiffness (1.05: 5 % "
                                f"stiffer) and every frequency by its square root ({np.sqrt(value):.3g}x): a model "
                                f"that far off is another structure; give a factor between {1 / MAX_STIFFNESS_FACTOR:g} "
                                f"and {MAX_STIFFNESS_FACTOR:g}")
    for k, value in enumerate(np.atleast_1d(np.asarray(frequencies, float)), start=1):
        if not 1 / MAX_STIFFNESS_FACTOR <= value ** 2 <= MAX_STIFFNESS_FACTOR:
            raise AKFInputError(f"[filter] frequency_factors[{k - 1}] = {value:.4g} multiplies mode {k}'s frequency: a "
                                "mode that far off is another structure; give a factor between "
                                f"{MAX_STIFFNESS_FACTOR ** -0.5:g} and {MAX_STIFFNESS_FACTOR ** 0.5:g}")


def check_covariance_levels(model_error_cov, force_increment_cov, section="[filter]"):
    """``model_error_cov`` (m^2 per step) and ``force_increment_cov`` (N^2 per step) of a job
    checked against what a structure can take (:data:`MAX_MODEL_ERROR_COV`; a giga-newton step,
    :data:`MAX_FORCE_STD` squared), so that a mistyped level is named by its key instead of failing
    in the Riccati solver; a level that is no number is left to the filter's checks."""
    for key, value, top, unit, step, typical in (
            ("model_error_cov", model_error_cov, MAX_MODEL_ERROR_COV, "m^2 per step at every DOF", "m", "1e-16 to 1e-8"),
            ("force_increment_cov", force_increment_cov, MAX_FORCE_STD ** 2, "N^2 per step", "N", "1e2 to 1e8")):
        try:
            big = np.max(np.abs(np.asarray(value, float)), initial=0.0)
        except (TypeError, ValueError):
            continue
        if big > top:
            raise AKFInputError(f"{section} {key} = {big:.4g} {unit} (a step of {np.sqrt(big):.3g} {step} at one standard "
                                f"deviation) is beyond what a structure takes (at most {top:g}): a typing slip? "
                                f"Typical levels are {typical}")


def check_force_prior(std, timescale, dt):
    """A Matérn prior's ``force_std`` (N) and ``force_timescale`` (s), checked against what a
    record can resolve: a time scale between ``dt / 1000`` and ~3 years, a standard deviation up
    to 1 GN, so that a mistyped value is named by its key instead of failing inside the filter."""
    for value in np.atleast_1d(np.asarray(std, float)):
        if not value <= MAX_FORCE_STD:
            raise AKFInputError(f"[filter] force_std = {value:.4g} N is beyond any load (at most {MAX_FORCE_STD:g} N); "
                                "give the forces' standard deviation in N, e.g. 500.0")
    for value in np.atleast_1d(np.asarray(timescale, float)):
        if not value >= (dt or 0.0) / TIMESCALE_BELOW_DT:
            raise AKFInputError(f"[filter] force_timescale = {value:.4g} s is far below the time step ({dt:.4g} s): the "
                                "record cannot resolve it; give the loads' correlation time in s, about the time step "
                                "or longer (e.g. 0.005)")
        if not value <= MAX_TIMESCALE:
            raise AKFInputError(f"[filter] force_timescale = {value:.4g} s is beyond any record (at most "
                                f"{MAX_TIMESCALE:g} s); give the loads' correlation time in s (e.g. 0.005)")


#: a noise standard deviation above this share of what a sensor reads (:data:`MAX_READABLE`: 0.01
#: m/m of strain, 1e4 m/s^2) is no sensor's noise but a variance typed in other units
NOISE_SHARE_OF_RANGE = 0.01


def check_noise_within_reach(sensors, noise_cov):
    """Refuse a ``[filter] noise_cov`` whose standard deviation for a sensor is above
    :data:`NOISE_SHARE_OF_RANGE` of what such a sensor reads (:data:`core_akf.sensors.MAX_READABLE`):
    a variance typed in other units (0.5 for a strain gauge, 1e9 for an accelerometer), which the
    filter would take as "this channel says nothing".

    Parameters
    ----------
    sensors : list of Sensor
    noise_cov : dict, float, list or matrix
        As ``[filter] noise_cov`` (SI units squared).
    """
    variances = np.diag(noise_covariance(sensors, noise_cov))
    beyond = np.flatnonzero(variances > (NOISE_SHARE_OF_RANGE * readable_limits(sensors)) ** 2)
    if beyond.size:
        s, var = sensors[beyond[0]], float(variances[beyond[0]])
        raise AKFInputError(f"[filter] noise_cov of {s.label} is {var:.4g} ({UNITS[s.kind]})^2, a standard deviation of "
                            f"{np.sqrt(var):.4g} {UNITS[s.kind]}, above {NOISE_SHARE_OF_RANGE:.0%} of what "
                            f"{SENSOR_NAMES[s.kind]} reads ({MAX_READABLE[s.kind]:g} {UNITS[s.kind]}): noise_cov is a "
                            "variance in SI units squared "
                            f"(a noise of {_TYPICAL_NOISE[s.kind]})")


#: a typical noise of a sensor kind and its variance in SI units squared (messages)
_TYPICAL_NOISE = {"strain": "1 microstrain is 1e-12", "acc": "10 mg is 0.0096", "vel": "1 mm/s is 1e-6",
                  "disp": "1 mm is 1e-6"}


class Job:
    """A job parsed once for one command, with every default applied once.

    Build it with :func:`load_job` (a file) or :meth:`from_dict` (a dict as read from TOML, for
    instance a built-in example from :func:`akf.examples.load_example`); the runners
    (:func:`akf.estimate.estimate_job`, :func:`akf.locating.run_locate_job`,
    :func:`akf.placement.problem_from_job`) take a :class:`Job`.

    Attributes
    ----------
    spec : akf.schema.Job
        The validated job (pydantic), paths resolved; its sections hold the keys as written.
    command : str
        "estimate", "place" or "locate".
    source : str or None
        The job file (None for a job built from a dict).
    name, description : str
        The job's name (default: the file's stem, else the command) and free text.
    dt : float
        Time step (s).
    stiffness_factor : float
        The filter's stiffness relative to the true structure: ``[filter] stiffness_factor`` or
        the command's default (``stiffness_factor`` for estimate, ``placement_stiffness_factor``
        for place; :data:`core_akf.defaults.DEFAULTS`).
    model_error_cov, force_increment_cov
        Q and S levels (``[filter]`` or the defaults registry).
    steady : bool or None
        The filter form; None: the steady-state filter where the sensor set is detectable.
    allow_undetectable : bool
        Run even if the PBH test fails.
    frequency_factors : list of float
        Factors on the filter model's frequencies of modes 1..k (empty: none).
    calibrate : list of str
        The ``[filter]`` keys to learn from the record (:mod:`core_akf.calibration`); empty: none.
    calibrate_modes : list of int or None
        The modes whose frequencies ``calibrate = ["frequencies"]`` learns (None: the default).
    smooth : bool
        Smooth the estimate (:mod:`core_akf.filter.smoother`).
    smooth_lag : float, "auto" or None
        The smoother's lag (s); None: the whole record when it is held in one piece, "auto" when
        it is filtered in chunks.
    calibrate_window : float or None
        Calibrate on the record's first this many seconds (None: the whole record, at most one
        chunk).
    calibrate_method : str
        The likelihood that learns a stationary force prior (``method`` of
        :func:`core_akf.calibration.calibrate`): "auto", "time" or "whittle".
    calibrate_held : str
        What calibration does with a held covariance level the record rejects (``held`` of
        :func:`core_akf.calibration.calibrate`): "learn" or "warn".
    force_model : ForceModel
        The forces' prior (``[filter] force_model``, ``force_std``, ``force_timescale``; the
        random walk of :attr:`force_increment_cov` by default).
    dummy : DummyMeasurements or None
        ``[filter] dummy``.
    n_modes : int, "auto" or None
        Modes kept in the filter's model (with a static correction); None: the full model.
        estimate: ``[filter] n_modes``; place and locate: ``[place]`` / ``[locate] n_modes``
        ("full" -> None, default "auto").
    """

    def __init__(self, spec: JobSpec, command: str, source: str | None = None, structure=None):
        self.spec, self.command, self.source = spec, command, source
        #: the record's length was set from outside the job (--duration): loads it leaves out are meant
        self.duration_overridden = False
        self.name = str(spec.name or (os.path.splitext(os.path.basename(source))[0] if source else command))
        self.description = spec.description or ""
        self.dt = float(spec.dt) if spec.dt is not None else None
        f = spec.filter
        self.stiffness_factor = default("placement_stiffness_factor" if command == "place" else "stiffness_factor",
                                        f.stiffness_factor)
        self.model_error_cov = default("model_error_cov", f.model_error_cov)
        self.force_increment_cov = default("force_increment_cov", f.force_increment_cov)
        check_covariance_levels(self.model_error_cov, self.force_increment_cov)
        self.steady = f.steady
        self.allow_undetectable = bool(f.allow_undetectable)
        self.frequency_factors = list(f.frequency_factors or [])
        check_stiffness_factors(self.stiffness_factor, self.frequency_factors)
        self.calibrate = list(f.calibrate or [])
        self.calibrate_modes = f.calibrate_modes
        self.smooth = bool(f.smooth)
        self.smooth_lag = f.smooth_lag
        if self.smooth_lag is not None and not self.smooth:
            raise AKFInputError("[filter] smooth_lag is the lag of the smoother: set smooth = true as well, or remove it")
        self.calibrate_window = f.calibrate_window
        self.calibrate_method = f.calibrate_method or "auto"
        self.calibrate_held = f.calibrate_held or "warn"
        self.force_model = self._force_model(f)
        self.dummy = None if f.dummy is None else DummyMeasurements(f.dummy.sensors, f.dummy.variance)
        section = {"place": spec.place, "locate": spec.locate}.get(command)
        if command == "estimate":
            self.n_modes = f.n_modes
        else:
            modes = getattr(section, "n_modes", None)
            self.n_modes = None if modes == "full" else (modes or "auto")
        self._structure = structure

    def _force_model(self, f):
        """The :class:`~core_akf.forcemodels.ForceModel` of ``[filter]``, its keys checked together."""
        kind = f.force_model or "random_walk"
        if kind != "butterworth" and (f.force_band is not None or f.force_band_order is not None):
            raise AKFInputError("[filter] force_band and force_band_order belong to the Butterworth force model: set "
                                "force_model = \"butterworth\", or remove them")
        if kind == "random_walk":
            if f.force_std is not None or f.force_timescale is not None:
                raise AKFInputError("[filter] force_std and force_timescale belong to a Matérn force model: set "
                                    "force_model = \"matern32\" (or matern12, matern52), or remove them")
            return ForceModel("random_walk", increment_cov=self.force_increment_cov, hold=f.load_hold or "zero")
        if f.force_increment_cov is not None:
            raise AKFInputError(f"[filter] force_increment_cov is the random walk's S; force_model = \"{kind}\" takes "
                                "force_std (N) and force_timescale (s) instead: remove force_increment_cov")
        if kind == "butterworth":
            return self._butterworth(f)
        if f.force_std is None or f.force_timescale is None:
            raise AKFInputError(f"[filter] force_model = \"{kind}\" needs force_std (N) and force_timescale (s), e.g. "
                                "force_std = 500.0 and force_timescale = 0.005")
        n_p = len(self.spec.forces or [])
        for name in ("force_std", "force_timescale"):
            value = getattr(f, name)
            if isinstance(value, list) and len(value) not in (1, n_p):
                raise AKFInputError(f"[filter] {name} has {len(value)} values for {n_p} forces: give one, or one per force")
        std, ell = (v[0] if isinstance(v, list) and len(v) == 1 else v for v in (f.force_std, f.force_timescale))
        check_force_prior(std, ell, self.dt)
        return ForceModel(kind, std=std, timescale=ell, hold=f.load_hold or "zero")

    def _butterworth(self, f):
        """The Butterworth force model of ``[filter]``: ``force_std``, ``force_band`` below Nyquist, an order 2-8."""
        if f.force_timescale is not None:
            raise AKFInputError("[filter] force_timescale belongs to a Matérn force model; force_model = \"butterworth\" "
                                "takes force_band = [f_low, f_high] (Hz) instead")
        if f.force_std is None or f.force_band is None:
            raise AKFInputError("[filter] force_model = \"butterworth\" needs force_std (N) and force_band = [f_low, "
                                "f_high] (Hz), e.g. force_std = 500.0 and force_band = [0.0, 120.0]")
        n_p = len(self.spec.forces or [])
        if isinstance(f.force_std, list) and len(f.force_std) not in (1, n_p):
            raise AKFInputError(f"[filter] force_std has {len(f.force_std)} values for {n_p} forces: give one, or one per force")
        std = f.force_std[0] if isinstance(f.force_std, list) and len(f.force_std) == 1 else f.force_std
        check_force_prior(std, [], self.dt)
        low, high = f.force_band
        if not low < high:
            raise AKFInputError(f"[filter] force_band = {f.force_band} must be [f_low, f_high] with f_low < f_high (Hz)")
        if self.dt and not high < 0.5 / self.dt:
            raise AKFInputError(f"[filter] force_band reaches {high:g} Hz, at or above the Nyquist frequency "
                                f"{0.5 / self.dt:.4g} Hz of dt = {self.dt:g} s: give f_high below it")
        order = 4 if f.force_band_order is None else f.force_band_order
        if order not in range(2, 9):
            raise AKFInputError(f"[filter] force_band_order = {order} must be an integer from 2 to 8")
        return ForceModel("butterworth", std=std, band=(float(low), float(high)), band_order=int(order),
                          hold=f.load_hold or "zero")

    @classmethod
    def from_dict(cls, data: dict, command: str, *, source: str | os.PathLike | None = None,
                  overrides: dict | None = None) -> Job:
        """A :class:`Job` from a dict as read from TOML (copied, never changed).

        ``source``: the job file it came from; relative data paths are taken from its folder
        (without it, from the working folder) and messages name it.  ``overrides``: values that
        replace keys before the job is checked, ``{"simulation.duration": 2.0, "filter.steady":
        False}`` (dotted ``table.key``; a table that is absent is created)."""
        data = copy.deepcopy(data)
        if not isinstance(data, dict):
            return cls(parse_job(data, command, source=source), command)       # parse_job names the problem
        for dotted, value in (overrides or {}).items():
            *tables, key = dotted.split(".")
            table = data
            for t in tables:
                table = table.setdefault(t, {})
                if not isinstance(table, dict):
                    raise AKFInputError(f"[{t}] of the job is not a table; cannot set {dotted}")
            table[key] = value
        source = None if source is None else os.fspath(source)
        if source is not None:
            resolve_paths(data, os.path.dirname(os.path.abspath(source)))
        job = cls(parse_job(data, command, source=source), command, source)
        job.duration_overridden = "simulation.duration" in (overrides or {})
        return job

    def to_dict(self) -> dict:
        """The job as written (the keys set, after renames and path resolution): a dict for TOML or JSON."""
        return self.spec.model_dump(mode="json", exclude_unset=True)

    # ------------------------------------------------------------------ what the runners build
    @property
    def structure(self):
        """The true structure of ``[structure]`` (built on first use)."""
        if self._structure is None:
            self._structure = build_structure(self.spec.structure.model_dump())
        return self._structure

    @cached_property
    def sensors(self):
        """The sensor layout (tuple of :class:`core_akf.sensors.Sensor`), checked against the structure."""
        layout = as_layout(self.spec.sensors)
        selection_matrices(self.structure, layout)       # every sensor exists on this structure
        return layout

    @cached_property
    def forces(self):
        """The unknown force locations as 1-based ``(node, direction)`` pairs, checked against the structure."""
        return parse_force_locations(self.structure, self.spec.forces)

    def filter_model(self):
        """The filter's model: the structure with :attr:`stiffness_factor` and
        :attr:`frequency_factors`, reduced to
        :attr:`n_modes` (an int) with a static correction."""
        model = self.structure.scaled(self.stiffness_factor)
        if self.frequency_factors:
            model = model.with_frequency_factors(self.frequency_factors)
        if isinstance(self.n_modes, int):
            model = model.reduce(self.n_modes, static_correction=True)
        return model

    def noise_cov(self, simulation=None):
        """R: ``[filter] noise_cov``; "simulated" (the default) is the true noise of ``simulation``
        (floored at :data:`core_akf.defaults.DEFAULTS` ``noise_floor``), which measured data lack."""
        value = "simulated" if self.spec.filter.noise_cov is None else self.spec.filter.noise_cov
        if not isinstance(value, str):
            if self.spec.sensors:
                check_noise_within_reach(self.sensors, value)
            return value
        if simulation is None:
            raise AKFInputError("[filter] noise_cov = \"simulated\" (the default) needs a simulated job: measured data need "
                                "the noise variances: [filter] noise_cov = {strain = ..., acc = ...} (SI units squared) or "
                                "one variance per sensor")
        return np.diag(np.maximum(simulation.noise_std, default("noise_floor")) ** 2)

    def open_record(self):
        """The :class:`core_akf.io.Record` of ``[measurements]``, its time step checked against ``dt``."""
        from core_akf.io import open_record
        from core_akf.io.record import MAX_GAP

        meas = self.spec.measurements
        if meas is None or meas.file is None:
            raise AKFInputError("[measurements] needs file = 'data.csv' (a file, a folder or a glob pattern)")
        record = open_record(meas.file, self.sensors, channels=meas.channels, units=meas.units,
                        gauge_factor=meas.gauge_factor, bridge=meas.bridge, invert=meas.invert or (),
                        remove_offset=meas.remove_offset or False, format=meas.format,
                        time_column=meas.time_column or "time", group=meas.group,
                        max_gap=MAX_GAP if meas.max_gap is None else meas.max_gap)
        if record.n_steps < 2:
            raise AKFInputError(f"{record.files[0]}: {record.n_steps} data row(s); a record needs at least two time "
                                "steps")
        record.check_dt(self.dt)
        return record

    def open_live_record(self):
        """The record, and the job without the channels that have no observed sample in it.

        A channel whose every sample is missing (NaN) is dropped, with a note naming it; a record
        with no channel of a kind left where the job had one is refused.

        Returns
        -------
        record : Record
            Over the live channels.
        job : Job
            This job, or a copy without the dead channels.
        notes : list of str
        """
        record = self.open_record()
        counts = record.observed_counts()
        if counts.all():
            return record, self, list(record.warnings)
        dead = [s for s, c in zip(self.sensors, counts) if c == 0]
        live = [s for s, c in zip(self.sensors, counts) if c > 0]
        for kind in sorted({s.kind for s in dead}):
            if not any(s.kind == kind for s in live):
                names = ", ".join(s.label for s in dead if s.kind == kind)
                raise AKFInputError(f"every sample of {names} is missing (NaN) in the record, and the job has no other "
                                    f"{kind} channel: there is no {kind} data to estimate from")
        if not live:
            raise AKFInputError("the record has no observed sample: every value is missing (NaN)")
        job = self.without_sensors([s.label for s in dead])
        notes = [f"channel {s.label} has no observed sample in the record (every value is missing): dropped from the "
                 "sensors" for s in dead]
        record = job.open_record()
        return record, job, list(record.warnings) + notes

    def without_sensors(self, labels) -> Job:
        """The same job without some sensors (their channel map, units and per-sensor noise too).

        Parameters
        ----------
        labels : list of str
            Sensor labels ("strain:9").

        Returns
        -------
        Job
        """
        drop = set(labels)
        data = self.to_dict()
        keep = [i for i, s in enumerate(self.sensors) if s.label not in drop]
        data["sensors"] = [data["sensors"][i] for i in keep]
        meas = data.get("measurements") or {}
        channels = meas.get("channels")
        gone = {c for c, sensor in (channels or {}).items() if as_layout([sensor])[0].label in drop} if channels else drop
        if channels:
            meas["channels"] = {c: v for c, v in channels.items() if c not in gone}
        for key in ("units", "gauge_factor", "bridge"):
            if isinstance(meas.get(key), dict):
                meas[key] = {c: v for c, v in meas[key].items() if c not in gone}
        if meas.get("invert"):
            meas["invert"] = [c for c in meas["invert"] if c not in gone]
        noise = (data.get("filter") or {}).get("noise_cov")
        if isinstance(noise, list):
            data["filter"]["noise_cov"] = [noise[i] for i in keep]
        return Job.from_dict(data, self.command, source=self.source)

    def with_record(self, path: str) -> Job:
        """The same job reading another record (``[measurements] file = path``), not checked again."""
        meas = self.spec.measurements.model_copy(update={"file": os.fspath(path)})
        return Job(self.spec.model_copy(update={"measurements": meas}), self.command, self.source, self._structure)

    def loads(self, n_steps: int | None = None):
        """The simulated load histories (N, n_p) of ``[[simulation.loads]]`` (N from the duration)."""
        sim = self.spec.simulation
        if sim is None or sim.duration is None:
            raise AKFInputError("[simulation] needs a positive duration (s)")
        if n_steps is None:            # the whole record, to be simulated (place, show): refused before it is built
            self._check_record_fits()
            n_steps = int(round(sim.duration / self.dt))
        specs = [{"components": [c.model_dump(exclude_unset=True) for c in load.components]}
                 for load in (sim.loads or [])]
        return build_loads(specs, n_steps, self.dt, len(self.spec.forces),
                           warn_after_end=not self.duration_overridden)      # not for a record cut short on purpose

    def _check_record_fits(self, per_step=None):
        """The simulated record's steps, refused when its simulation (``per_step`` float64 values per
        step, default the states, strains and readings) would not fit in memory."""
        sp, structure = self.spec.simulation, self.structure
        n_steps = sp.duration / self.dt
        per_step = per_step or (2 * 2 * structure.n + structure.n_strain + 2 * len(self.spec.sensors or []))
        check_memory(n_steps, per_step, f"a {sp.duration:g} s record at dt = {self.dt:g} s",
                     "shorten [simulation] duration (CLI: --duration) or check dt")
        return int(round(n_steps))

    def simulate(self, per_step=None):
        """Simulate the measurements of ``[simulation]``: the true structure, its sensors, the forces
        with the loads of ``[[simulation.loads]]`` and the noise of ``relative_noise`` /
        ``absolute_noise`` (a :class:`core_akf.simulate.Simulation`).

        ``per_step``: float64 values the caller holds per time step, to refuse a record that would
        not fit in memory before it is allocated."""
        sp = self.spec.simulation
        if sp is None or sp.duration is None:
            raise AKFInputError("[simulation] needs a positive duration (s)")
        if self.spec.forces is None:
            raise AKFInputError("a simulated job needs forces = ['NODE:DIR'] (where the loads act)")
        structure, sensors, forces, dt = self.structure, self.sensors, self.forces, self.dt
        n_steps = self._check_record_fits(per_step)
        if n_steps < 2:
            raise AKFInputError(f"[simulation] duration {sp.duration:g} s is shorter than two steps of dt = {dt:g} s")
        loads = self.loads(n_steps)
        absolute = _absolute_noise(sp.absolute_noise) if sp.absolute_noise is not None else None
        check_noise(sp.relative_noise, absolute, {s.kind for s in sensors},
                    names=("[simulation] relative_noise", "[simulation] absolute_noise"))
        return simulate(structure, sensors, forces, loads, dt, relative_noise=sp.relative_noise,
                        absolute_noise=absolute, seed=sp.seed or 0, load_hold=self.load_hold)

    @property
    def load_hold(self) -> str:
        """``[simulation] load_hold`` of an estimate or locate job: ``"linear"`` unless the job says
        ``"zero"``; placement simulates its records held (``"zero"``)."""
        sp = self.spec.simulation
        if self.command not in ("estimate", "locate"):
            return "zero"
        return (sp.load_hold if sp is not None else None) or "linear"

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
    size = os.path.getsize(path)
    if size > MAX_JOB_BYTES:
        raise AKFInputError(f"{path}: the job file is {size / 1e6:.3g} MB; a job file is a few kB of settings (at most "
                            f"{MAX_JOB_BYTES / 1e6:g} MB): data belong in files that [measurements] or [structure] name")
    with open(path, "rb") as fh:
        raw = fh.read()
    text = job_text(raw, path)
    depth = nesting_depth(text)
    if depth > MAX_JOB_DEPTH:
        raise AKFInputError(f"{path}: arrays or inline tables nested {depth} deep; a job nests at most "
                            f"{MAX_JOB_DEPTH} (an S-N curve is [[N, range], ...]: 2)")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise AKFInputError(f"{path}: not valid TOML: {exc}") from None
    except RecursionError:
        raise AKFInputError(f"{path}: tables, arrays or keys nested too deep to read") from None
    depth = _data_depth(data)
    if depth > MAX_JOB_DEPTH:
        raise AKFInputError(f"{path}: tables or dotted keys nested deeper than {MAX_JOB_DEPTH}, the most a job nests "
                            "([output.fatigue] and [locate.covariances] are 2)")
    return data


#: a job file larger than this is refused before it is parsed (the built-in jobs are 1-3 kB)
MAX_JOB_BYTES = 1_000_000
#: nesting of tables, arrays and inline tables a job may have
MAX_JOB_DEPTH = 8


def nesting_depth(text: str) -> int:
    """The deepest nesting of ``[`` and ``{`` in TOML text outside strings and comments (a table
    header's brackets count too), found without parsing, so a hostile file is refused before the
    parser recurses into it."""
    depth = deepest = i = 0
    n = len(text)
    while i < n:
        c = text[i]
        if c == "#":                                   # a comment, to the end of the line
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif c in "\"'":
            quote = c * 3 if text.startswith(c * 3, i) else c
            i += len(quote)
            while i < n and not text.startswith(quote, i):
                i += 2 if (c == '"' and text[i] == "\\") else 1
            i += len(quote)
            continue
        elif c in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif c in "]}":
            depth = max(0, depth - 1)
        i += 1
    return deepest


def _data_depth(data) -> int:
    """How deep dicts and lists nest in parsed data (without recursion)."""
    deepest, stack = 0, [(data, 0)]
    while stack:
        value, d = stack.pop()
        deepest = max(deepest, d)
        if d > MAX_JOB_DEPTH:
            break
        if isinstance(value, dict):
            stack.extend((v, d + 1) for v in value.values())
        elif isinstance(value, list):
            stack.extend((v, d + 1) for v in value)
    return deepest


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
    params = inspect.signature(MODELS[name]).parameters
    open_ended = any(p.kind == p.VAR_KEYWORD for p in params.values())     # footbridge(**overrides) names its own
    unknown = [] if open_ended else [k for k in spec if k not in params]
    if unknown:
        raise AKFInputError(f"[structure] model = {name!r} has no key {unknown[0]!r}; its keys are "
                            f"{', '.join(params)}")
    if name == "matrices":
        missing = [k for k in ("K", "M", "dofs", "nodes") if k not in spec]
        if missing:
            raise AKFInputError(f"[structure] model = \"matrices\" needs {', '.join(missing)} (files of K, M, the DOF map "
                                "and the node coordinates)")
        for k in MATRIX_FILES:
            if k in spec and not isinstance(spec[k], str) and not (k == "extensometers" and isinstance(spec[k], list)):
                raise AKFInputError(f"[structure] {k} must be a file's path (text, relative to the job file)"
                                    f"{' or a list of node pairs [[a, b], ...]' if k == 'extensometers' else ''}; got "
                                    f"{spec[k]!r} ({type(spec[k]).__name__})")
        if spec.get("K") == spec.get("M"):
            raise AKFInputError(f"[structure] K and M name the same file ({os.path.basename(spec['K'])}): give the "
                                "stiffness matrix as K and the mass matrix as M")
    try:
        return MODELS[name](**spec)
    except AKFInputError:
        raise
    except (TypeError, ValueError) as exc:
        raise AKFInputError(f"bad arguments for structure model {name!r}: {exc}") from None


def build_loads(load_specs, n_steps, dt, n_forces, warn_after_end=True):
    """Load histories (N, n_p) from one ``{"components": [...]}`` spec per force location;
    ``warn_after_end``: a :class:`LoadWarning` for a load that starts after the record's end (not
    for a record cut short on purpose)."""
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
                part = _LOADS[kind](t, dt, c, c.get("seed"))
            except KeyError as exc:
                raise AKFInputError(f"load {kind!r} for force {j + 1} needs parameter {exc}") from None
            except AKFInputError as exc:
                raise AKFInputError(f"simulation.loads[{j}] (force {j + 1}), the {kind!r} load: {exc}") from None
            _check_load_part(part, kind, c, j, n_steps, dt, warn_after_end)
            out[:, j] += part
    return out


class LoadWarning(UserWarning):
    """A simulated load that the record does not hold (it starts after the record's end)."""


#: the key that sets each load type's size: a component whose size is not zero must not vanish
_LOAD_SIZE = {"band_noise": "rms", "white_noise": "std", "pulse": "peak", "ramp": "peak", "half_sine": "peak",
              "sine": "amplitude", "constant": "value"}


def _check_load_part(part, kind, c, j, n_steps, dt, warn_after_end):
    """A load component that the record's samples miss is named, not simulated as zero or as an
    alias: one that falls between two samples or a sine at or above the Nyquist frequency is an
    error, one that starts after the record's end (a record cut short) a :class:`LoadWarning`."""
    where = f"simulation.loads[{j}] (force {j + 1}): the {kind!r} load"
    if kind == "sine" and c["frequency"] >= 0.5 / dt:
        raise AKFInputError(f"{where} at {c['frequency']:g} Hz is at or above the Nyquist frequency ({0.5 / dt:g} Hz): "
                            "its samples would be an alias of a lower frequency")
    if c.get(_LOAD_SIZE[kind], 0) != 0 and not np.any(part):
        end = (n_steps - 1) * dt
        if c.get("start", -np.inf) > end:         # a time typed in ms, or a record cut short (--duration)
            if warn_after_end:
                warnings.warn(f"{where} starts at {c['start']:g} s, after the record's end ({end:.6g} s): it is zero "
                              "throughout (times are in s)", LoadWarning, stacklevel=2)
            return
        raise AKFInputError(f"{where} is zero at every sample of the record (0 to {end:.6g} s, every "
                            f"{dt:.6g} s): its start, end or duration lie outside the record or between two samples "
                            "(times are in s)")


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
