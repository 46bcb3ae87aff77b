"""One job object and one estimate pipeline (issue 20): a job is checked by the schema once per
run, whatever the command, and a simulated and a measured record go through the same function to
the same numbers."""
import json
import os

import numpy as np
import pandas as pd
import pytest
from helpers import ROOT as HELPERS_ROOT
from helpers import write_record

import akf.schema
from akf.cli import main
from akf.estimate import estimate_job
from akf.examples import example, example_job
from akf.job import Job, load_job

ROOT = str(HELPERS_ROOT)


@pytest.fixture
def validations(monkeypatch):
    """Counts every validation of a job against the schema (pydantic's ``model_validate`` of the
    top-level :class:`akf.schema.Job`), wherever it is called from."""
    calls = []
    original = akf.schema.Job.model_validate.__func__

    def counting(cls, *args, **kwargs):
        calls.append(cls)
        return original(cls, *args, **kwargs)
    monkeypatch.setattr(akf.schema.Job, "model_validate", classmethod(counting))
    return calls


@pytest.mark.parametrize("command", [
    ["estimate", "--example", "s17-case4", "--duration", "0.1", "--filter", "time-varying"],
    ["estimate", "examples/daq/s17-tdms.toml"],
    ["locate", "--example", "imp-truss-case1", "--no-tune"],
    ["locate", "examples/impacts/truss-impacts.toml", "--no-tune"],
    ["place", "--example", "th-case5", "--generations", "1", "--population", "4", "--window", "0.2"],
], ids=lambda c: " ".join(c[:3]))
def test_a_job_is_checked_once_per_run(command, validations, tmp_path, monkeypatch, capsys):
    args = [os.path.join(ROOT, a) if a.endswith(".toml") else a for a in command]
    monkeypatch.chdir(tmp_path)
    assert main(args + ["--no-plot", "--json", "--out", str(tmp_path / "o")]) == 0, capsys.readouterr().err
    assert len(validations) == 1


def test_a_python_run_checks_the_job_once(validations):
    job = example("s17-case4", overrides={"simulation.duration": 0.1})
    estimate_job(job)
    estimate_job(job)          # a Job is run again without a second check
    assert len(validations) == 1


def _simulated_and_measured(tmp_path, chunk_s):
    """A simulated job, and the same job reading its simulated record from a CSV file, both with
    the R of the simulated noise."""
    data = example_job("s17-case4")
    data["simulation"]["duration"] = 0.5
    simulated = Job.from_dict(data, "estimate")
    sim = simulated.simulate()
    R = [float(v) ** 2 for v in sim.noise_std]
    data["filter"]["noise_cov"] = R
    simulated = Job.from_dict(data, "estimate")
    write_record(sim, data["sensors"], data["dt"], tmp_path / "record.csv")
    measured = dict(data, measurements={"file": "record.csv", "chunk": chunk_s})
    del measured["simulation"]
    (tmp_path / "job.json").write_text(json.dumps(measured))
    return simulated, Job.from_dict(measured, "estimate", source=str(tmp_path / "job.toml"))


def test_a_simulated_and_a_measured_record_go_through_one_pipeline(tmp_path):
    """The same record, simulated (one chunk, with the truth) and read from a file in chunks of
    0.1 s: the same forces, strains, diagnostics and files from the one function."""
    simulated, measured = _simulated_and_measured(tmp_path, 0.1)
    a = estimate_job(simulated, str(tmp_path / "a"), plot=False)
    b = estimate_job(measured, str(tmp_path / "b"), plot=False)
    assert set(a.files) == {"timeseries", "summary"} and set(b.files) == {"timeseries", "summary", "data_quality"}
    ta, tb = (pd.read_csv(r.files["timeseries"]).sort_values(["channel", "time"], kind="stable", ignore_index=True)
              for r in (a, b))        # a chunked record's rows come chunk by chunk
    assert list(ta.columns) == list(tb.columns) and len(ta) == len(tb)
    np.testing.assert_allclose(tb["estimated"], ta["estimated"], rtol=1e-9, atol=1e-9 * np.abs(ta["estimated"]).max())
    assert ta["reference"].notna().all() and tb["reference"].isna().all()       # the truth beside a simulation only
    for x, y in zip(a.metrics["sensors"], b.metrics["sensors"]):
        assert x["channel"] == y["channel"] and x["consistency"] == pytest.approx(y["consistency"], rel=1e-9)
    for x, y in zip(a.metrics["forces"], b.metrics["forces"]):
        assert x["peak"] == pytest.approx(y["peak"], rel=1e-9) and x["time_of_peak"] == pytest.approx(y["time_of_peak"])
    assert "rms_force" in a.metrics and "rms_force" not in b.metrics
    assert a.estimate is not None and b.estimate is None            # b ran in 5 chunks
    # in memory (no output folder) the measured record is one chunk, and the Estimate is kept
    c = estimate_job(measured)
    np.testing.assert_allclose(c.estimate.forces, a.estimate.forces, rtol=1e-9, atol=1e-9 * np.abs(a.estimate.forces).max())
    assert c.files == {}


def test_the_tidy_rows_of_a_reduced_model_carry_its_static_correction(tmp_path):
    """Written strains are the Estimate's strains (with the static correction of a reduced filter
    model), for a simulated job and for a measured record in chunks alike."""
    simulated, measured = _simulated_and_measured(tmp_path, 0.2)
    for job in (simulated, measured):
        reduced = Job.from_dict(job.to_dict(), "estimate", overrides={"filter.n_modes": 6})
        whole = estimate_job(reduced).estimate
        out = str(tmp_path / f"r{id(job)}")
        estimate_job(reduced, out, plot=False)
        ts = pd.read_csv(os.path.join(out, "timeseries.csv"))
        written = ts[ts.channel == "strain:13"]["estimated"].to_numpy()
        k = whole.structure.strain_labels.index("strain:13")
        np.testing.assert_allclose(written, whole.strains[:, k], rtol=1e-9, atol=1e-9 * np.abs(whole.strains[:, k]).max())
        assert whole.structure.static is not None


def test_runners_take_a_job_not_a_dict():
    with pytest.raises(TypeError, match="takes an akf.job.Job"):
        estimate_job(example_job("s17-case4"))
    with pytest.raises(ValueError, match="read for akf place, not for akf estimate"):
        estimate_job(example("th-case5"))


def test_defaults_are_applied_once_per_command():
    """The stiffness factor: 1.0 for estimate and 1.05 for place unless the job sets it; n_modes:
    "auto" for place and locate unless set, "full" is the full model (None)."""
    est = example_job("s17-case4")
    del est["filter"]["stiffness_factor"]
    assert Job.from_dict(est, "estimate").stiffness_factor == 1.0
    place = example("th-case5").to_dict()
    place["filter"].pop("stiffness_factor", None)
    place.setdefault("place", {}).pop("n_modes", None)
    job = Job.from_dict(place, "place")
    assert job.stiffness_factor == 1.05 and job.n_modes == "auto"
    job = Job.from_dict(place, "place", overrides={"place.n_modes": "full"})
    assert job.n_modes is None
    assert example("imp-truss-case1").n_modes in ("auto", None) or isinstance(example("imp-truss-case1").n_modes, int)


def test_paths_are_taken_from_the_job_files_folder(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "job.toml").write_text('dt = 0.001\nsensors = ["strain:13"]\nforces = ["8:y"]\n'
                                               '[structure]\nmodel = "s17_truss"\n[filter]\nnoise_cov = 1e-14\n'
                                               '[measurements]\nfile = "data/rec.csv"\n')
    job = load_job(tmp_path / "sub" / "job.toml", "estimate")
    assert job.spec.measurements.file == str(tmp_path / "sub" / "data" / "rec.csv")
    assert job.name == "job" and job.source == str(tmp_path / "sub" / "job.toml")
