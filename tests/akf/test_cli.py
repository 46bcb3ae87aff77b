"""The command line as a user runs it."""
import json
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from akf.cli import main


def test_cli_example_json(tmp_path, capsys):
    rc = main(["estimate", "--example", "s17-case4", "--json", "--out", str(tmp_path), "--duration", "0.5"])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["rms_force"]) == {"4:y", "6:y", "8:y", "12:y"}
    assert all(v > 0 for v in out["rms_force"].values())
    assert 0 < out["avg_strain_error"] < 1e-4
    ts = pd.read_csv(out["files"]["timeseries"])
    assert set(ts["quantity"]) == {"force", "strain"}
    assert ts.query("quantity == 'strain'")["channel"].nunique() == 34
    summary = pd.read_csv(out["files"]["summary"])
    assert len(summary) == 4 + 9 + 34                          # forces, sensors, strain outputs
    assert set(summary["quantity"]) == {"force", "sensor", "strain"}
    assert out["units"]["rms_force"] == "N" and out["units"]["avg_strain_error"] == "m/m"
    assert out["avg_strain_error_microstrain"] == pytest.approx(out["avg_strain_error"] * 1e6)
    assert (tmp_path / "estimate.png").stat().st_size > 10_000


def test_cli_undetectable_exits_with_report(tmp_path, capsys):
    rc = main(["estimate", "--example", "s17-case2", "--out", str(tmp_path), "--duration", "0.2"])
    assert rc == 3
    assert "s = 0" in capsys.readouterr().err


def test_cli_unknown_example(capsys):
    assert main(["estimate", "--example", "nope"]) == 2
    assert "unknown example 'nope'" in capsys.readouterr().err


def test_cli_toml_job_with_measured_csv(tmp_path, capsys):
    """A user's own job: a truss, measured data from a CSV file (here made by the simulator)."""
    from core_akf.models import s17_truss
    from core_akf.simulate import simulate

    sensors = ["strain:13", "strain:21", "acc:8:y"]
    dt = 1 / 1024
    t = np.arange(1024) * dt
    sim = simulate(s17_truss(), sensors, ["8:y"], (1000 * np.sin(2 * np.pi * 4 * t))[:, None], dt,
                   relative_noise=0.01, seed=3)
    df = pd.DataFrame(sim.measurements, columns=sensors)
    df.insert(0, "time", t)
    df.to_csv(tmp_path / "data.csv", index=False)
    job = tmp_path / "job.toml"
    job.write_text(f'''
name = "my-truss"
dt = {dt!r}
sensors = ["strain:13", "strain:21", "acc:8:y"]
forces = ["8:y"]
[structure]
model = "s17_truss"
[filter]
model_error_cov = 1e-16
force_increment_cov = 1e4
noise_cov = {{strain = 1e-16, acc = 1e-4}}
[measurements]
file = "{(tmp_path / 'data.csv').as_posix()}"
[output]
strains = ["strain:13", "strain:1"]
''')
    assert main(["estimate", str(job), "--out", str(tmp_path / "out"), "--json", "--no-plot"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["rms_force"] is None  # no reference for measured data
    ts = pd.read_csv(out["files"]["timeseries"])
    est = ts.query("quantity == 'force'")["estimated"].to_numpy()
    ref = 1000 * np.sin(2 * np.pi * 4 * t)
    assert np.sqrt(np.mean((est[256:] - ref[256:]) ** 2)) < 50
    assert set(ts.query("quantity == 'strain'")["channel"]) == {"strain:13", "strain:1"}


def test_console_script_installed():
    r = subprocess.run([sys.executable, "-m", "akf", "estimate", "--list-examples"],
                       capture_output=True, text=True)
    assert r.returncode == 0 and "s17-case4" in r.stdout


def test_job_typo_is_an_error_not_a_default():
    from helpers import run_estimate

    from akf.examples import example_job
    job = example_job("s17-case4")
    job["filter"]["stifness_factor"] = 1.05
    with pytest.raises(ValueError, match="unknown key 'stifness_factor' in \\[filter\\]; did you mean 'stiffness_factor'"):
        run_estimate(job)
    job = example_job("s17-case4")
    del job["dt"]
    with pytest.raises(ValueError, match="the job has no 'dt'"):
        run_estimate(job)


def test_measurement_path_relative_to_job_file(tmp_path, capsys, monkeypatch):
    """A job file next to its data works from any working directory."""
    sensors = ["strain:13", "strain:21"]
    dt = 1 / 512
    t = np.arange(256) * dt
    df = pd.DataFrame({"time": t, "strain:13": 1e-6 * np.sin(t), "strain:21": 1e-6 * np.cos(t)})
    (tmp_path / "jobdir").mkdir()
    df.to_csv(tmp_path / "jobdir" / "data.csv", index=False)
    (tmp_path / "jobdir" / "job.toml").write_text(f'''
dt = {dt!r}
sensors = {sensors!r}
forces = ["8:y"]
[structure]
model = "s17_truss"
[filter]
force_increment_cov = 1e4
noise_cov = {{strain = 1e-16}}
[measurements]
file = "data.csv"
''')
    monkeypatch.chdir(tmp_path)
    assert main(["estimate", "jobdir/job.toml", "--json", "--no-plot", "--out", "o"]) == 0
    assert json.loads(capsys.readouterr().out)["n_steps"] == 256


def test_job_absolute_noise_units():
    """IMP's absolute noise levels, 1 µε and 1 mg, given in the job's units."""
    from helpers import run_estimate

    from akf.examples import example_job
    job = example_job("s17-case4")
    job["simulation"].pop("relative_noise")
    job["simulation"]["absolute_noise"] = {"microstrain": 1.0, "acc_mg": 1.0}
    job["simulation"]["duration"] = 0.25
    sim = run_estimate(job).simulation
    assert sim.noise_std[:5] == pytest.approx(9.80665e-3)   # five accelerometers
    assert sim.noise_std[5:] == pytest.approx(1e-6)         # four strain gauges
    job["simulation"]["absolute_noise"] = {"micro_strain": 1.0}
    with pytest.raises(ValueError, match="absolute_noise.micro_strain in \\[simulation\\]: input should be 'strain', 'microstrain'"):
        run_estimate(job)


def test_version_and_show(tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0 and capsys.readouterr().out.startswith("akf-toolkit ")
    assert main(["show", "s17_truss", "--json", "--out", str(tmp_path)]) == 0
    d = json.loads(capsys.readouterr().out)
    assert (d["nodes"], d["members"], d["dofs"], d["strain_outputs"]) == (18, 34, 33, 34)
    assert d["first_strain_output"] == "strain:1" and np.all(np.diff(d["frequencies_hz"]) > 0)
    assert os.path.getsize(d["files"]["figure"]) > 10_000
    assert main(["show", "th_plate", "--no-plot"]) == 0
    assert "strain:1:ex ... strain:121:gxy" in capsys.readouterr().out


def test_multimetric_placement_says_to_use_a_longer_window(tmp_path, capsys):
    args = ["place", "--example", "th-multi", "--generations", "0", "--population", "4", "--json", "--no-plot"]
    assert main(args + ["--out", str(tmp_path / "a")]) == 0
    notes = json.loads(capsys.readouterr().out)["notes"]
    assert len(notes) == 1 and "--window 1" in notes[0]
    assert main(args + ["--window", "1", "--out", str(tmp_path / "b")]) == 0
    assert json.loads(capsys.readouterr().out)["notes"] == []


def test_every_study_writes_a_summary(tmp_path, monkeypatch):
    """imp_cases (one setting here) and th_placement write their summary CSV like the others."""
    import pandas as pd

    from akf.studies import imp, run_study, th_placement

    monkeypatch.setattr(imp, "SETTINGS", [("imp-truss-case1", "abs")])
    res = run_study("imp_cases", out=str(tmp_path), quick=True)
    summary = pd.read_csv(res.files["summary"])
    assert list(summary["example"]) == ["imp-truss-case1"] and summary["hits"].iloc[0] == 1
    hits = imp.run_hit_rate(out=str(tmp_path / "hits"), quick=True, examples=["imp-truss-case1"])
    assert len(hits.table) >= 4 and hits.summary["hit_rate"].iloc[0] >= 0.75
    table = pd.DataFrame([
        {"study": "case 5", "label": "seed 0", "n_sensors": 3, "sensors": "a", "full_record_error_ue": 2.0},
        {"study": "case 5", "label": "seed 1", "n_sensors": 3, "sensors": "b", "full_record_error_ue": 1.8},
        {"study": "case 5", "label": "TH case 2 (trial and error)", "n_sensors": 3, "sensors": "c",
         "full_record_error_ue": 3.6},
        {"study": "case 6", "label": "8 gauges", "n_sensors": 8, "sensors": "d", "full_record_error_ue": 1.0}])
    s = th_placement._summary(table, 3.6).set_index("study")
    assert s.loc["case 5", "best_sensors"] == "b" and s.loc["case 5", "gain_over_case2"] == pytest.approx(2.0)
    assert s.loc["case 6", "published_gain_over_case2"] == pytest.approx(0.00666 / 0.00183)
