"""A lost joblib worker: the map runs once more, a second loss is a named error (exit 4)."""
import joblib
import pytest
from joblib.externals.loky.process_executor import TerminatedWorkerError

from core_akf.tasks import WorkerLostError, run_tasks


def _square(x):
    return x * x


def _dying(losses, monkeypatch):
    """joblib.Parallel that loses a worker ``losses`` times, then runs."""
    real, calls = joblib.Parallel, []

    class Dying(real):
        def __call__(self, iterable):
            calls.append(1)
            if len(calls) <= losses:
                raise TerminatedWorkerError("A worker process managed by the executor was unexpectedly terminated. "
                                            "This could be caused by a segmentation fault ... (SIGKILL)")
            return super().__call__(iterable)

    monkeypatch.setattr(joblib, "Parallel", Dying)
    return calls


def test_one_lost_worker_is_retried(monkeypatch):
    calls = _dying(1, monkeypatch)
    assert run_tasks(_square, range(6), 2) == [0, 1, 4, 9, 16, 25] and len(calls) == 2


def test_a_second_loss_is_named(monkeypatch):
    _dying(2, monkeypatch)
    with pytest.raises(WorkerLostError, match="a worker process died twice while running 6 tasks on 2 workers"):
        run_tasks(_square, range(6), 2)


def test_a_place_run_whose_workers_die_exits_4_with_the_advice(monkeypatch, capsys, tmp_path):
    from akf.cli import main

    _dying(10, monkeypatch)
    assert main(["place", "--example", "th-case5", "--generations", "1", "--population", "20", "--n-jobs", "2",
                 "--no-plot", "--out", str(tmp_path)]) == 4
    err = capsys.readouterr().err
    assert "a worker process died twice" in err and "with a smaller --n-jobs, or without it" in err
