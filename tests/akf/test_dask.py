"""The same jobs on a dask cluster: a 2-worker LocalCluster gives bit-identical results to the
default (in-process / loky) backend for one seed -- the placement logbook, the location ranking
and the tuned covariances -- because the GA engine draws from its own seeded streams and evaluates
fixed-size batches, and the scan has no randomness."""
import json

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from akf.cli import main  # noqa: E402
from akf.examples.impact import example_scenario  # noqa: E402
from akf.parallel import scheduler  # noqa: E402
from akf.placement import example_problem  # noqa: E402
from impactloc import locate  # noqa: E402
from sensoropt import place  # noqa: E402


@pytest.fixture(scope="module")
def client():
    with (distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster,
          distributed.Client(cluster) as c):
        yield c


@pytest.fixture(scope="module")
def placement_problem():
    p = example_problem("th-case5")
    enc = p.encoding()
    return enc, p.objective(enc)


def _placement(enc, obj, n_jobs):
    return place(obj, enc, population=8, generations=3, seed=5, n_jobs=n_jobs)


def test_placement_is_bit_identical_on_a_cluster(client, placement_problem):
    enc, obj = placement_problem
    here = _placement(enc, obj, n_jobs=1)
    with scheduler(client):
        there = _placement(enc, obj, n_jobs=-1)
    assert there.sensors == here.sensors and there.best_error == here.best_error
    assert there.logbook.drop(columns="seconds").equals(here.logbook.drop(columns="seconds"))
    assert there.hall_of_fame == here.hall_of_fame


def test_location_ranking_and_tuning_are_bit_identical_on_a_cluster(client):
    sc = example_scenario("imp-truss-case1")
    kw = dict(n_ad=sc.n_ad, ad_kinds=sc.ad_kinds, direction=sc.direction, max_splits=6, seed=2,
              tuning={"population": 6, "generations": 2, "n_splits": 3})
    here = locate(sc.structure, sc.sensors, sc.measurements, sc.dt, n_jobs=1, **kw)
    with scheduler(client):
        there = locate(sc.structure, sc.sensors, sc.measurements, sc.dt, n_jobs=-1, **kw)
    assert there.scan.summary.equals(here.scan.summary)
    assert np.array_equal(there.scan.errors, here.scan.errors, equal_nan=True)
    assert there.tuning.covariances == here.tuning.covariances
    assert there.tuning.logbook.drop(columns="seconds").equals(here.tuning.logbook.drop(columns="seconds"))
    assert np.array_equal(there.reconstruction.force, here.reconstruction.force)


def test_cli_scheduler_local_cluster(tmp_path, capsys):
    args = ["place", "--example", "th-case5", "--generations", "1", "--population", "4", "--json", "--no-plot"]
    assert main(args + ["--out", str(tmp_path / "here")]) == 0
    here = json.loads(capsys.readouterr().out)
    assert main(args + ["--scheduler", "local:2", "--out", str(tmp_path / "there")]) == 0
    there = json.loads(capsys.readouterr().out)
    assert (there["sensors"], there["error"], there["evaluations"]) == (here["sensors"], here["error"], here["evaluations"])
    assert main(args + ["--scheduler", "local:0", "--out", str(tmp_path / "bad")]) == 2
    assert "local:N needs a number of workers N >= 1" in capsys.readouterr().err


def _distance_to_node_121(sensors):
    """A cheap placement objective (distance of the sensors' nodes from node 121)."""
    return float(sum(abs(int(s.split(":")[1]) - 121) for s in sensors))


class _EndsItsWorker:
    """Objective whose first evaluation on a cluster worker ends that worker's process, as an
    out-of-memory kill would (``times`` evaluations in all, counted in files under ``folder``)."""

    n_objectives = 1

    def __init__(self, folder, times=1):
        self.folder, self.times = str(folder), times

    def evaluate(self, layouts):
        import os

        try:
            distributed.get_worker()
        except ValueError:          # in this process: never
            return [_distance_to_node_121(s) for s in layouts]
        done = len(os.listdir(self.folder))
        if done < self.times:
            open(os.path.join(self.folder, f"killed-{done}"), "w").close()
            os._exit(1)
        return [_distance_to_node_121(s) for s in layouts]


def _toy_placement(objective, n_jobs):
    from core_akf.models import th_plate
    from sensoropt import PlateGrid

    enc = PlateGrid(th_plate(), kinds=("ex",), n_sensors=2)
    return place(objective, enc, population=12, generations=4, seed=1, n_jobs=n_jobs)


def test_a_worker_that_dies_mid_run_changes_nothing(tmp_path):
    """One worker process ends in the middle of the GA: the cluster restarts it, its task runs
    again, and the placement is the one of a run without the loss."""
    from sensoropt import FunctionObjective

    here = _toy_placement(FunctionObjective(_distance_to_node_121), n_jobs=1)
    with scheduler("local:2"):
        there = _toy_placement(_EndsItsWorker(tmp_path), n_jobs=-1)
    assert len(list(tmp_path.iterdir())) == 1               # a worker did die
    assert there.sensors == here.sensors and there.best_error == here.best_error
    assert there.logbook.drop(columns="seconds").equals(here.logbook.drop(columns="seconds"))


def test_a_task_that_keeps_killing_workers_stops_with_a_clear_message(tmp_path):
    import dask

    from akf.parallel import ClusterError

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        with pytest.raises(ClusterError, match="ended its worker process again and again.*--resume"):
            with scheduler("local:2", resume="run again with --resume"):
                _toy_placement(_EndsItsWorker(tmp_path, times=100), n_jobs=-1)
