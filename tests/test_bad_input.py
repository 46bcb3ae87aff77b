"""Bad input gets a clear message, never a traceback or a silent result.

``API_CASES`` and ``JOB_CASES`` are the corpus of plausible user mistakes: each entry is an input
and the message it must produce.  ``CLI_CASES`` run through ``akf`` and check the exit code (2
for bad input) and the message on stderr.  Property-based tests (hypothesis) then throw random
job values and random array shapes at the same entry points: every outcome is a result or an
:class:`AKFInputError`.
"""
import copy
import os
import re

import numpy as np
import pandas as pd
import pytest
from helpers import run_estimate

from akf.cli import main
from core_akf import AKFInputError, UndetectableError
from core_akf import filter as akf
from core_akf.calibration import calibrate
from core_akf.fatigue import FatigueAccumulator, SNCurve, damage, equivalent_range, rainflow
from core_akf.filter import estimate
from core_akf.forcemodels import DummyMeasurements, ForceModel
from core_akf.models import plate, s17_truss
from core_akf.simulate import simulate
from core_akf.structure import Structure

SENSORS = ["acc:4:y", "acc:8:y", "strain:5", "strain:13"]
FORCES = ["8:y"]
DT = 1 / 1024


def _small_run_inputs(n=6, m=2, N=20):
    rng = np.random.default_rng(0)
    A = 0.9 * np.eye(n)
    G = rng.normal(size=(m, n))
    return A, G, 1e-2 * np.eye(n), 1e-2 * np.eye(m), rng.normal(size=(N, m))


def _run(**change):
    A, G, Q, R, Y = _small_run_inputs()
    kw = dict(A_a=A, G_a=G, Q_a=Q, R=R, Y=Y)
    kw.update(change)
    return akf.run(**kw)


def _measured(n=256):
    """Simulated measurements of SENSORS (N x 4) for the small truss job."""
    t = np.arange(n) * DT
    sim = simulate(s17_truss(), SENSORS, FORCES, (800 * np.sin(2 * np.pi * 5 * t))[:, None], DT,
                   relative_noise=0.02, seed=1)
    return sim.measurements


def _estimate(**change):
    kw = dict(structure=s17_truss(), sensors=SENSORS, forces=FORCES, measurements=_measured(), dt=DT,
              model_error_cov=1e-16, force_increment_cov=1e4, noise_cov={"strain": 1e-14, "acc": 1e-2})
    kw.update(change)
    return estimate(**kw)


def _indefinite(n):
    M = np.eye(n)
    M[0, 1] = M[1, 0] = 2.0                   # eigenvalues -1, 3, 1, ...
    return M


def _stream(chunk):
    """One chunk through a streaming Estimator of the small truss job."""
    est = akf.Estimator(s17_truss(), SENSORS, FORCES, DT, model_error_cov=1e-16, force_increment_cov=1e4,
                        noise_cov={"strain": 1e-14, "acc": 1e-2})
    return est.update(chunk)


def _locate(**change):
    """impactloc.locate on a short simulated impact at joint 8 of the truss, with ``change``."""
    from impactloc import locate, simulate_impact

    sensors = ["acc:4:y", "acc:8:y", "acc:12:y", "strain:5", "strain:9", "strain:13", "strain:26"]
    sim = simulate_impact(s17_truss(), sensors, "8:y", record=0.3, seed=1)
    kw = dict(n_ad=2, direction="y", tune=False, max_splits=2, candidates=[8, 10])
    kw.update(change)
    return locate(s17_truss(), sensors, kw.pop("measurements", sim.measurements), sim.dt, **kw)


def _place(**change):
    """A short GA (sensoropt.place) of 3 sensors on the truss, a toy objective, with ``change``."""
    from sensoropt import CandidateSet, FunctionObjective, place

    kw = dict(population=6, generations=1, seed=0)
    kw.update(change)
    return place(FunctionObjective(lambda sensors: float(len(sensors))),
                 CandidateSet(s17_truss(), kinds=("strain", "acc"), n_sensors=3), **kw)


API_CASES = {
    "Q_a not symmetric": (lambda: _run(Q_a=np.triu(np.ones((6, 6))) * 1e-2), "Q_a is not symmetric"),
    "Q_a indefinite": (lambda: _run(Q_a=1e-2 * _indefinite(6)), "Q_a must be positive semi-definite"),
    "R = 0": (lambda: _run(R=np.zeros((2, 2))), "R must be positive definite"),
    "R indefinite": (lambda: _run(R=_indefinite(2)), "R must be positive definite"),
    "R not symmetric": (lambda: _run(R=np.array([[1.0, 0.5], [0.0, 1.0]])), "R is not symmetric"),
    "P0 = -I": (lambda: _run(P0=-np.eye(6)), "P0 must be positive semi-definite"),
    "complex data": (lambda: _run(Y=np.ones((20, 2)) * (1 + 1j)), "complex"),
    "NaN data": (lambda: _run(Y=np.full((20, 2), np.nan)), "NaN"),
    "no time steps": (lambda: _run(Y=np.zeros((0, 2))), "no time steps"),
    "A_a not square": (lambda: _run(A_a=np.eye(6)[:5]), "A_a must be square"),
    "G_a wrong columns": (lambda: _run(G_a=np.ones((2, 5))), "G_a has 5 columns"),
    "R wrong size": (lambda: _run(R=np.eye(3)), "R must be 2x2"),
    "Y wrong channels": (lambda: _run(Y=np.ones((20, 3))), "3 channels"),
    "x0 wrong size": (lambda: _run(x0=np.zeros(5)), "x0 must have 6 entries"),
    "text as data": (lambda: _run(Y=[["a", "b"]] * 20), "must be numeric"),
    "numbers as text": (lambda: _run(Y=np.ones((20, 2)).astype(str)), "must be numeric .*, not text"),
    "true/false data": (lambda: _run(Y=np.ones((20, 2)) > 0), "must be numeric .*, not true/false values"),
    "noise_cov negative": (lambda: _estimate(noise_cov={"strain": -1e-14, "acc": 1e-2}),
                           r"noise_cov\['strain'\] must be a positive variance"),
    "noise_cov zero": (lambda: _estimate(noise_cov={"strain": 0.0, "acc": 1e-2}),
                       r"noise_cov\['strain'\] must be a positive variance"),
    "noise_cov kind missing": (lambda: _estimate(noise_cov={"strain": 1e-14}), r"no variance for sensor kind\(s\) \['acc'\]"),
    "noise_cov not symmetric": (lambda: _estimate(noise_cov=np.triu(np.ones((4, 4)))), "noise_cov is not symmetric"),
    "noise_cov as bool": (lambda: _estimate(noise_cov=True), "noise_cov must be a number"),
    "model_error_cov indefinite": (lambda: _estimate(model_error_cov=1e-16 * _indefinite(66)),
                                   "model_error_cov must be positive semi-definite"),
    "force_increment_cov negative": (lambda: _estimate(force_increment_cov=-1.0),
                                     "force_increment_cov must be positive semi-definite"),
    "P0 = -I in estimate": (lambda: _estimate(P0=-np.eye(67)), "P0 must be positive semi-definite"),
    "columns != sensors": (lambda: _estimate(measurements=np.ones((10, 3))), "3 columns for 4 sensors"),
    "unknown member": (lambda: _estimate(sensors=SENSORS[:3] + ["strain:99"]), "unknown member 99"),
    "unknown joint": (lambda: _estimate(sensors=SENSORS[:3] + ["acc:40:y"]), "unknown node/joint 40"),
    "duplicate sensor": (lambda: _estimate(sensors=SENSORS[:3] + ["strain:5"]), "duplicate sensor strain:5"),
    "force on a support": (lambda: _estimate(forces=["1:y"]), "constrained"),
    "dt = 0": (lambda: _estimate(dt=0.0), "time step dt must be a positive number"),
    "dt NaN": (lambda: _estimate(dt=float("nan")), "time step dt must be a positive number"),
    "dt as text": (lambda: _estimate(dt="0.001"), "time step dt must be a positive number of seconds, got '0.001'"),
    "dt as an array": (lambda: _estimate(dt=np.array([1e-3, 2e-3])), "time step dt must be a positive number"),
    "dt as true": (lambda: _estimate(dt=True), "time step dt must be a positive number"),
    "a chunk of text": (lambda: _stream([["a", "b", "c", "d"]] * 5), "a chunk of measurements must be numeric .*, not text"),
    "a chunk of numbers as text": (lambda: _stream(_measured()[:5].astype(str)), "must be numeric .*, not text"),
    "a chunk of true/false": (lambda: _stream(_measured()[:5] > 0), "must be numeric .*, not true/false values"),
    "a complex chunk": (lambda: _stream(_measured()[:5] * (1 + 1j)), "a chunk of measurements is complex"),
    "candidate node as text": (lambda: _locate(candidates=["8"]), r"candidate node\(s\) \['8'\] are not node numbers"),
    "fractional candidate node": (lambda: _locate(candidates=[8.5]), r"candidate node\(s\) \[8.5\] are not node numbers"),
    "negative skip": (lambda: _locate(skip=-1.0), r"skip must be a time >= 0 \(s\), got -1.0"),
    "NaN skip": (lambda: _locate(skip=float("nan")), r"skip must be a time >= 0 \(s\), got nan"),
    "no workers": (lambda: _locate(n_jobs=0), r"n_jobs must be a whole number of workers >= 1 \(or -1: every core\)"),
    "negative seed": (lambda: _locate(seed=-1), "seed must be a whole number >= 0, got -1"),
    "fractional seed": (lambda: _locate(seed=1.5), "seed must be a whole number >= 0, got 1.5"),
    "a tuning setting misspelt": (lambda: _locate(tune=True, tuning={"generation": 3}),
                                  r"tuning has unknown setting\(s\) \['generation'\]"),
    "tuning as text": (lambda: _locate(tune=True, tuning="fast"), "tuning must be a dict of tune_covariances settings"),
    "a force model as text": (lambda: _locate(force_model="matern"), "force_model must be a core_akf.forcemodels.ForceModel"),
    "impact record of true/false": (lambda: _locate(measurements=np.ones((300, 7)) > 0), "not true/false values"),
    "a noise seed below zero": (lambda: simulate(s17_truss(), ["acc:4:y"], FORCES, np.ones((5, 1)), DT,
                                                 relative_noise=0.1, seed=-3),
        "seed must be a whole number >= 0, got -3"),
    "fractional population": (lambda: _place(population=6.5), "population must be a whole number >= 2, got 6.5"),
    "population as text": (lambda: _place(population="6"), "population must be a whole number >= 2, got '6'"),
    "crossover above 1": (lambda: _place(crossover=2.0), "crossover must be a probability between 0 and 1, got 2.0"),
    "negative mutation": (lambda: _place(mutation=-1.0), "mutation must be a probability between 0 and 1"),
    "tournament of none": (lambda: _place(tournament=0), "tournament must be a whole number >= 1, got 0"),
    "negative stall": (lambda: _place(stall_generations=-1), "stall_generations must be a whole number >= 0"),
    "checkpoint every 0": (lambda: _place(checkpoint_every=0), "checkpoint_every must be a whole number >= 1"),
    "checkpoint a folder": (lambda: _place(checkpoint=os.getcwd()), "is a folder; give the checkpoint file's path"),
    "NaN penalty": (lambda: _place(penalty=float("nan")), "penalty must be a positive number"),
    "an initial layout too short": (lambda: _place(initial=[["strain:5"]]),
                                    r"initial layout 1 \(1 sensors: \['strain:5'\]\) is not a layout of this search "
                                    r"\(3 sensors, each a candidate once\)"),
    "on_generation as text": (lambda: _place(on_generation="print"), "on_generation must be a function"),
    "a chunk of lists": (lambda: _stream([[1.0, [2.0], 3.0, 4.0]] * 5), "a chunk of measurements must be numeric"),
    "undetectable set": (lambda: _estimate(sensors=["acc:4:y", "acc:8:y", "strain:9"],
                                           measurements=_measured()[:, :3]), "not detectable"),
    "steady on undetectable": (lambda: _estimate(sensors=["acc:4:y", "acc:8:y", "strain:9"], steady=True,
                                                 allow_undetectable=True, measurements=_measured()[:, :3]),
                               "steady-state AKF does not exist"),
    # arguments of another type, each a TypeError/AttributeError/ValueError from inside before
    "a structure that is a path": (lambda: _estimate(structure="model.toml"), "structure must be a Structure .*, got str"),
    "forces left out": (lambda: _estimate(forces=None), "forces must be a list of force locations"),
    "one sensor as a number": (lambda: _estimate(sensors=5.0), "sensors must be a list of sensor labels"),
    "layouts as a number": (lambda: akf.estimate_batch(s17_truss(), -1, FORCES, np.ones((1, 10, 4)), DT,
                                                       model_error_cov=1e-16, force_increment_cov=1e4, noise_cov=1e-8),
                            "layouts must be a list of sensor layouts"),
    "FilterModel dt as empty text": (lambda: akf.FilterModel(s17_truss(), FORCES, ""), "time step dt must be a positive"),
    "calibrate parameters as a number": (
        lambda: calibrate(s17_truss(), SENSORS, FORCES, _measured(), DT, parameters=1, model_error_cov=1e-16,
                          force_increment_cov=1e4, noise_cov={"strain": 1e-14, "acc": 1e-2}),
        "parameters must be a list of parameter names"),
    "damage with swapped arguments": (lambda: damage(SNCurve.ec3(71), rainflow([0.0, 1e8, 0.0])),
                                      "cycles must be the Cycles that rainflow\\(\\) counts, got SNCurve \\(were the "
                                      "arguments swapped\\?\\)"),
    "an S-N curve that is a number": (lambda: damage(rainflow([0.0, 1e8, 0.0]), 71), "curve must be an SNCurve"),
    "a slope as text": (lambda: equivalent_range(rainflow([0.0, 1e8, 0.0]), "3", 2e6), "needs a slope m > 0"),
    "fatigue of 1e300 outputs": (lambda: FatigueAccumulator(1e300, SNCurve.ec3(71)), "fatigue of 1e\\+300 outputs: .* need about"),
    "an S-N curve of objects": (lambda: SNCurve([1e6, 2e6], [object(), 1e8]), "must be numbers"),
    "a force model kind that is no text": (lambda: ForceModel(kind=["matern32"]), "unknown force model"),
    "dummy sensors as a number": (lambda: DummyMeasurements(sensors=1e-3, variance=1e-8), "dummy sensors must be a list"),
    "a plate of 1e300 elements": (lambda: plate(1e300, 4, 1.0, 1.0, 0.01, 2e11, 0.3, 7800.0),
                                  "a plate mesh of 1e\\+300 x 4 elements: .* need about"),
    "a plate of text elements": (lambda: plate("4", 4, 1.0, 1.0, 0.01, 2e11, 0.3, 7800.0), "must be a whole number"),
    "a complex plate length": (lambda: plate(4, 4, 1j, 1.0, 0.01, 2e11, 0.3, 7800.0), "ly|lx must be a positive number"),
    "a plate beyond memory": (lambda: plate(10 ** 6, 10 ** 6, 1.0, 1.0, 0.01, 2e11, 0.3, 7800.0),
                              "a plate mesh of 1e\\+06 x 1e\\+06 elements: .* need about"),
    "a complex Young's modulus": (lambda: s17_truss(E=1j), "E must be a positive number"),
    "a truss height as text": (lambda: s17_truss(height=""), "height must be a positive number"),
    "a series of objects": (lambda: rainflow({}), "a series is an array of numbers"),
    "singular mass": (lambda: Structure(M=np.diag([1.0, 0.0]), K=np.eye(2), nodes=[[0, 0]], dof_names=("x", "y"),
                                        free_dofs=[0, 1]), "mass matrix M is singular"),
    "K not symmetric": (lambda: Structure(M=np.eye(2), K=np.array([[2.0, 1.0], [0.0, 2.0]]), nodes=[[0, 0]],
                                          dof_names=("x", "y"), free_dofs=[0, 1]), "stiffness matrix K is not symmetric"),
}


@pytest.mark.parametrize("name", list(API_CASES))
def test_api_bad_input(name):
    make, message = API_CASES[name]
    with pytest.raises(AKFInputError, match=message):
        make()


def test_undetectable_is_its_own_error():
    with pytest.raises(UndetectableError):
        API_CASES["undetectable set"][0]()


# ----------------------------------------------------------------------------------- job files
def _job(**sections):
    job = {"name": "small", "dt": DT, "sensors": list(SENSORS), "forces": list(FORCES),
           "structure": {"model": "s17_truss"},
           "filter": {"model_error_cov": 1e-16, "force_increment_cov": 1e4},
           "simulation": {"duration": 0.1, "relative_noise": 0.02, "seed": 0,
                          "loads": [{"components": [{"type": "sine", "frequency": 5.0, "amplitude": 800.0}]}]}}
    for path, value in sections.items():
        where = job
        keys = path.split("__")
        for k in keys[:-1]:
            where = where.setdefault(k, {}) if isinstance(where, dict) else where
        if value is _DELETE:
            del where[keys[-1]]
        else:
            where[keys[-1]] = value
    return job


_DELETE = object()


def measured_job(tmp_path, frame, **extra):
    path = tmp_path / "data.csv"
    if isinstance(frame, str):
        path.write_text(frame)
    else:
        frame.to_csv(path, index=False)
    return _job(simulation=_DELETE, measurements={"file": str(path)},
                filter={"model_error_cov": 1e-16, "force_increment_cov": 1e4,
                        "noise_cov": {"strain": 1e-14, "acc": 1e-2}}, **extra)


def _frame(n=256, t=None, **columns):
    Y = _measured(n)
    df = pd.DataFrame(Y, columns=SENSORS)
    df.insert(0, "time", np.arange(n) * DT if t is None else t)
    for k, v in columns.items():
        df[k.replace("_", ":")] = v
    return df


JOB_CASES = {
    "steady = 'no'": (lambda tp: _job(filter__steady="no"), "steady in \\[filter\\] must be true or false"),
    "allow_undetectable = 'no'": (lambda tp: _job(filter__allow_undetectable="no"),
                                  "allow_undetectable in \\[filter\\] must be true or false"),
    "n_modes = 0": (lambda tp: _job(filter__n_modes=0), "n_modes in \\[filter\\] must be an integer >= 1"),
    "dt = false": (lambda tp: _job(dt=False), "dt in the job must be a positive number"),
    "dt = '1ms'": (lambda tp: _job(dt="1ms"), "dt in the job must be a positive number"),
    "seed = 0.0": (lambda tp: _job(simulation__seed=0.0), "seed in \\[simulation\\] must be an integer >= 0"),
    "dt = 1e-300": (lambda tp: _job(dt=1e-300), "GiB"),
    "duration = -1": (lambda tp: _job(simulation__duration=-1.0), "duration in \\[simulation\\] must be a positive number"),
    "duration shorter than a step": (lambda tp: _job(simulation__duration=1e-4), "shorter than two steps"),
    "noise_cov negative": (lambda tp: _job(filter__noise_cov={"strain": -1.0, "acc": 1.0}), "noise_cov in \\[filter\\]"),
    "noise_cov string": (lambda tp: _job(filter__noise_cov="big"), "noise_cov in \\[filter\\]"),
    "typo in a key": (lambda tp: _job(filter__stifness_factor=1.05), "did you mean 'stiffness_factor'"),
    "sensors as one string": (lambda tp: _job(sensors="strain:13"), "sensors in the job must be a non-empty list"),
    "stiffness_factor = 0": (lambda tp: _job(filter__stiffness_factor=0), "stiffness_factor in \\[filter\\]"),
    "relative_noise = '2%'": (lambda tp: _job(simulation__relative_noise="2%"), "relative_noise in \\[simulation\\]"),
    "relative_noise = 1e300": (lambda tp: _job(simulation__relative_noise=1e300),
                               "\\[simulation\\] relative_noise must be a fraction of each channel's RMS between 0 and 10"),
    "absolute_noise of 1e9 mg": (lambda tp: _job(simulation__absolute_noise={"acc_mg": 1e9, "microstrain": 1.0}),
                                 "\\[simulation\\] absolute_noise of acc = 9.807e\\+06 m/s\\^2: a standard deviation"),
    "stiffness_factor = 1e-12": (lambda tp: _job(filter__stiffness_factor=1e-12),
                                 "\\[filter\\] stiffness_factor = 1e-12 multiplies the model's stiffness"),
    "model_error_cov negative": (lambda tp: _job(filter__model_error_cov=-1e-16), "model_error_cov in \\[filter\\]"),
    "no sensors key": (lambda tp: _job(sensors=_DELETE), "the job has no 'sensors'"),
    "unknown model": (lambda tp: _job(structure={"model": "bridge"}), "model in \\[structure\\] must be one of"),
    "noise_cov simulated on measured data": (lambda tp: dict(measured_job(tp, _frame()), filter={"noise_cov": "simulated"}),
                                             "needs a simulated job"),
    "measurement file missing": (lambda tp: _job(simulation=_DELETE, measurements={"file": str(tp / "nope.csv")}),
                                 "not found"),
    "measurement folder without data files": (lambda tp: _job(simulation=_DELETE, measurements={"file": str(tp)}),
                                               "has no data files"),
    "empty CSV": (lambda tp: measured_job(tp, ""), "the file is empty"),
    "header-only CSV": (lambda tp: measured_job(tp, "time," + ",".join(SENSORS) + "\n"), "0 data row"),
    "strings in data": (lambda tp: measured_job(tp, _frame(strain_13=["x"] * 256)),
                        "column 'strain:13' has 256 non-numeric sample"),
    "infinity in data": (lambda tp: measured_job(tp, _frame(strain_13=np.r_[np.ones(100), np.inf, np.ones(155)] * 1e-6)),
                         "'strain:13' has 1 infinite sample"),
    "duplicate time stamps": (lambda tp: measured_job(tp, _frame(t=np.r_[0.0, np.arange(255) * DT])),
                              "time repeats at data row 2"),
    "time goes back": (lambda tp: measured_job(tp, _frame(t=np.r_[np.arange(100), 50, np.arange(101, 256)] * DT)),
                       "time goes back at data row 101"),
    "a gap in the record": (lambda tp: measured_job(tp, _frame(t=np.r_[np.arange(128), np.arange(129, 257)] * DT)),
                            "data row 129 .* off the uniform grid"),
    "another sampling rate": (lambda tp: measured_job(tp, _frame(t=np.arange(256) * DT * 2)),
                              "sampling interval 0.001953125 s .* does not match the job's dt = 0.0009765625 s"),
    "constant channel": (lambda tp: measured_job(tp, _frame(acc_8_y=np.full(256, 0.5))), "'acc:8:y' is constant"),
    "all-zero data": (lambda tp: measured_job(tp, _frame(**{k.replace(":", "_"): np.zeros(256) for k in SENSORS})),
                      "is constant \\(0\\)"),
    "strain in microstrain": (lambda tp: measured_job(tp, _frame(strain_5=_measured()[:, 2] * 1e6)),
                              "'strain:5' has an RMS of .* it looks like microstrain"),
    "strain:99 on measured data": (lambda tp: dict(measured_job(tp, _frame()), sensors=SENSORS[:3] + ["strain:99"]),
                                   "unknown member 99"),
}


@pytest.mark.parametrize("name", list(JOB_CASES))
def test_job_bad_input(name, tmp_path):
    make, message = JOB_CASES[name]
    with pytest.raises(AKFInputError, match=message):
        run_estimate(make(tmp_path))


def test_time_column_rounded_to_six_decimals_is_accepted(tmp_path):
    """A DAQ that prints the time with 6 decimals is off the grid by <= 5e-7 s (0.05 % of a step)."""
    job = measured_job(tmp_path, _frame(t=np.round(np.arange(256) * DT, 6)))
    res = run_estimate(job)
    assert res.metrics["n_steps"] == 256


def test_messages_print_unequal_numbers_unequally(tmp_path):
    with pytest.raises(AKFInputError) as err:
        run_estimate(measured_job(tmp_path, _frame(t=np.arange(256) * DT * 1.05)))
    msg = str(err.value)
    assert "0.00102539062" in msg and "0.0009765625" in msg


# --------------------------------------------------------------------------------------- CLI
def _write_job(tmp_path, text):
    p = tmp_path / "job.toml"
    p.write_text(text)
    return str(p)


CLI_CASES = {
    "--out is a file": (lambda tp: (tp / "f").write_text("x") and ["estimate", "--example", "s17-case4", "--duration",
                                                                     "0.05", "--no-plot", "--out", str(tp / "f")],
                        "is a file, not a folder"),
    "--out cannot be created": (lambda tp: ["estimate", "--example", "s17-case4", "--no-plot", "--out", "/proc/akf-out"],
                                "cannot create --out"),
    "job file missing": (lambda tp: ["estimate", str(tp / "missing.toml")], "not found"),
    "job file is a folder": (lambda tp: ["estimate", str(tp)], "is a folder"),
    "job file not TOML": (lambda tp: ["estimate", _write_job(tp, "dt = = 1")], "not valid TOML"),
    "string for a boolean": (lambda tp: ["estimate", _write_job(tp, 'dt = 0.001\nsensors = ["strain:5"]\n'
                                                                'forces = ["8:y"]\n[structure]\nmodel = "s17_truss"\n'
                                                                '[filter]\nsteady = "no"\n')],
                             "steady in \\[filter\\] must be true or false"),
    "unknown example": (lambda tp: ["estimate", "--example", "nope"], "unknown example 'nope'"),
    "locate: strain:99 on measured data": (lambda tp: ["locate", _write_job(tp, 'dt = 0.001\nsensors = ["strain:5", '
                                                                     '"strain:99", "acc:8:y"]\n[structure]\nmodel = '
                                                                     '"s17_truss"\n[locate]\nn_ad = 1\ndirection = "y"\n'
                                                                     '[measurements]\nfile = "x.csv"\n'),
                                                       "--out", str(tp / "o")], "unknown member 99"),
}


@pytest.mark.parametrize("name", list(CLI_CASES))
def test_cli_bad_input_exit_2(name, tmp_path, capsys):
    make, message = CLI_CASES[name]
    rc = main(make(tmp_path))
    err = capsys.readouterr().err
    assert rc == 2, err
    assert err.startswith("akf: error: ")
    assert __import__("re").search(message, err), err


@pytest.mark.parametrize("command, value, message", [
    ("place --example th-case5", "0", "a number of workers is >= 1, or negative (-1: all cores), not 0"),
    ("locate --example imp-truss-case1", "0", "a number of workers is >= 1, or negative (-1: all cores), not 0"),
    ("study s17_truss --quick", "0", "a number of workers is >= 1, or negative (-1: all cores), not 0"),
    ("estimate --example s17-case4", "two", "a number of workers is a whole number (-1: all cores), got 'two'"),
])
def test_n_jobs_that_is_no_number_of_workers_is_refused_by_every_command(command, value, message, tmp_path, capsys):
    """`akf study --n-jobs 0` ran (the studies that use no workers ignored it); every command now
    refuses it as it parses its flags, as it does a seed."""
    with pytest.raises(SystemExit) as stop:
        main([*command.split(), "--n-jobs", value, "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and f"argument --n-jobs: {message}" in err, err


def test_second_run_into_a_locked_folder_refuses(tmp_path, capsys):
    from akf.outputs import OutputFolder
    with OutputFolder(str(tmp_path), "--out"):
        rc = main(["estimate", "--example", "s17-case4", "--duration", "0.05", "--no-plot", "--out", str(tmp_path)])
    assert rc == 2
    assert "in use by another akf run" in capsys.readouterr().err
    assert not (tmp_path / "timeseries.csv").exists()
    # a lock left by a process that no longer exists is stale and taken over
    (tmp_path / ".akf-run.lock").write_text(f"999999999 {__import__('socket').gethostname()} 2026-01-01 00:00:00\n")
    assert main(["estimate", "--example", "s17-case4", "--duration", "0.05", "--no-plot", "--out", str(tmp_path)]) == 0
    assert not (tmp_path / ".akf-run.lock").exists()


def test_two_concurrent_cli_runs_never_mix_outputs(tmp_path):
    """Two processes into one --out: one writes, the other refuses (exit 2); the file parses."""
    import subprocess
    import sys
    cmd = [sys.executable, "-m", "akf", "estimate", "--example", "s17-case4", "--duration", "1",
           "--no-plot", "--out", str(tmp_path)]
    procs = [subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    codes = sorted(p.wait(timeout=300) for p in procs)
    errs = [p.stderr.read() for p in procs]
    assert codes in ([0, 0], [0, 2]), errs                 # sequential by chance, or one refused
    if codes == [0, 2]:
        assert any("in use by another akf run" in e for e in errs)
    ts = pd.read_csv(tmp_path / "timeseries.csv")
    assert len(ts) == 4096 * (4 + 34)                     # one complete run: 1 s at 4096 Hz
    assert not [f for f in os.listdir(tmp_path) if f.endswith(".tmp.csv") or f.startswith(".timeseries")]


def test_ctrl_c_exits_130_and_leaves_no_partial_file(tmp_path, capsys, monkeypatch):
    import core_akf.outputs as outputs

    real = outputs.write_csv
    calls = []

    def interrupted(frame, path, **kw):
        calls.append(path)
        if len(calls) == 1:           # summary.csv is being written (timeseries.csv is appended chunk by chunk)
            with outputs.atomic_path(path) as tmp:
                frame.head(5).to_csv(tmp)
                raise KeyboardInterrupt
        return real(frame, path, **kw)

    monkeypatch.setattr("akf.estimate.files.write_csv", interrupted)
    rc = main(["estimate", "--example", "s17-case4", "--duration", "0.05", "--no-plot", "--out", str(tmp_path)])
    assert rc == 130
    assert "interrupted after the whole record was filtered: timeseries.csv is complete" in capsys.readouterr().err
    assert (tmp_path / "timeseries.csv").exists()          # complete
    assert not (tmp_path / "summary.csv").exists()         # absent, not partial
    assert sorted(os.listdir(tmp_path)) == [".akf-files", "timeseries.csv"]        # and the list of what akf wrote


def test_place_refuses_to_overwrite_a_checkpoint_and_checks_it(tmp_path, capsys):
    args = ["place", "--example", "th-case5", "--generations", "1", "--population", "4", "--no-plot", "--json",
            "--out", str(tmp_path)]
    assert main(args) == 0
    assert main(args) == 0                 # a finished run's checkpoint: the rerun simply runs
    capsys.readouterr()
    ck = tmp_path / "checkpoint.json"
    ck.write_bytes(ck.read_bytes()[:100])                  # truncated
    assert main(args + ["--resume"]) == 2
    assert "is truncated or not a GA checkpoint" in capsys.readouterr().err
    ck.write_bytes(b"not JSON at all")
    assert main(args + ["--resume"]) == 2
    assert "truncated or not a GA checkpoint" in capsys.readouterr().err


def _interrupted_place(tmp_path, capsys):
    """A place run of 2 generations checkpointed every one, its checkpoint made 'interrupted' at 1."""
    import json

    from core_akf.evolution import load_checkpoint, save_checkpoint

    args = ["place", "--example", "th-case5", "--generations", "2", "--population", "4", "--no-plot", "--json",
            "--out", str(tmp_path)]
    assert main(args) == 0
    capsys.readouterr()
    ck = tmp_path / "checkpoint.json"
    data = load_checkpoint(str(ck))
    data.update(finished=False, generation=1, rows=data["rows"][:2])
    save_checkpoint(str(ck), data)
    os.remove(f"{ck}.bak")
    return args, ck, json.loads(json.dumps(data))


GA_TAMPERING = {
    "an edited number": (lambda d: None, "was changed after it was written"),
    "a missing entry": (lambda d: d.pop("cache"), r"the entries \['cache'\] are missing"),
    "a genome off the candidates": (lambda d: d["population"][0].__setitem__(0, 10**6), "population entry 1 holds a genome"),
    "an unsorted genome": (lambda d: d["population"][1].reverse(), "population entry 2 holds a genome"),
    "a generation beyond the run": (lambda d: d.update(generation=7), "generation 7 is not one of this run's 0..2"),
    "a fitness of two numbers": (lambda d: d["fitness"][0].append(1.0), "population entry 1 has a fitness"),
    "a negative count": (lambda d: d.update(evaluations=-3), "evaluations = -3 is not a count"),
}


@pytest.mark.parametrize("case", list(GA_TAMPERING))
def test_a_tampered_ga_checkpoint_is_not_resumed(tmp_path, capsys, case):
    """Each was resumed silently or ended in an internal error: a checksum catches an edit, and the
    entries are checked one by one (here under a recomputed checksum)."""
    from core_akf.evolution import save_checkpoint

    args, ck, data = _interrupted_place(tmp_path, capsys)
    change, message = GA_TAMPERING[case]
    if case == "an edited number":
        ck.write_text(ck.read_text().replace('"evaluations": ', '"evaluations": 1', 1))
    else:
        change(data)
        save_checkpoint(str(ck), data)
    assert main(args + ["--resume"]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err), err


def test_overwrite_leaves_a_checkpoint_path_that_is_a_users_file(tmp_path, capsys):
    mine = tmp_path / "results.csv"
    mine.write_text("a,b\n1,2\n")
    args = ["place", "--example", "th-case5", "--generations", "1", "--population", "4", "--no-plot", "--json",
            "--out", str(tmp_path / "o"), "--checkpoint", str(mine), "--overwrite"]
    assert main(args) == 2
    assert "is not one (a file of yours?); it was left as it is" in capsys.readouterr().err
    assert mine.read_text() == "a,b\n1,2\n"
    args, ck, _ = _interrupted_place(tmp_path / "p", capsys)
    assert main(args + ["--overwrite"]) == 0                  # the run's own checkpoint is replaced


# ---------------------------------------------------------------------------- property based
hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_VALUES = st.one_of(st.none(), st.booleans(), st.integers(-3, 3), st.sampled_from([0.0, -1.0, 1e-300, 1e300, 0.5, 2.0]),
                    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=5),
                    st.lists(st.integers(-2, 2), max_size=3), st.dictionaries(st.text(max_size=3), st.integers(), max_size=2))
_PATHS = ["dt", "sensors", "forces", "name", "filter__steady", "filter__allow_undetectable", "filter__n_modes",
          "filter__model_error_cov", "filter__force_increment_cov", "filter__noise_cov", "filter__stiffness_factor",
          "simulation__duration", "simulation__seed", "simulation__relative_noise", "simulation__loads",
          "simulation__absolute_noise", "structure__model", "output__strains", "structure", "filter"]


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(path=st.sampled_from(_PATHS), value=_VALUES)
def test_any_job_value_gives_a_result_or_a_clear_error(path, value):
    job = _job(**{path: value})
    try:
        res = run_estimate(copy.deepcopy(job))
    except AKFInputError as exc:
        assert str(exc)
    else:
        assert np.all(np.isfinite(res.estimate.forces))


@settings(max_examples=80, deadline=None)
@given(n=st.integers(1, 5), m=st.integers(1, 3), N=st.integers(0, 4), batch=st.integers(0, 3),
       wrong=st.sampled_from(["", "A", "G", "Q", "R", "Y", "Yd"]))
def test_any_array_shape_gives_a_result_or_a_clear_error(n, m, N, batch, wrong):
    A = 0.5 * np.eye(n, n + (wrong == "A"))
    G = np.ones((m, n + (wrong == "G")))
    Q = np.eye(n + (wrong == "Q"))
    R = np.eye(m + (wrong == "R"))
    Y = np.ones((N, m + (wrong == "Y"))) if wrong != "Yd" else np.ones(N)
    if batch:
        Y = np.broadcast_to(Y, (batch,) + Y.shape) if Y.ndim == 2 else Y
    try:
        X = akf.run(A, G, Q, R, Y)
    except AKFInputError as exc:
        assert str(exc)
    else:
        assert X.shape[-1] == n and np.all(np.isfinite(X))


def test_locate_confidence_is_honest():
    """One candidate: nothing to compare (confidence 0). Data that no candidate explains (noise):
    confidence 0, not the share of votes; a warning says why."""
    from akf.examples.impact import example_scenario
    from impactloc.locate import locate
    sc = example_scenario("imp-truss-case1")
    kw = dict(n_ad=sc.n_ad, ad_kinds=sc.ad_kinds, direction=sc.direction, tune=False)
    one = locate(sc.structure, sc.sensors, sc.measurements, sc.dt, candidates=[14], **kw)
    assert one.scan.confidence == 0.0 and "only one candidate" in one.warnings[0]
    noise = np.random.default_rng(0).normal(size=sc.measurements.shape) * sc.measurements.std(axis=0)
    res = locate(sc.structure, sc.sensors, noise, sc.dt, **kw)
    assert res.scan.confidence == 0.0 and "no candidate explains the data" in res.warnings[0]
    good = locate(sc.structure, sc.sensors, sc.measurements, sc.dt, **kw)
    assert good.identified == (14, "y") and good.scan.confidence == 1.0 and not good.warnings


def test_tuning_at_a_search_bound_is_reported():
    from akf.examples.impact import example_scenario
    from impactloc.locate import locate
    sc = example_scenario("imp-truss-case1")
    res = locate(sc.structure, sc.sensors, sc.measurements, sc.dt, n_ad=sc.n_ad, ad_kinds=sc.ad_kinds,
                 direction=sc.direction, tuning={"decades": 0.3, "generations": 3, "population": 6})
    assert res.tuning.at_bound
    assert any("search bound" in w for w in res.warnings)


def test_estimates_say_when_they_cannot_be_trusted():
    """A forced undetectable run drifts; a record shorter than the filter's transient has not
    settled; a good run says nothing."""
    from akf.examples import example_job
    job = example_job("s17-case2")
    job["simulation"]["duration"] = 0.2
    res = run_estimate(job, allow_undetectable=True, steady=False)
    assert any("does not decay" in w for w in res.metrics["warnings"])
    job = example_job("s17-case4")
    job["simulation"]["duration"] = 0.02
    res = run_estimate(job)
    assert any("shorter than 3 time constants" in w for w in res.metrics["warnings"])
    job["simulation"]["duration"] = 1.0
    said = run_estimate(job).metrics["warnings"]        # the paper's S (1e5 N^2) is far above the loads' steps
    assert len(said) == 1 and said[0].startswith("innovations smaller than predicted at acc:")
    assert "Most likely force_increment_cov (S)" in said[0]
    job["filter"]["force_increment_cov"] = 5e3          # about what calibration finds: a good run says nothing
    assert run_estimate(job).metrics["warnings"] == []
