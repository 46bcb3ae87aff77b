"""Hostile or mistyped job files: bounded before they are parsed or built from, refused by name,
with short messages."""
import re

import numpy as np
import pytest
from helpers import ROOT

from akf.cli import main

CASE4 = (ROOT / "akf" / "examples" / "jobs" / "s17-case4.toml").read_text()

HOSTILE = {
    "nested arrays": (CASE4.replace('strains = "all"', "strains = " + "[" * 5000 + "]" * 5000),
                      "arrays or inline tables nested 5000 deep; a job nests at most 8"),
    "nested inline tables": (CASE4.replace('strains = "all"', 'strains = "all"\nx = ' + "{a = " * 3000 + "1" + "}" * 3000),
                             "arrays or inline tables nested 3000 deep"),
    "dotted keys": ("a" + ".a" * 3000 + " = 1\n" + CASE4, "tables or dotted keys nested deeper than 8"),
    "a label twice": (CASE4.replace('strains = "all"', 'strains = ["strain:13", "strain:5", "strain:13"]'),
                      r"\[output\] strains lists 'strain:13' twice \(entries 1 and 3\)"),
    "more labels than outputs": (CASE4.replace('strains = "all"', "strains = [" + ", ".join(
        f'"strain:{i}"' for i in range(1, 40)) + "]"), "lists 39 labels; the model has 34 strain outputs"),
    "a label a million times": (CASE4.replace('strains = "all"', "strains = [" + ", ".join(['"strain:13"'] * 10**5) + "]"),
                                "the job file is 1.3 MB; a job file is a few kB"),
    "a huge list echoed": (CASE4.replace("[simulation]", "calibrate = [\"frequencies\"]\ncalibrate_modes = ["
                                         + ", ".join(["1"] * 50000) + "]\n[simulation]"),
                           r"got \[1, 1, .* \.\.\. \(150,000 characters\)\]"),
}


@pytest.mark.parametrize("case", list(HOSTILE))
def test_a_hostile_job_file_is_refused_by_name_with_a_short_message(tmp_path, capsys, case):
    text, message = HOSTILE[case]
    job = tmp_path / "job.toml"
    job.write_text(text)
    assert main(["estimate", str(job), "--no-plot", "--duration", "0.05", "--out", str(tmp_path / "o")]) == 2
    err = "".join(line for line in capsys.readouterr().err.splitlines(True) if line.startswith("akf: error"))
    assert len(err) < 600, err[:300]
    assert re.search(message, err), err


def test_brackets_in_strings_and_comments_are_not_nesting(tmp_path, capsys):
    from akf.job import load_job_file, nesting_depth

    text = CASE4.replace('name = "s17-case4"', 'name = "s17-case4"  # [[[[[[[[[[[[\n'
                         'text = "[[[[[[[[[[ \\" {{{{{{{{{{"\nnote = \'\'\'[[[[[[[[[[\n]]]]\'\'\'')
    job = tmp_path / "job.toml"
    job.write_text(text)
    assert nesting_depth(text) == 2 and load_job_file(job)["text"].startswith("[[[[")


MISTYPED = {
    "force_std 1e300": ({"filter.force_model": "matern32", "filter.force_std": 1e300, "filter.force_timescale": 0.005,
                         "filter.force_increment_cov": None}, r"force_std = 1e\+300 N is beyond any load"),
    "force_timescale 1e-12": ({"filter.force_model": "matern32", "filter.force_std": 500.0,
                               "filter.force_timescale": 1e-12, "filter.force_increment_cov": None},
                              r"force_timescale = 1e-12 s is far below the time step"),
    "force_timescale 1e300": ({"filter.force_model": "matern32", "filter.force_std": 500.0,
                               "filter.force_timescale": 1e300, "filter.force_increment_cov": None},
                              r"force_timescale = 1e\+300 s is beyond any record"),
    "smooth_lag 1e300": ({"filter.smooth": True, "filter.smooth_lag": 1e300},
                         r"smooth_lag = 1e\+300 s is longer than the record \(0.100\d* s\)"),
    # both ended in a failed steady-state gain (the plate: 30 s of Riccati solvers first)
    "model_error_cov 1e6 (1e-6 meant)": ({"filter.model_error_cov": 1e6},
                                         r"\[filter\] model_error_cov = 1e\+06 m\^2 per step .* beyond what a "
                                         r"structure takes \(at most 0.001\)"),
    "model_error_cov 1e-2": ({"filter.model_error_cov": 1e-2}, r"model_error_cov = 0.01 m\^2 per step"),
    "force_increment_cov 1e24": ({"filter.force_increment_cov": 1e24},
                                 r"force_increment_cov = 1e\+24 N\^2 per step .* \(at most 1e\+18\)"),
}


@pytest.mark.parametrize("case", list(MISTYPED))
def test_a_mistyped_value_is_named_by_its_key(case):
    from akf.estimate import estimate_job
    from akf.examples import example_job
    from akf.job import Job
    from core_akf.checks import AKFInputError

    overrides, message = MISTYPED[case]
    data = example_job("s17-case4")
    data["simulation"]["duration"] = 0.1
    for dotted, value in overrides.items():
        table, key = dotted.split(".")
        if value is None:
            data[table].pop(key, None)
        else:
            data[table][key] = value
    with pytest.raises(AKFInputError, match=message):
        estimate_job(Job.from_dict(data, "estimate"), None)


def test_a_mode_above_nyquist_is_not_calibrated():
    from core_akf.calibration import calibrate
    from core_akf.checks import AKFInputError
    from core_akf.models import s17_truss

    s = s17_truss()
    dt = 1 / 512                                    # Nyquist 256 Hz
    above = [int(k) + 1 for k in range(s.n) if s.frequencies()[k] >= 256][:1]
    Y = np.zeros((256, 2))
    with pytest.raises(AKFInputError, match=rf"modes \[{above[0]}\] lie at or above the record's Nyquist frequency"):
        calibrate(s, ["strain:13", "acc:8:y"], ["8:y"], Y, dt, parameters=["frequencies"], modes=[1, above[0]],
                  model_error_cov=1e-16, force_increment_cov=1e3, noise_cov={"strain": 1e-14, "acc": 1e-4})


@pytest.mark.parametrize("decades", [400, 1e300, 0])
def test_tuning_decades_out_of_range_is_named_by_its_key_before_the_scan(tmp_path, capsys, decades):
    from akf.examples import example_path

    text = open(example_path("imp-truss-case1")).read().replace("[locate]", f"[locate.tuning]\ndecades = {decades}\n"
                                                                             "[locate]", 1)
    job = tmp_path / "job.toml"
    job.write_text(text)
    assert main(["locate", str(job), "--no-plot", "--json", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert re.search(r"\[locate.tuning\] decades = \S+ is the half-width of the search", err) or \
        "decades in [locate.tuning]" in err, err
    assert not (tmp_path / "o" / "scan.csv").exists()


def test_a_mistyped_locate_covariance_is_named_by_its_key(tmp_path, capsys):
    """[locate.covariances] are checked as [filter]'s are, before the scan."""
    text = (ROOT / "akf" / "examples" / "jobs" / "imp-truss-case1.toml").read_text().replace(
        "[simulation]", "[locate.covariances]\nmodel_error_cov = 1e4\nforce_increment_cov = 1e5\n"
                        "noise_cov = {strain = 1e-12, acc = 1e-4}\n\n[simulation]")
    job = tmp_path / "job.toml"
    job.write_text(text)
    assert main(["locate", str(job), "--no-plot", "--no-tune", "--out", str(tmp_path / "o")]) == 2
    assert "[locate.covariances] model_error_cov = 1e+04 m^2 per step" in capsys.readouterr().err
