"""The one job schema: every key of an ``akf estimate``, ``akf place`` or ``akf locate`` job file,
declared once with its type, unit, default and the commands that use it.

Validation is pydantic (v2) in strict mode: a value of the wrong type is refused, never coerced
(``steady = "no"`` or ``seed = 0.0`` is an error), unknown keys are refused with the closest
known key, and every error names where it is (``[filter] steady``).  Pydantic was chosen over a
hand-written checker because it gives one declaration for three things that must agree: the
checks, the JSON Schema that editors use to complete job files (:func:`json_schema`), and the
reference page of the documentation (:func:`reference_markdown`).

>>> job = parse_job({"dt": 0.001, "sensors": ["strain:5"], "forces": ["4:y"],
...                  "structure": {"model": "s17_truss"},
...                  "simulation": {"duration": 0.5}}, "estimate")
>>> job.dt, job.filter.steady, job.simulation.duration      # steady: None, the command's default
(0.001, None, 0.5)
"""
from __future__ import annotations

import difflib
import json
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, PlainValidator, ValidationError, WithJsonSchema

from core_akf.checks import AKFInputError
from core_akf.defaults import DEFAULTS
from core_akf.fatigue import EC3_CATEGORIES
from core_akf.faults import FAULT_MODES

#: the commands that read job files
COMMANDS = ("estimate", "place", "locate")

ALL = COMMANDS
ESTIMATE = ("estimate",)
PLACE = ("place",)
LOCATE = ("locate",)


def key(expect, description, *, used_by=ALL, unit=None, default=None, registry=None, required=False, default_text=None,
        **field_kw):
    """A job key: ``expect`` says the type in a message ("a positive number"), ``description``
    what it means; ``used_by`` the commands that read it; ``unit`` its SI unit; ``registry`` the
    name of its default in :data:`core_akf.defaults.DEFAULTS` (the default is documented from
    there and applied by the command)."""
    extra = {"expect": expect, "used_by": list(used_by)}
    if unit:
        extra["unit"] = unit
    if registry:
        extra["default_from"] = registry
    if default_text:
        extra["default_text"] = default_text
    if required:
        field_kw["default"] = ...
    elif "default_factory" not in field_kw:
        field_kw["default"] = default
    return Field(description=description, json_schema_extra=extra, **field_kw)


Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Fraction = Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)]
Finite = Annotated[float, Field(allow_inf_nan=False)]
Count = Annotated[int, Field(ge=1)]
Count0 = Annotated[int, Field(ge=0)]
Text = Annotated[str, Field(min_length=1)]
Texts = Annotated[list[Text], Field(min_length=1)]


def _path_text(value):
    """A path: a non-empty string, also one that holds bytes of a file name that are not valid
    UTF-8 (as Python's file functions give them), which a plain pydantic string refuses."""
    if not isinstance(value, str) or not value:
        raise ValueError("a non-empty string")
    return value


PathText = Annotated[str, PlainValidator(_path_text), WithJsonSchema({"type": "string", "minLength": 1})]
Covariance = NonNegative | Annotated[list[NonNegative], Field(min_length=1)] | Annotated[list[list[Finite]], Field(min_length=1)]
Modes = Count | Literal["auto", "full"]


class Section(BaseModel):
    """A table of a job file: unknown keys and values of another type are refused.  A key that is
    absent takes its default (None: the command's default); an explicit None is refused like any
    other value of the wrong type (TOML has no null)."""

    model_config = ConfigDict(extra="forbid", strict=True, validate_default=False)


class StructureSection(BaseModel):
    """``[structure]``: a built-in model and its arguments."""

    model_config = ConfigDict(extra="allow", strict=True)
    model: Literal["s17_truss", "th_plate", "imp_plate", "plate", "footbridge", "matrices"] = key(
        "one of 's17_truss', 'th_plate', 'imp_plate', 'plate', 'footbridge', 'matrices'",
        "the structure: the S17 truss, the thesis plate, the IMP plate, a `plate` with its arguments "
        "(nx, ny, lx, ly, thickness, E, nu, rho, clamped_edge, damping, n_modes), the 3-D truss `footbridge` "
        "(1011 DOFs, members strain:1..1097), or `matrices`: a model of your own "
        "from files, K and M (Matrix Market .mtx, .npz or .npy), dofs (CSV: node, direction per matrix row), "
        "nodes (CSV: node, x, y[, z]), fixed ([\"NODE:DIR\", ...] or node ids), damping (a modal ratio or "
        "[\"rayleigh\", alpha, beta]), extensometers ([[a, b], ...] or a CSV of columns a, b: strain outputs strain:1, "
        "...), strains (a strain "
        "operator file, k x n: strain outputs ahead of the extensometers), n_modes (keep the lowest modes of "
        "the sparse matrices with a static correction; always done above 6000 DOFs, 100 modes unless given), "
        "paths relative to the job file; "
        "further keys are the model's arguments (see the API reference of core_akf.models)")


#: what ``[filter] calibrate`` may list (:data:`core_akf.calibration.PARAMETERS` and the noise of one kind or per channel)
CALIBRATION_KEYS = ("stiffness_factor", "frequencies", "damping", "noise_cov", "noise_cov:strain", "noise_cov:acc",
                    "noise_cov:vel", "noise_cov:disp", "noise_cov:channels", "force_increment_cov", "model_error_cov",
                    "force_std", "force_timescale", "force_band", "force_std:forces", "force_timescale:forces")
#: the force models of ``[filter] force_model`` (:data:`core_akf.forcemodels.FORCE_MODELS`)
FORCE_MODEL_NAMES = ("random_walk", "matern12", "matern32", "matern52", "butterworth")
PerForce = Positive | Annotated[list[Positive], Field(min_length=1)]


class Dummy(BaseModel):
    """``[filter] dummy``: zero pseudo-measurements of displacements or strains."""

    model_config = ConfigDict(extra="forbid", strict=True)
    sensors: Texts = key("a non-empty list of displacement or strain sensors, e.g. [\"disp:8:y\"]",
                         "the displacements (disp:NODE:DIR) or strains (strain:MEMBER) said to be zero", required=True)
    variance: Positive = key("a positive number", "the pseudo-measurements' variance (m^2 for displacements, "
                             "(m/m)^2 for strains): the size of the response they allow", unit="SI^2", required=True)


class Filter(Section):
    """``[filter]``: the filter's model and covariances."""

    stiffness_factor: Positive = key(
        "a number between 0.01 and 100", "the filter's stiffness relative to the true structure (1.05: 5 % stiffer)",
        used_by=("estimate", "place"), registry="stiffness_factor / placement_stiffness_factor")
    n_modes: Count = key("an integer >= 1", "keep this many modes (with static correction) in the filter's model; "
                         "default the full model (the key was reduce_modes)", used_by=ESTIMATE)
    model_error_cov: Covariance = key(
        "a variance >= 0, a list of variances or a matrix (list of lists)",
        "Q: model-error variance per step (one level, one per state, or the matrix; at most 1e-3)",
        used_by=("estimate", "place"), unit="state units^2", registry="model_error_cov")
    force_increment_cov: Covariance = key(
        "a variance >= 0, a list of variances or a matrix (list of lists)",
        "S: force-increment variance per step (random-walk force model; at most 1e18)", used_by=("estimate", "place"),
        unit="N^2", registry="force_increment_cov")
    force_model: Literal[FORCE_MODEL_NAMES] = key(
        "one of " + ", ".join(f'\"{k}\"' for k in FORCE_MODEL_NAMES),
        "the forces' prior: random_walk (the papers'; needs strain or displacement sensors), or a stationary "
        "Gaussian process with a Matérn covariance (matern12, matern32, matern52: smoothness 1/2, 3/2, 5/2; "
        "force_std and force_timescale) or band-limited white noise (butterworth: force_std, force_band and "
        "force_band_order), which makes accelerometer-only sets detectable for zero-mean loads",
        default_text='"random_walk"')
    force_std: PerForce = key("a positive number or one per force", "Matérn force model: the standard deviation of "
                              "each force (akf calibrate learns it: calibrate = [\"force_std\"])", unit="N")
    force_timescale: PerForce = key("a positive number or one per force", "Matérn force model: the time scale "
                                    "(length scale) of each force's covariance, over which it stays correlated",
                                    unit="s")
    force_band: Annotated[list[NonNegative], Field(min_length=2, max_length=2)] = key(
        "[f_low, f_high], 0 <= f_low < f_high", "Butterworth force model: the loads' band (f_low = 0: a low-pass; "
        "f_low > 0: a band-pass), below the Nyquist frequency; akf calibrate learns it: calibrate = [\"force_band\"]",
        unit="Hz")
    force_band_order: int = key("an integer from 2 to 8", "Butterworth force model: the filter's order (the spectrum "
                                "falls by 20 x order dB per decade outside the band)", default_text="4")
    load_hold: Literal["zero", "linear"] = key(
        "\"zero\" or \"linear\"", "how the filter takes a force from one sample to the next: held over the step "
        "(zero, the papers' filter) or linear between samples (a continuous load: the filter runs the first-order "
        "hold of the structure); match it to the loads: a measured load is continuous", default_text='"zero"')
    dummy: Dummy = key("a table {sensors = [...], variance = ...}", "zero-valued pseudo-measurements of "
                       "displacements or strains added to the sensors (dummy measurements): they keep an "
                       "accelerometer-only random-walk filter from drifting, at the cost of a bias towards zero "
                       "static response", used_by=ESTIMATE)
    noise_cov: Literal["simulated"] | dict[Text, Positive] | Annotated[list[Positive], Field(min_length=1)] | Positive = key(
        "\"simulated\", a table of positive variances per sensor kind (e.g. {strain = 1e-12, acc = 1e-4}), "
        "or positive variances per channel",
        "R: measurement-noise variance per sensor kind (SI units squared), per channel, or \"simulated\" "
        "(the true noise of a simulated job)", used_by=ESTIMATE, unit="SI^2", default_text='"simulated"')
    steady: bool = key("true or false (a TOML boolean, not a string or a number)",
                                 "the steady-state filter (fast); false: the time-varying filter",
                                 used_by=ESTIMATE, registry="steady")
    allow_undetectable: bool = key("true or false (a TOML boolean, not a string or a number)",
                                             "run even if the PBH detectability test fails (the estimate drifts)",
                                             used_by=ESTIMATE)
    frequency_factors: Annotated[list[Positive], Field(min_length=1)] = key(
        "a non-empty list of numbers between 0.1 and 10", "factors on the filter model's natural frequencies of modes 1, 2, "
        "... (mode shapes kept; the other modes keep theirs): a local stiffness change that a global factor cannot "
        "express; akf calibrate writes it from calibrate = [\"frequencies\"]", used_by=ESTIMATE)
    calibrate: Annotated[list[Literal[CALIBRATION_KEYS]], Field(min_length=1)] = key(
        "a non-empty list of " + ", ".join(f'\"{k}\"' for k in CALIBRATION_KEYS),
        "learn these from the record by maximum likelihood before estimating: the [filter] keys; frequencies (a "
        "factor per mode of calibrate_modes, one common factor on the other modes -- written as stiffness_factor -- "
        "and a stationary force prior's two parameters unless one is named); damping (the model's modal damping "
        "ratio); noise_cov (one factor per sensor kind; noise_cov:<kind> one kind, noise_cov:channels one per "
        "channel); the JSON reports the fit, akf calibrate writes the job with the fitted values",
        used_by=ESTIMATE)
    calibrate_modes: Annotated[list[Count], Field(min_length=1)] = key(
        "a non-empty list of mode numbers (1-based)", "the modes whose frequencies calibrate = [\"frequencies\"] "
        "learns (default the lowest calibration_modes modes below a quarter of the sampling rate)",
        used_by=ESTIMATE, registry="calibration_modes")
    smooth: bool = key("true or false (a TOML boolean, not a string or a number)",
                       "smooth the estimate with the record after each step (RTS smoother): better forces and "
                       "strains, with their standard deviations (the std column of timeseries.csv, bands in "
                       "estimate.png); the whole record when it is held in one piece, else a fixed lag (smooth_lag); "
                       "calibrate first where the model is off", used_by=ESTIMATE)
    smooth_lag: Positive | Literal["auto"] = key(
        "a positive number or \"auto\"", "with smooth = true: smooth each step with this many seconds of the record "
        "after it (fixed-lag smoothing, constant memory: a streamed record of any length); \"auto\": the shortest lag "
        "after which the record barely changes the estimate (smooth_lag_tolerance); default: the whole record for a "
        "record in one piece, \"auto\" for a record filtered in chunks", used_by=ESTIMATE, unit="s")
    calibrate_window: Positive = key("a positive number", "the first this many seconds of the record are used to "
                                     "calibrate (default: a window of about a minute of fitting for the filter's size, at "
                                     "least 50 periods of the first mode, at most 65536 steps; the JSON's window names "
                                     "it)",
                                     used_by=ESTIMATE, unit="s")
    calibrate_method: Literal["auto", "time", "whittle"] = key(
        '"auto", "time" or "whittle"', "the likelihood that learns a stationary force model's force_std, "
        "force_timescale or force_band: time (every sample of the record), whittle (its spectrum against the "
        "record's periodogram over the frequency bins standing 10x above the noise floor; the other parameters by "
        "the time-domain likelihood after it), auto (whittle for a Matérn prior when at most half the bins hold signal, else time); "
        "the JSON's calibration says which ran and why", default_text="auto", used_by=ESTIMATE)
    calibrate_held: Literal["learn", "warn"] = key(
        '"learn" or "warn"', "a covariance level the fit holds (model_error_cov, the random walk's "
        "force_increment_cov, the noise of a sensor kind not calibrated) that the record rejects (the log-likelihood "
        "rises by more than 5.4 at another value) and that a fitted parameter leans on (learning it would move that "
        "parameter by more than 2 robust standard errors): learn fits again with it learnt as well (about as many "
        "filters again) and says so in the JSON's calibration notes; warn keeps the job's value and names the "
        "parameter in a warning", default_text="warn", used_by=ESTIMATE)


class LoadComponent(BaseModel):
    """One component of a simulated load history."""

    model_config = ConfigDict(extra="forbid", strict=True)
    type: Literal["band_noise", "white_noise", "pulse", "ramp", "half_sine", "sine", "constant"] = key(
        "a load type", "band_noise (rms, f_low, f_high, seed), white_noise (std, seed), pulse (start, duration, "
        "peak), ramp (start, end, peak), half_sine (start, end, peak), sine (frequency, amplitude, phase), "
        "constant (value)")
    rms: NonNegative = key("a number >= 0", "RMS of band-limited noise", unit="N")
    std: NonNegative = key("a number >= 0", "standard deviation of white noise", unit="N")
    f_low: NonNegative = key("a number >= 0", "lower band edge of band_noise", unit="Hz")
    f_high: Positive = key("a positive number", "upper band edge of band_noise", unit="Hz")
    seed: Count0 = key("an integer >= 0", "seed of a random component")
    start: Finite = key("a number", "start time", unit="s")
    end: Finite = key("a number", "end time", unit="s")
    duration: Positive = key("a positive number", "pulse duration", unit="s")
    peak: Finite = key("a number", "peak force", unit="N")
    frequency: NonNegative = key("a number >= 0", "sine frequency", unit="Hz")
    amplitude: Finite = key("a number", "sine amplitude", unit="N")
    phase: Finite = key("a number", "sine phase", unit="rad")
    value: Finite = key("a number", "constant force", unit="N")


class Load(BaseModel):
    """``[[simulation.loads]]``: the load history at one force location, a sum of components."""

    model_config = ConfigDict(extra="forbid", strict=True)
    components: list[LoadComponent] = key("a list of load components", "the components, summed",
                                          default_factory=list)


class Simulation(Section):
    """``[simulation]``: simulate the measurements (instead of ``[measurements]``)."""

    duration: Positive = key("a positive number", "record length", unit="s")
    relative_noise: NonNegative = key("a number >= 0", "sensor noise as a fraction of each channel's RMS",
                                                registry="relative_noise")
    absolute_noise: dict[Literal["strain", "microstrain", "acc", "acc_mg", "vel", "disp"], NonNegative] = key(
        "a table of noise levels: strain, microstrain, acc, acc_mg, vel or disp",
        "sensor noise standard deviation per kind, e.g. {microstrain = 1, acc_mg = 1}", used_by=("estimate", "locate"))
    seed: Count0 = key("an integer >= 0", "noise seed")
    load_hold: Literal["zero", "linear"] = key(
        "\"zero\" or \"linear\"", "how a simulated load goes from one sample to the next: linear (a continuous "
        "load, exact first-order hold) or zero (held over each step, as the filter assumes by default; the built-in "
        "examples keep it so that their published numbers stay); a stepped load excites the structure below its "
        "first mode far more than a continuous one and suits a held filter: it flatters the estimates of "
        "measured (continuous) loads", used_by=("estimate", "locate"),
        default_text='"linear"')
    loads: list[Load] = key("a list of tables", "one table per force location, in the order of `forces`")


Bridge = Literal["quarter", "half", "full"]


class FaultThresholds(Section):
    """``[measurements.fault_thresholds]``: the thresholds of the sensor-fault tests (:mod:`core_akf.faults`)."""

    stuck_steps: Count = key("a whole number >= 1", "identical samples in a row that make a stuck span",
                             used_by=ESTIMATE, default_text="25")
    clip_count: Count = key("a whole number >= 1", "samples at one extreme value that make it a rail (clipping)",
                            used_by=ESTIMATE, default_text="3")
    spike_sigma: Positive = key("a positive number", "robust standard deviations off the neighbours' median that make a "
                                "spike", used_by=ESTIMATE, default_text="15")
    spike_width: Count = key("a whole number >= 1", "the most outliers in a row that count as a spike", used_by=ESTIMATE,
                             default_text="2")
    cusum_drift: Positive = key("a positive number", "the drift test's allowance, in robust standard deviations of the "
                                "innovations per step", used_by=ESTIMATE, default_text="2")
    cusum_threshold: Positive = key("a positive number", "the drift test's alarm level (its CUSUM)", used_by=ESTIMATE,
                                    default_text="60")


class Measurements(Section):
    """``[measurements]``: measured data: one file, or a record in many files, with a channel map."""

    file: PathText = key("a non-empty string", "a data file (CSV, Parquet, TDMS, UFF 58, HDF5), a folder or a glob pattern "
                     "(\"run/*.tdms\"), relative to the job file; estimate: the pieces of one record, joined in time "
                     "order; locate: one impact per file", used_by=("estimate", "locate"))
    format: Text = key("a non-empty string", "the file format (csv, parquet, tdms, uff, hdf5 or a registered reader); "
                       "default from the extension", used_by=("estimate", "locate"))
    time_column: Text = key("a non-empty string", "name of the time column or channel (default \"time\"; TDMS, UFF "
                            "and HDF5 may give the time by their waveform properties instead)",
                            used_by=("estimate", "locate"))
    group: Text = key("a non-empty string", "TDMS or HDF5 group holding the channels (default all groups / the root)",
                      used_by=("estimate", "locate"))
    channels: dict[Text, Text] = key("a table of file channel = sensor", "which file channel is which sensor, e.g. "
                                     "{SG13 = \"strain:13\", ACC_8Y = \"acc:8:y\"}; default: channels named like "
                                     "the sensors", used_by=("estimate", "locate"))
    units: dict[Text, Text] = key("a table of file channel = unit", "each channel's unit, e.g. {SG13 = \"microstrain\", "
                                  "ACC_8Y = \"g\"} (pint units; mV/V for a bridge output); default the unit the file "
                                  "records, else SI", used_by=("estimate", "locate"))
    gauge_factor: Positive | dict[Text, Positive] = key(
        "a positive number or a table per channel", "gauge factor of the channels in mV/V (bridge outputs)",
        used_by=("estimate", "locate"))
    bridge: Bridge | dict[Text, Bridge] = key(
        "\"quarter\", \"half\" or \"full\", or a table per channel", "bridge type of the channels in mV/V "
        "(default quarter)", used_by=("estimate", "locate"))
    invert: list[Text] = key("a list of channel names", "channels whose sign is flipped", used_by=("estimate", "locate"))
    remove_offset: bool | Positive = key(
        "true, false or a positive number of seconds", "subtract each channel's offset (zero drift): true the mean of the "
        "whole record, a number the mean of its first that many seconds", used_by=("estimate", "locate"), unit="s")
    chunk: Positive = key("a positive number", "the record is filtered and written in pieces this long (constant "
                          "memory)", used_by=ESTIMATE, unit="s", default_text="65536 steps (fewer for a large model)")
    faults: Literal[FAULT_MODES] = key(
        "\"flag\", \"drop\" or \"off\"", "sensor faults (stuck, clipped, spikes, drift): \"flag\" reports them "
        "(data_quality.csv, the JSON, warnings), \"drop\" also treats the faulty samples as missing, \"off\" does "
        "not look", used_by=ESTIMATE, default_text="\"flag\"")
    fault_thresholds: FaultThresholds = key("a table", "the thresholds of the fault tests", used_by=ESTIMATE)
    max_gap: NonNegative = key("a number >= 0", "the longest gap between two files the filter predicts through (its "
                            "steps are missing samples); after a longer one it restarts from its prior", used_by=ESTIMATE,
                            unit="s", default_text="60")


class Fatigue(Section):
    """``[output.fatigue]``: fatigue of the estimated strains (fatigue.csv, fatigue.png)."""

    detail_category: Literal[EC3_CATEGORIES] = key(
        "one of " + ", ".join(str(c) for c in EC3_CATEGORIES),
        "the EN 1993-1-9 detail category: Δσ_C at 2e6 cycles; slope 3 to Δσ_D = 0.737 Δσ_C at 5e6, slope 5 to the "
        "cut-off Δσ_L = 0.549 Δσ_D at 1e8, no damage below (give this or sn_curve)", used_by=ESTIMATE, unit="MPa")
    sn_curve: Annotated[list[Annotated[list[Positive], Field(min_length=2, max_length=2)]], Field(min_length=2)] = key(
        "a list of at least two [N, range] pairs", "an S-N curve of one's own through these points (N increasing, "
        "range in MPa decreasing), power law between them, the first slope above the first point, no damage below "
        "the last (instead of detail_category)", used_by=ESTIMATE)
    youngs_modulus: Positive = key("a positive number", "E for the stress of every strain output (default the "
                                   "model's own, where it has one)", used_by=ESTIMATE, unit="Pa")
    gamma_mf: Annotated[float, Field(ge=1, allow_inf_nan=False)] = key(
        "a number >= 1", "partial factor for fatigue strength: the curve's ranges are divided by it (default 1)",
        used_by=ESTIMATE)
    del_slope: Positive = key("a positive number", "slope m of the damage-equivalent stress range "
                              "DEL = (Σ n_i Δσ_i^m / N_eq)^(1/m) (default 3)", used_by=ESTIMATE)
    del_cycles: Positive = key("a positive number", "N_eq of the damage-equivalent range (default 2e6)",
                               used_by=ESTIMATE)
    outputs: Annotated[list[Text], Field(min_length=1)] = key(
        "a non-empty list of strain output labels", "the strain outputs assessed, e.g. [\"strain:13\", "
        "\"strain:70:ex\"] (default every strain output)", used_by=ESTIMATE)
    members: Annotated[list[Count], Field(min_length=1)] = key(
        "a non-empty list of member numbers", "the truss members assessed (instead of outputs)", used_by=ESTIMATE)


class Output(Section):
    """``[output]``: what to write."""

    strains: Literal["all"] | list[Text] = key(
        "\"all\" or a list of strain labels", "strain histories to write (labels as sensors: \"strain:13\", "
        "\"strain:70:ex\")", used_by=ESTIMATE)
    format: Literal["csv", "parquet"] = key("\"csv\" or \"parquet\"", "file format of the time series "
                                            "(timeseries.csv or timeseries.parquet)", used_by=ESTIMATE)
    fatigue: Fatigue = key("a table", "rainflow counting, Miner damage and damage-equivalent ranges of the "
                           "estimated strains ([output.fatigue])", used_by=ESTIMATE)


Measure = Literal["mean", "p90", "worst", "cvar90"]


class PlaceUncertainty(Section):
    """``[place.uncertainty]``: the true structures a layout is scored on (the filter stays the
    job's model)."""

    stiffness_factor: Positive | Annotated[list[Positive], Field(min_length=2)] = key(
        "a positive number, [low, high] or a list of three or more positive numbers",
        "the filter's stiffness against the truth: a range [low, high] drawn by a Latin hypercube, or the "
        "factors themselves (default the [filter] stiffness_factor)", used_by=PLACE)
    frequency_factors: PathText = key(
        "a path to a calibrated.toml", "draw per-mode frequency factors of the truth from a calibration (akf calibrate "
        "with calibrate = [\"frequencies\"]): its fitted factors, its stiffness_factor and the standard errors in "
        "the calibration.json beside it; relative to the job file", used_by=PLACE)
    samples: Count = key("an integer >= 1", "models drawn from the range (default 8)", used_by=PLACE)
    seeds: Count = key("an integer >= 1", "noise draws per model (default 3)", used_by=PLACE)
    measure: Measure = key("\"mean\", \"p90\", \"worst\" or \"cvar90\"",
                           "what the fitness makes of a layout's errors over the models and seeds (default p90: "
                           "the 90 % quantile; cvar90: the mean of the worst 10 %)", used_by=PLACE)


class PlaceConstraints(Section):
    """``[place.constraints]``: what a layout may cost and where sensors may go."""

    cost: dict[Text, NonNegative] = key(
        "a table of numbers >= 0 per sensor type or kind, e.g. {strain = 1.0, acc = 4.0}",
        "the cost of one sensor of each type (strain, acc) or kind (ex, acc:z); default 1 each", used_by=PLACE)
    budget: Positive = key("a positive number", "the most a layout may cost (in the units of cost)", used_by=PLACE)
    forbidden: Annotated[list[Annotated[list[Finite], Field(min_length=4, max_length=6)]], Field(min_length=1)] = key(
        "a list of boxes [x0, y0, x1, y1] (2-D) or [x0, y0, z0, x1, y1, z1] (3-D)",
        "regions where no sensor may go: a candidate whose position lies in a box is never placed", used_by=PLACE,
        unit="m")
    forbidden_nodes: Annotated[list[Count], Field(min_length=1)] = key(
        "a list of node numbers (1-based)", "nodes where no sensor may go: an accelerometer or a gauge at the node, "
        "or a member that ends there", used_by=PLACE)
    min_spacing: Positive = key("a positive number", "the least distance between any two sensors of a layout",
                                used_by=PLACE, unit="m")


class Place(Section):
    """``[place]``: what to place and the GA settings (TH defaults)."""

    sensors: Count = key("an integer >= 1", "number of sensors", used_by=PLACE)
    budget: dict[Literal["strain", "acc"], Count0] = key(
        "a table of counts per sensor type, e.g. {strain = 2, acc = 1}", "sensors per type", used_by=PLACE)
    kinds: Texts = key("a non-empty list of strings", "kinds that may be placed: strain (a gauge on every strain "
                       "output: truss members, extensometers, strain rows), acc (an accelerometer on every free "
                       "translational DOF), acc:DIR (one direction, e.g. acc:z); on a plate ex, ey, gxy, acc; default "
                       "a plate's ex, ey, gxy or strain", used_by=PLACE)
    candidates: Texts = key("a non-empty list of sensor strings", "the candidate set itself, e.g. [\"strain:13\", "
                            "\"acc:8:y\"] (instead of kinds)", used_by=PLACE)
    targets: Texts = key("a non-empty list of strain output labels", "the strain outputs whose error is averaged "
                         "(default all), e.g. [\"strain:1\", \"strain:2\"]", used_by=PLACE)
    window: Positive = key("a positive number", "simulated response per fitness evaluation",
                                     used_by=PLACE, unit="s", registry="window")
    population: Count = key("an integer >= 1", "GA population (TH: 50)", used_by=PLACE)
    generations: Count0 = key("an integer >= 0", "GA generations (TH: 100)", used_by=PLACE)
    elite: Count0 = key("an integer >= 0", "layouts kept unchanged per generation (TH: 2)", used_by=PLACE)
    crossover: Fraction = key("a number between 0 and 1", "crossover probability (TH: 0.8)", used_by=PLACE)
    mutation: Fraction = key("a number between 0 and 1", "mutation probability (TH: 0.16)", used_by=PLACE)
    tournament: Count = key("an integer >= 1", "tournament size (TH: 4)", used_by=PLACE)
    stall_generations: Count0 = key("an integer >= 0", "stop after this many generations without "
                                              "progress (TH: 50)", used_by=PLACE)
    operators: Literal["set", "thesis"] = key("\"set\" or \"thesis\"", "set-based operators or the "
                                                        "thesis' intermediate crossover", used_by=PLACE)
    n_modes: Modes = key("an integer >= 1, \"auto\" or \"full\"", "filter modes (with static "
                                   "correction) of the fitness; \"auto\": core_akf.defaults.band_modes (the layout's "
                                   "reported error: core_akf.defaults.auto_modes)", used_by=PLACE)
    objective: Literal["strain", "fatigue"] = key(
        "\"strain\" or \"fatigue\"", "what the GA minimises: the average strain error of the targets (the "
        "thesis' fitness, default) or the mean relative error of their damage-equivalent stress range (fatigue)",
        used_by=PLACE)
    del_slope: Positive = key("a positive number", "objective = \"fatigue\": the slope m of the damage-equivalent "
                              "range (default 3)", used_by=PLACE)
    objectives: Annotated[list[Literal["error", "cost"]], Field(min_length=1, max_length=2)] = key(
        "[\"error\"] or [\"error\", \"cost\"]", "what the GA minimises: the error of one layout of `sensors` "
        "(default), or the front of error against cost (NSGA-II over layouts of 1 to `sensors` sensors of any "
        "kind, costed by [place.constraints] cost)", used_by=PLACE)
    uncertainty: PlaceUncertainty = key("a table", "score each layout over true structures unlike the filter's "
                                        "model ([place.uncertainty])", used_by=PLACE)
    survive_failures: Count0 = key("an integer >= 0", "score each layout also with each this many of its sensors "
                                   "lost; a layout left undetectable by a loss is infeasible (default 0)",
                                   used_by=PLACE)
    failure_measure: Measure = key("\"mean\", \"p90\", \"worst\" or \"cvar90\"",
                                   "how the error without a loss and the errors after each loss combine (default "
                                   "worst)", used_by=PLACE)
    constraints: PlaceConstraints = key("a table", "costs, a budget, forbidden regions and a minimum spacing "
                                        "([place.constraints])", used_by=PLACE)


class CovariancesSection(Section):
    """``[locate.covariances]``: assumed covariance levels before tuning."""

    model_error_cov: NonNegative = key("a number >= 0", "Q level (as [filter] model_error_cov; the key was "
                                       "model_error)", unit="state units^2", used_by=LOCATE, required=True)
    force_increment_cov: Positive = key("a positive number", "S level (as [filter] force_increment_cov; the key was "
                                        "force_increment)", unit="N^2", used_by=LOCATE, required=True)
    noise_cov: dict[Text, Positive] = key("a table of positive numbers", "R per sensor kind (as [filter] noise_cov; "
                                          "the key was noise)", unit="SI^2", used_by=LOCATE, required=True)


class Tuning(Section):
    """``[locate.tuning]``: covariance-tuning GA settings."""

    population: Count = key("an integer >= 1", "GA population", used_by=LOCATE)
    generations: Count0 = key("an integer >= 0", "GA generations", used_by=LOCATE)
    n_splits: Count = key("an integer >= 1", "role splits in the fitness", used_by=LOCATE)
    decades: Positive = key("a positive number", "search range around the start, in decades",
                                      used_by=LOCATE)
    crossover: Fraction = key("a number between 0 and 1", "crossover probability", used_by=LOCATE)
    mutation: Fraction = key("a number between 0 and 1", "mutation probability", used_by=LOCATE)


class Locate(Section):
    """``[locate]``: impact localisation settings."""

    n_ad: Count = key("an integer >= 1", "AD (held-back) sensors per role split", used_by=LOCATE)
    ad_kinds: Texts = key("a non-empty list of strings", "sensor kinds that may be AD (default "
                                    "[\"strain\"])", used_by=LOCATE)
    direction: Text = key("a non-empty string", "force direction at the candidates (x, y, w, ...)",
                                    used_by=LOCATE)
    candidates: Annotated[list[int], Field(min_length=1)] = key(
        "a non-empty list of integers", "candidate node ids (default every free node)", used_by=LOCATE)
    max_splits: Count = key("an integer >= 1", "cap on the role splits (a seeded sample)", used_by=LOCATE)
    tune: bool | Literal["ga", "ml"] = key(
        "true, false, \"ga\" or \"ml\"", "tune the covariances at the identified location: with the paper's GA "
        "(true or \"ga\", the default; the tuned levels are kept where they lower the AD error) or by maximum "
        "likelihood of the record (\"ml\"; faster, every level fitted); false: not at all", used_by=LOCATE)
    n_modes: Modes = key("an integer >= 1, \"auto\" or \"full\"", "filter modes for the scan and the "
                                   "tuning", used_by=LOCATE)
    skip: NonNegative = key("a number >= 0", "seconds at the start left out of the AD error",
                                      used_by=LOCATE, unit="s")
    covariances: CovariancesSection = key("a table", "assumed levels (default: from the data)", used_by=LOCATE)
    tuning: Tuning = key("a table", "GA settings of the tuning", used_by=LOCATE)


#: a job's name: a plain file name (its output folder akf-out/NAME), no path
JOB_NAME_PATTERN = r"^[^./\\\x00][^/\\\x00]*$"


class Job(Section):
    """A job file: one structure, its sensors and unknown forces, and the sections of the command."""

    name: Annotated[str, Field(pattern=JOB_NAME_PATTERN)] = key(
        "a plain name (no '/', no '\\', not starting with '.')", "name of the job (its output folder akf-out/NAME)")
    description: str = key("a string", "free text")
    dt: Positive = key("a positive number", "time step; must match measured data", unit="s")
    sensors: Texts = key("a non-empty list of strings", "sensors: \"strain:13\" (truss member), "
                                   "\"strain:58:ex\" (plate node and component ex, ey or gxy), \"acc:8:y\", \"vel:8:y\", "
                                   "\"disp:8:y\"", used_by=("estimate", "locate"))
    forces: Texts = key("a non-empty list of strings", "unknown force locations \"NODE:DIR\" (directions x, y for "
                        "a truss; w for a plate); locate: where a simulated impact hits")
    structure: StructureSection = key("a table", "the structure")
    filter: Filter = key("a table", "filter settings", default_factory=Filter)
    simulation: Simulation = key("a table", "simulated measurements (locate: to try the method on a simulated "
                                 "impact at `forces`)")
    measurements: Measurements = key("a table", "measured data", used_by=("estimate", "locate"))
    output: Output = key("a table", "what to write", used_by=ESTIMATE, default_factory=Output)
    place: Place = key("a table", "sensor placement", used_by=PLACE)
    locate: Locate = key("a table", "impact localisation", used_by=LOCATE)


#: what each command needs: top-level keys, and keys needed inside a section
REQUIRED = {
    "estimate": ["dt", "sensors", "forces", "structure"],
    "place": ["dt", "forces", "structure", "place", "simulation"],
    "locate": ["dt", "sensors", "structure", "locate"],
}
SECTION_REQUIRED = {"locate": {"locate": ["n_ad", "direction"]}}


# ----------------------------------------------------------------------------------- messages
def _where(path):
    """``[filter]`` for a section path, ``the job`` for the top level."""
    return "the job" if not path else "[" + ".".join(path) + "]"


def _describe(value):
    return f"{value!r} ({type(value).__name__})"


def _message(error, kind):
    """One located, plain message from a pydantic error."""
    loc = [p for p in error["loc"]]
    model, path = Job, []
    field = None
    i = 0
    while i < len(loc):
        name = loc[i]
        fields = model.model_fields if isinstance(model, type) and issubclass(model, BaseModel) else {}
        if not isinstance(name, str) or name not in fields:
            break
        field = fields[name]
        sub = _section_model(field.annotation)
        if sub is None or i == len(loc) - 1:
            break
        model, path = sub, path + [name]
        field = None
        i += 1
    if error["type"] == "extra_forbidden":
        known = list(model.model_fields) if isinstance(model, type) else []
        bad = loc[-1]
        if path and bad in Job.model_fields:
            return misplaced_key(bad, path[0])
        hint = difflib.get_close_matches(str(bad), known, n=1)
        return (f"unknown key {bad!r} in {_where(path)}"
                + (f"; did you mean {hint[0]!r}?" if hint else f"; allowed: {sorted(known)}"))
    if error["type"] == "missing" and field is not None:
        return f"{_where(path)} needs {loc[i]!r}"
    if field is None or i >= len(loc):
        return f"{_where(path)} of the {kind}: {error['msg'].lower()}; got {_describe(error.get('input'))}"
    name = loc[i]
    rest = "".join(f"[{p + 1}]" if isinstance(p, int) else f".{p}" for p in loc[i + 1:]
                   if isinstance(p, int) or (isinstance(p, str) and not _is_type_tag(p)))
    if rest:          # inside a list of tables (simulation.loads[1].components[2].rms)
        return f"{name}{rest} in {_where(path)}: {error['msg'].lower()}; got {_describe(error.get('input'))}"
    expect = (field.json_schema_extra or {}).get("expect", error["msg"].lower())
    value = error.get("input")
    return f"{name} in {_where(path)} must be {expect}; got {_describe(value)}"


#: keys renamed so that one concept has one name everywhere: (table path, old key, new key)
RENAMED_KEYS = ((("filter",), "reduce_modes", "n_modes"),
                (("locate", "covariances"), "model_error", "model_error_cov"),
                (("locate", "covariances"), "force_increment", "force_increment_cov"),
                (("locate", "covariances"), "noise", "noise_cov"))


def _rename_old_keys(data, source=None):
    """Read a job written with a key's old name (:data:`RENAMED_KEYS`) under its new one, with a
    ``FutureWarning`` that says what to change; both names at once are an error."""
    import warnings

    for path, old, new in RENAMED_KEYS:
        table = data
        for part in path:
            table = table.get(part) if isinstance(table, dict) else None
        if not isinstance(table, dict) or old not in table:
            continue
        where = "[" + ".".join(path) + "]"
        if new in table:
            raise JobError([f"{where} has both {old!r} and {new!r}; {old} is the old name of {new}: keep one"], source)
        table[new] = table.pop(old)
        warnings.warn(f"{source + ': ' if source else ''}{where} {old} is now called {new}; read as {new} (rename it in "
                      "the job file)", FutureWarning, stacklevel=3)


#: top-level job keys that no model function takes as an argument (a ``[structure]`` table passes
#: its other keys to the model)
TOP_LEVEL_ONLY = ("dt", "sensors", "forces", "description")


def misplaced_key(name, table):
    """The message for a top-level key written after a ``[table]`` header (TOML puts it into that
    table)."""
    return (f"{name!r} sits in [{table}], but it is a top-level key: in TOML every key after a [table] header "
            f"belongs to that table; move {name} above the first [table]")


def _is_type_tag(p):
    """pydantic's union-member tags in a location ('constrained-float', "literal['simulated']")."""
    return any(c in p for c in "[]-") or p in ("float", "int", "str", "bool", "list", "dict")


def _section_model(annotation):
    """The section model class inside ``Model`` (None if it is not a section)."""
    for candidate in (annotation, *getattr(annotation, "__args__", ())):
        if isinstance(candidate, type) and issubclass(candidate, BaseModel):
            return candidate
    return None


class JobError(AKFInputError):
    """A job file that does not fit the schema; ``problems`` lists every located message."""

    def __init__(self, problems, source=None):
        self.problems = list(problems)
        head = f"{source}: " if source else ""
        more = "" if len(self.problems) == 1 else f" (and {len(self.problems) - 1} more: " + "; ".join(
            self.problems[1:4]) + (" ..." if len(self.problems) > 4 else "") + ")"
        super().__init__(head + self.problems[0] + more)


def parse_job(data: dict, command: str, source: str | None = None) -> Job:
    """Validate a job (a dict as read from TOML) for ``command`` ("estimate", "place", "locate").

    Returns the :class:`Job`; raises :class:`JobError` naming every problem and where it is: a
    value of the wrong type, an unknown key, a key the command needs and does not find, or a key
    that the command would ignore."""
    if command not in COMMANDS:
        raise ValueError(f"command must be one of {COMMANDS}, got {command!r}")
    kind = {"estimate": "job", "place": "place job", "locate": "locate job"}[command]
    if not isinstance(data, dict):
        raise JobError([f"a {kind} is a table of settings (a dict), got {type(data).__name__}"], source)
    _rename_old_keys(data, source)
    structure = data.get("structure")
    if isinstance(structure, dict):       # its extra keys go to the model function: catch a misplaced job key first
        misplaced = [misplaced_key(k, "structure") for k in structure if k in TOP_LEVEL_ONLY]
        if misplaced:
            raise JobError(misplaced, source)
    try:
        job = Job.model_validate(data)
    except ValidationError as exc:
        problems = list(dict.fromkeys(_message(e, kind) for e in exc.errors()))
        raise JobError(problems, source) from None
    missing = [f"the {kind} has no {k!r}" for k in REQUIRED[command] if getattr(job, k) is None]
    for section, keys in SECTION_REQUIRED.get(command, {}).items():
        table = getattr(job, section)
        missing += [f"[{section}] needs {k!r}" for k in keys if table is not None and getattr(table, k) is None]
    if missing:
        raise JobError(missing, source)
    unused = _unused_keys(job, command)
    if unused:
        raise JobError([f"{k} is not used by akf {command}; remove it (it is read by akf "
                        f"{' and akf '.join(c)})" for k, c in unused], source)
    return job


def _unused_keys(model, command, path=()):
    """Keys set in the job that ``command`` does not read: (where, commands that read it)."""
    out = []
    for name in model.model_fields_set:
        field = type(model).model_fields[name]
        used = (field.json_schema_extra or {}).get("used_by", list(ALL))
        label = name if not path else f"{name} in [{'.'.join(path)}]"
        if command not in used:
            out.append((label, used))
            continue
        value = getattr(model, name)
        if isinstance(value, Section):
            out += _unused_keys(value, command, path + (name,))
    return out


# --------------------------------------------------------------------------- schema and reference
def _clean_defaults(node):
    """Schema defaults as a user sees them: the registry's value where a key has one, none where
    the default is "not given" (None)."""
    if isinstance(node, dict):
        extra = node.get("default_from")
        if "default" in node and node["default"] is None:
            del node["default"]
            if extra and "/" not in extra:
                node["default"] = DEFAULTS[extra][0]
        for v in node.values():
            _clean_defaults(v)
    elif isinstance(node, list):
        for v in node:
            _clean_defaults(v)
    return node


def json_schema():
    """The JSON Schema of a job file (draft 2020-12), for editors that complete TOML/JSON."""
    schema = _clean_defaults(Job.model_json_schema())
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "akf job file"
    return schema


def json_schema_text():
    return json.dumps(json_schema(), indent=2, sort_keys=True) + "\n"


def _type_text(field):
    return (field.json_schema_extra or {}).get("expect", "")


#: defaults that the runners apply (documented here; the values live with the code that uses them:
#: the thesis' GA settings in sensoropt.ga.THESIS, the tuning GA's in impactloc.tuning)
_DOC_DEFAULTS = {
    ("Measurements", "time_column"): '"time"', ("Measurements", "remove_offset"): "false",
    ("Measurements", "bridge"): '"quarter"', ("Output", "format"): '"csv"', ("Output", "strains"): '"all"', ("Simulation", "seed"): "0",
    ("Place", "kinds"): '["ex", "ey", "gxy"]', ("Place", "operators"): '"set"', ("Place", "n_modes"): '"auto"',
    ("Place", "population"): "50", ("Place", "generations"): "100", ("Place", "elite"): "2",
    ("Place", "crossover"): "0.8", ("Place", "mutation"): "0.16", ("Place", "tournament"): "4",
    ("Place", "stall_generations"): "50", ("Locate", "ad_kinds"): '["strain"]', ("Locate", "tune"): "true",
    ("Locate", "n_modes"): '"auto"', ("Locate", "skip"): "0.0", ("Tuning", "population"): "12",
    ("Tuning", "generations"): "8", ("Tuning", "n_splits"): "8", ("Tuning", "decades"): "3.0",
    ("Tuning", "crossover"): "0.7", ("Tuning", "mutation"): "0.3", ("Filter", "allow_undetectable"): "false",
}


def _default_text(field, model=None, name=None):
    if model is not None and (model.__name__, name) in _DOC_DEFAULTS:
        return _DOC_DEFAULTS[(model.__name__, name)]
    extra = field.json_schema_extra or {}
    names = extra.get("default_from")
    if names:
        return " / ".join(_toml_value(DEFAULTS[n.strip()][0]) for n in names.split("/"))
    if extra.get("default_text"):
        return extra["default_text"]
    return ""


def _toml_value(value):
    """A default as it is written in a TOML file."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value)


def reference_markdown():
    """The job-file reference (Markdown): one table per section, generated from the schema."""
    lines = ["# Job-file reference", "",
             "Generated from `akf.schema` (`python -m akf.schema`); do not edit by hand. Every key is optional "
             "for the schema; a command refuses a job that lacks a key it needs (estimate: "
             + ", ".join(REQUIRED["estimate"]) + " and `[simulation]` or `[measurements]`; place: "
             + ", ".join(REQUIRED["place"]) + "; locate: " + ", ".join(REQUIRED["locate"])
             + ", `n_ad` and `direction` in `[locate]`, and `[measurements]` or `[simulation]`) or that sets a key it does not read. "
             "A default with two values is estimate / place. Units are SI.", "",
             "An editor completes job files from the JSON Schema `akf/job.schema.json` "
             "(`python -m akf.schema --json`).", ""]
    sections = [("the top level", Job, None)] + [
        (f"[{n}]", _section_model(f.annotation), n) for n, f in Job.model_fields.items()
        if _section_model(f.annotation) is not None]
    sections.insert(sections.index(next(s for s in sections if s[2] == "locate")) + 1,
                    ("[locate.covariances]", CovariancesSection, "locate.covariances"))
    sections.append(("[locate.tuning]", Tuning, "locate.tuning"))
    sections.insert(sections.index(next(s for s in sections if s[2] == "output")) + 1,
                    ("[output.fatigue]", Fatigue, "output.fatigue"))
    sections.append(("[[simulation.loads]] components", LoadComponent, "loads"))
    for title, model, _ in sections:
        lines += [f"## {title}", "", (model.__doc__ or "").strip().splitlines()[0], "",
                  "| key | type | default | unit | used by | meaning |", "|---|---|---|---|---|---|"]
        for name, field in model.model_fields.items():
            if title == "the top level" and _section_model(field.annotation) is not None:
                continue
            extra = field.json_schema_extra or {}
            lines.append(f"| `{name}` | {_type_text(field)} | {_default_text(field, model, name)} | {extra.get('unit', '')} | "
                         f"{', '.join(extra.get('used_by', ALL))} | {field.description or ''} |")
        lines.append("")
    return "\n".join(lines)


def _main(argv=None):
    import argparse

    parser = argparse.ArgumentParser(prog="python -m akf.schema", description="print the job-file JSON Schema or "
                                     "the Markdown reference")
    parser.add_argument("--json", action="store_true", help="the JSON Schema (default: the Markdown reference)")
    args = parser.parse_args(argv)
    print(json_schema_text() if args.json else reference_markdown(), end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(_main())
