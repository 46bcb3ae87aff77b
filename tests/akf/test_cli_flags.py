"""Command-line flags a user mistypes or overdoes: named as flags, capped at what can be used."""
import argparse
import json

import pytest
import tomlkit
from helpers import measured_s17_files

from akf.cli import main
from akf.parallel import at_most, usable_cores, workers
from core_akf.checks import AKFInputError


def test_a_typo_in_parameters_is_named_as_the_flag_with_the_closest_names(capsys):
    assert main(["calibrate", "--example", "s17-case4", "--parameters", "stifness_factor"]) == 2
    err = capsys.readouterr().err
    assert "--parameters stifness_factor: not a parameter akf calibrate learns; did you mean stiffness_factor?" in err
    assert "[filter]" not in err


def test_print_job_of_another_commands_example_is_refused(capsys):
    assert main(["estimate", "--example", "th-case5", "--print-job"]) == 2
    assert "'th-case5' is an example of akf place, not of akf estimate" in capsys.readouterr().err
    assert main(["place", "--example", "th-case5", "--print-job"]) == 0
    assert 'name = "th-case5"' in capsys.readouterr().out


def test_n_jobs_is_capped_at_the_cores_and_the_work():
    cores = usable_cores()
    on = lambda n, scheduler=None: workers(argparse.Namespace(n_jobs=n, scheduler=scheduler))  # noqa: E731
    assert on(1000) == cores and on(-1) == cores and on(1) == 1 and on(None) == 1
    assert on(-2) == max(1, cores - 1)
    assert on(1000, "tcp://host:8786") == 1000 and on(None, "local:2") == -1      # the cluster decides
    with pytest.raises(AKFInputError, match="--n-jobs 0 runs nothing"):
        on(0)
    assert at_most(1000, 4) == 4 and at_most(-1, 4) == 4 and at_most(2, 4) == 2


def test_a_time_parallel_run_starts_no_more_processes_than_files(tmp_path, capsys, monkeypatch):
    import joblib

    started = []
    real = joblib.Parallel

    class Counting(real):
        def __init__(self, n_jobs=None, **kw):
            started.append(n_jobs)
            super().__init__(n_jobs=1, **kw)

    monkeypatch.setattr(joblib, "Parallel", Counting)
    job = tmp_path / "job.toml"
    job.write_text(tomlkit.dumps(measured_s17_files(tmp_path, 4, {"strains": ["strain:13"]})))
    assert main(["estimate", str(job), "--no-plot", "--json", "--n-jobs", "1000", "--out", str(tmp_path / "o")]) == 0
    assert json.loads(capsys.readouterr().out)["complete"]
    assert started and max(started) <= min(4, usable_cores())
