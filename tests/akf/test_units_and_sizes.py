"""Units and sizes a user sees before trusting a result: a large time series announced before the
run with a size that holds, fatigue.csv headers with their units, the yearly damage's caveat."""
import json
import os
import re

import pandas as pd
import pytest

import akf.estimate.files as files
from akf.cli import main
from akf.examples import example_path


def _case4(tmp_path, output, duration=2.0):
    """The s17-case4 job file with its [output] table replaced by ``output`` and the record ``duration`` s long."""
    text = open(example_path("s17-case4")).read().split("[output]")[0].replace("duration = 2.0", f"duration = {duration}")
    job = tmp_path / "job.toml"
    job.write_text(text + "[output]\n" + output)
    return str(job)


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_a_large_time_series_is_announced_with_a_size_that_holds(tmp_path, capsys, monkeypatch, fmt):
    monkeypatch.setattr(files, "LARGE_OUTPUT_BYTES", 1e5)
    out = tmp_path / "o"
    job = _case4(tmp_path, f'strains = ["strain:13", "strain:20"]\nformat = "{fmt}"\n')
    assert main(["estimate", job, "--no-plot", "--json", "--out", str(out)]) == 0
    err = capsys.readouterr()
    said = re.search(r"timeseries\.\w+ will hold about (\d+) MB \((\d+) strain outputs and 4 forces x (\d+) steps\)",
                     err.err)
    assert said, err.err
    assert said.group(2) == "2" and said.group(3) == "8192"
    path = out / f"timeseries.{fmt}"
    size = (sum(f.stat().st_size for f in path.iterdir()) if path.is_dir() else path.stat().st_size) / 1e6
    assert 0.5 < int(said.group(1)) / size < 2.0
    assert any("will hold about" in w for w in json.loads(err.out)["warnings"])


def test_fatigue_csv_headers_carry_units_and_the_yearly_damage_its_caveat(tmp_path, capsys):
    out = tmp_path / "o"
    job = _case4(tmp_path, "[output.fatigue]\ndetail_category = 36\n", duration=0.5)
    assert main(["estimate", job, "--no-plot", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    table = pd.read_csv(out / "fatigue.csv")
    assert {"max_range_MPa", "del_MPa", "del_reference_MPa"} <= set(table.columns)
    lines = printed.splitlines()
    first = lines[next(i for i, line in enumerate(lines) if "max range (MPa)" in line) + 1].split()
    row = table.set_index("channel").loc[first[0]]
    assert float(first[2]) == pytest.approx(row["max_range_MPa"], rel=1e-3)      # the console's MPa are the CSV's
    assert float(first[3]) == pytest.approx(row["del_MPa"], rel=1e-3)
    assert "damage of 0.5 s of record times 6.31e+07" in printed and "shorter than a day" in printed
    assert os.path.exists(out / "summary.csv")


def test_n_jobs_on_a_job_it_cannot_split_says_so(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("akf.parallel.usable_cores", lambda: 4)      # --n-jobs 2 is not capped to 1 on one core
    assert main(["estimate", "--example", "s17-case4", "--no-plot", "--json", "--n-jobs", "2", "--duration", "0.2",
                 "--out", str(tmp_path / "o")]) == 0
    notes = json.loads(capsys.readouterr().out)["notes"]
    assert any(n.startswith("--n-jobs 2 not used: a simulated record is filtered sequentially") for n in notes)

