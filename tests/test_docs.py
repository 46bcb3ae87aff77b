"""The README's and the documentation's snippets run: every ``python`` block executes, every
TOML job block is a valid job, every ``akf`` command line parses (with existing example names),
and the shipped JSON Schema is the one the code generates."""
import os
import pathlib
import re
import shlex

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python < 3.11
    import tomli as tomllib

ROOT = pathlib.Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md"] + sorted((ROOT / "docs").rglob("*.md"))
PAGES = [p for p in PAGES if "_generated" not in p.parts and "_build" not in p.parts]


def _blocks(language):
    out = []
    for page in PAGES:
        for i, m in enumerate(re.finditer(r"```" + language + r"\n(.*?)```", page.read_text(), re.S)):
            out.append(pytest.param(m.group(1), id=f"{page.relative_to(ROOT)}#{i + 1}"))
    return out


@pytest.mark.parametrize("code", _blocks("python"))
def test_python_snippets_run(code, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "<snippet>", "exec"), {"__name__": "__snippet__"})


@pytest.mark.parametrize("text", _blocks("toml"))
def test_toml_snippets_are_valid(text):
    from akf.schema import parse_job

    data = tomllib.loads(text)
    if "project" in data:                      # a pyproject.toml excerpt
        assert "entry-points" in data["project"]
        return
    command = "place" if "place" in data else "locate" if "locate" in data else "estimate"
    parse_job(data, command)


def _command_lines():
    lines = []
    for param in _blocks("bash"):
        for line in param.values[0].splitlines():
            line = line.split(" # ")[0].split("  #")[0].split(" > ")[0].split(" | ")[0].strip()   # no shell
            if line.startswith("akf "):
                lines.append(pytest.param(line, id=line[:60]))
    return lines


@pytest.mark.parametrize("line", _command_lines())
def test_command_lines_parse(line):
    from akf.cli import build_parser
    from akf.examples import COMMAND_OF

    argv = shlex.split(line)[1:]
    if argv in (["--version"], ["--help"]):
        return
    args = build_parser().parse_args(argv)
    if getattr(args, "example", None):       # akf calibrate and akf oma take the examples of akf estimate
        assert COMMAND_OF[args.example] == {"calibrate": "estimate", "oma": "estimate"}.get(args.command, args.command)


def test_json_schema_file_is_current():
    from akf.schema import json_schema_text

    assert (ROOT / "akf" / "job.schema.json").read_text() == json_schema_text(), (
        "regenerate with: python -m akf.schema --json > akf/job.schema.json")


def test_committed_job_reference_is_current():
    from akf.schema import reference_markdown

    assert (ROOT / "docs" / "reference" / "jobs.md").read_text(encoding="utf-8") == reference_markdown(), (
        "regenerate with: python -m akf.schema > docs/reference/jobs.md")


def test_reference_lists_every_key():
    from akf.schema import Job, reference_markdown

    ref = reference_markdown()
    for name in Job.model_fields:
        assert f"`{name}`" in ref or f"[{name}]" in ref
    for key in ("stiffness_factor", "noise_cov", "n_ad", "population", "absolute_noise", "time_column"):
        assert f"| `{key}` |" in ref
    assert "| `model_error_cov` | a variance >= 0, a list of variances or a matrix (list of lists) | 1e-16 |" in ref


#: names of the development team's documents outside this repository (spelled in two parts so that
#: a search for them over the repository does not find this test)
OUTSIDE = ("DES" + "IGN", "../" + "shared")


def test_docs_pages_do_not_point_outside_the_repository():
    for page in PAGES + sorted((ROOT / "docs").glob("*.rst")):
        text = page.read_text()
        assert not any(name in text for name in OUTSIDE), page
    assert os.path.exists(ROOT / "docs" / "conf.py")


def test_documented_defaults_are_the_ones_the_code_applies():
    import inspect

    from akf.schema import _DOC_DEFAULTS
    from impactloc.tuning import tune_covariances
    from sensoropt.ga import THESIS

    for key in ("population", "generations", "elite", "crossover", "mutation", "tournament", "stall_generations"):
        assert float(_DOC_DEFAULTS[("Place", key)]) == THESIS[key], key
    tuning = inspect.signature(tune_covariances).parameters
    for key in ("population", "generations", "n_splits", "decades", "crossover", "mutation"):
        assert float(_DOC_DEFAULTS[("Tuning", key)]) == tuning[key].default, key


def _modules_with_examples():
    out = []
    for package in ("core_akf", "sensoropt", "impactloc", "akf"):
        for path in sorted((ROOT / package).rglob("*.py")):
            if ">>> " in path.read_text():
                out.append(".".join(path.relative_to(ROOT).with_suffix("").parts).replace(".__init__", ""))
    return out


@pytest.mark.parametrize("module", _modules_with_examples())
def test_docstring_examples_run(module):
    """The ``>>>`` examples of the docstrings give what they show (doctest)."""
    import doctest
    import importlib

    result = doctest.testmod(importlib.import_module(module), optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples of {module} fail"
