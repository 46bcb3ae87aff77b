"""``akf oma``: the identified modes of a job's accelerometers, paired with the filter's model."""
import json

import numpy as np
import pytest

from akf.cli import main


def test_oma_of_the_flagship_example_sees_the_filters_model_error(tmp_path, capsys):
    """S17 case 4 simulates the truth and filters with a model 5 % stiffer: every paired mode of
    the record sits at 1/sqrt(1.05) of the filter model's frequency."""
    assert main(["oma", "--example", "s17-case4", "--out", str(tmp_path / "o"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    paired = [m for m in out["modes"] if m["model_mode"] is not None]
    assert len(paired) >= 2 and all(m["mac"] > 0.95 for m in paired)
    # 2 s of record: the identified frequencies are within 1 % (mode 2: +0.7 %, mode 3: -0.02 %)
    assert np.allclose([m["frequency_ratio"] for m in paired], 1 / np.sqrt(1.05), rtol=0.01)
    assert (tmp_path / "o" / "oma_modes.csv").exists() and (tmp_path / "o" / "stabilisation.png").exists()
    assert out["channels"] == ["acc:4:y", "acc:6:y", "acc:8:y", "acc:12:y", "acc:6:x"]


def test_oma_needs_two_accelerometers(tmp_path, capsys):
    job = tmp_path / "job.toml"
    job.write_text('dt = 0.001\nsensors = ["strain:5", "acc:8:y"]\nforces = ["8:y"]\n[structure]\nmodel = "s17_truss"\n'
                   '[simulation]\nduration = 2.0\n[[simulation.loads]]\ncomponents = [{type = "band_noise", '
                   'rms = 100.0, f_high = 200.0, seed = 1}]\n')
    assert main(["oma", str(job), "--out", str(tmp_path / "o")]) == 2
    assert "at least 2 accelerometers" in capsys.readouterr().err


@pytest.mark.parametrize("flag", ["--list-examples", "--print-job"])
def test_oma_lists_and_prints_estimate_examples(flag, capsys):
    args = ["oma", flag] + (["--example", "s17-case4"] if flag == "--print-job" else [])
    assert main(args) == 0
    assert "s17-case4" in capsys.readouterr().out


def test_oma_refuses_a_record_shorter_than_twenty_periods_of_the_models_first_mode(tmp_path, capsys):
    job = tmp_path / "job.toml"
    job.write_text('dt = 0.001\nsensors = ["acc:4:y", "acc:8:y"]\nforces = ["8:y"]\n[structure]\nmodel = "s17_truss"\n'
                   '[simulation]\nduration = 0.5\n[[simulation.loads]]\ncomponents = [{type = "band_noise", '
                   'rms = 100.0, f_high = 200.0, seed = 1}]\n')
    assert main(["oma", str(job), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "periods of the model's first mode" in err and "at least 20" in err


def test_oma_of_a_record_with_no_step_where_every_accelerometer_is_seen_is_named(tmp_path, capsys):
    """Two accelerometers missing on alternate steps (or a record of infinite values) ended in
    "internal error: attempt to get argmax of an empty sequence"."""
    n, dt = 4096, 0.001
    t = np.arange(n) * dt
    a, b = np.sin(40 * t), np.cos(55 * t)
    a[::2], b[1::2] = np.nan, np.nan
    cell = lambda v: "" if np.isnan(v) else f"{v:.9g}"  # noqa: E731
    rows = "".join(f"{ti:.6f},{cell(x)},{cell(y)}\n" for ti, x, y in zip(t, a, b))
    (tmp_path / "r.csv").write_text("time,acc:4:y,acc:8:y\n" + rows)
    job = tmp_path / "job.toml"
    job.write_text(f'dt = {dt}\nsensors = ["acc:4:y", "acc:8:y"]\nforces = ["8:y"]\n[structure]\nmodel = "s17_truss"\n'
                   '[measurements]\nfile = "r.csv"\n')
    assert main(["oma", str(job), "--out", str(tmp_path / "o")]) == 2
    assert "no step where all of acc:4:y, acc:8:y are observed" in capsys.readouterr().err
