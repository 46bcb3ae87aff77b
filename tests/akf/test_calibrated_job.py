"""``calibrated.toml`` round trips: the job akf calibrate writes runs as it is, from wherever it
was written -- its data paths rewritten, its comments (units) kept, whatever TOML layout the
user's ``[filter]`` had."""
import json
import sys

import pytest
from helpers import DAQ

from akf.cli import main

tomllib = pytest.importorskip("tomllib" if sys.version_info >= (3, 11) else "tomli")

#: the S17 case-4 job on the SI sample record, up to its [measurements]
HEAD = (DAQ / "s17-tdms.toml").read_text().split("[measurements]")[0]


def _job(folder, text, record="../data/rec.csv"):
    """A job file ``folder/jobs/job.toml`` of ``text`` whose record is ``record`` (relative to it)."""
    (folder / "jobs").mkdir(parents=True, exist_ok=True)
    (folder / "data").mkdir(exist_ok=True)
    (folder / "data" / "rec.csv").write_bytes((DAQ / "record-si.csv").read_bytes())
    path = folder / "jobs" / "job.toml"
    path.write_text(text + f'\n[measurements]\nfile = "{record}"   # the record\n')
    return path


def _calibrate(capsys, *args):
    assert main(["calibrate", *args, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_the_default_out_folder_job_runs_as_written(tmp_path, capsys, monkeypatch):
    """The issue's case: a job in jobs/ whose record is ../data/rec.csv, calibrated with the
    default --out from another folder; the written job estimates with the calibrated numbers."""
    job = _job(tmp_path, HEAD.replace("force_increment_cov = 1e5", 'force_increment_cov = 1e5\ncalibrate = '
                                      '["stiffness_factor"]   # learn it'))
    monkeypatch.chdir(tmp_path)
    out = _calibrate(capsys, "jobs/job.toml")
    written = tmp_path / out["files"]["calibrated_job"]
    assert written.parent == tmp_path / "akf-out" / "s17-tdms"
    data = tomllib.loads(written.read_text())
    assert data["measurements"]["file"] == "../../data/rec.csv"
    assert "calibrate" not in data["filter"]
    assert data["filter"]["stiffness_factor"] == pytest.approx(out["calibration"]["stiffness_factor"])
    assert main(["estimate", str(written), "--json", "--no-plot", "--out", "e"]) == 0
    est = json.loads(capsys.readouterr().out)
    assert est["calibration"] is None
    assert est["loglik"] == pytest.approx(out["calibration"]["loglik_after"], rel=1e-6)
    assert job.read_text().count("calibrate") == 1         # the user's job is untouched


def test_an_absolute_record_path_stays_absolute(tmp_path, capsys):
    record = tmp_path / "data" / "rec.csv"
    job = _job(tmp_path, HEAD + 'calibrate = ["stiffness_factor"]\n', record=str(record))
    out = _calibrate(capsys, str(job), "--out", str(tmp_path / "o"))
    assert tomllib.loads(open(out["files"]["calibrated_job"]).read())["measurements"]["file"] == str(record)


def test_a_replaced_value_keeps_its_unit_comment(tmp_path, capsys):
    job = _job(tmp_path, HEAD + 'calibrate = ["noise_cov"]\n')
    out = _calibrate(capsys, str(job), "--out", str(tmp_path / "o"))
    lines = open(out["files"]["calibrated_job"]).read().splitlines()
    line = next(line for line in lines if line.startswith("noise_cov ="))
    assert line.endswith("# SI units squared")
    assert "0.2," not in line                                # the fitted values, not the old ones
    assert tomllib.loads("\n".join(lines))["filter"]["noise_cov"] == pytest.approx(out["calibration"]["noise_cov"])


def _filter_as(layout):
    """HEAD with its [filter] written as an inline table or as dotted keys."""
    head, rest = HEAD.split("[filter]\n")
    keys = {"stiffness_factor": "1.05", "model_error_cov": "1e-16", "force_increment_cov": "1e5",
            "noise_cov": "{acc = 0.2, strain = 4e-14}", "calibrate": '["stiffness_factor"]'}
    tail = rest.split("\n\n", 1)[1] if "\n\n" in rest else ""
    top = head.split("[structure]")[0]
    structure = "[structure]" + head.split("[structure]")[1]
    if layout == "inline":
        return top + "filter = {" + ", ".join(f"{k} = {v}" for k, v in keys.items()) + "}\n" + structure + tail
    return top + "".join(f"filter.{k} = {v}\n" for k, v in keys.items()) + structure + tail


@pytest.mark.parametrize("layout", ["inline", "dotted"])
def test_a_filter_of_any_toml_layout_is_written_as_valid_toml(tmp_path, capsys, layout):
    text = _filter_as(layout)
    assert tomllib.loads(text)["filter"]["calibrate"] == ["stiffness_factor"]     # the layout is what it says
    job = _job(tmp_path, text)
    out = _calibrate(capsys, str(job), "--out", str(tmp_path / "o"))
    data = tomllib.loads(open(out["files"]["calibrated_job"]).read())
    assert "calibrate" not in data["filter"]
    assert data["filter"]["stiffness_factor"] == pytest.approx(out["calibration"]["stiffness_factor"])
    assert data["filter"]["noise_cov"] == {"acc": 0.2, "strain": 4e-14}
    assert data["measurements"]["file"] == "../data/rec.csv"
    assert main(["estimate", out["files"]["calibrated_job"], "--json", "--no-plot", "--out", str(tmp_path / "e")]) == 0
    assert json.loads(capsys.readouterr().out)["loglik"] == pytest.approx(out["calibration"]["loglik_after"], rel=1e-6)


def test_an_output_label_estimate_would_refuse_is_named_before_the_fit(tmp_path, capsys):
    """calibrate ignored ``[output] strains`` and wrote a calibrated.toml that estimate then refused."""
    job = _job(tmp_path, HEAD + 'calibrate = ["stiffness_factor"]\n')
    job.write_text(job.read_text() + '\n[output]\nstrains = ["strain:13", "strain:99"]\n')
    assert main(["calibrate", str(job), "--out", str(tmp_path / "o")]) == 2
    assert "unknown strain output 'strain:99'" in capsys.readouterr().err
    assert not (tmp_path / "o" / "calibrated.toml").exists()
