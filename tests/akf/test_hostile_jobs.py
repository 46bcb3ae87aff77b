"""Hostile or mistyped job files: bounded before they are parsed or built from, refused by name,
with short messages."""
import re

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
    err = capsys.readouterr().err
    assert len(err) < 600, err[:300]
    assert re.search(message, err), err


def test_brackets_in_strings_and_comments_are_not_nesting(tmp_path, capsys):
    from akf.job import load_job_file, nesting_depth

    text = CASE4.replace('name = "s17-case4"', 'name = "s17-case4"  # [[[[[[[[[[[[\n'
                         'text = "[[[[[[[[[[ \\" {{{{{{{{{{"\nnote = \'\'\'[[[[[[[[[[\n]]]]\'\'\'')
    job = tmp_path / "job.toml"
    job.write_text(text)
    assert nesting_depth(text) == 2 and load_job_file(job)["text"].startswith("[[[[")
