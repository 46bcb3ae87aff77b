"""Months of data on many cores (issue 23, item 6): the steady-state AKF over a record's pieces
filtered at the same time (zero-state ends, a pass over the boundaries, every piece from its start
state) equals the sequential stream, also on a 2-worker dask cluster, and the pieces' rainflow
counts merge into the one-piece counts exactly."""
import numpy as np
import pytest
from helpers import measured_s17_files

from akf.examples import example
from core_akf.checks import AKFInputError
from core_akf.fatigue import FatigueAccumulator, SNCurve, rainflow, stress_operator
from core_akf.filter import Estimator, TimeParallel, estimate_in_parallel, zero_state_end


@pytest.fixture(scope="module")
def record():
    job = example("s17-case4", overrides={"filter.stiffness_factor": 1.0, "simulation.duration": 2.0})
    sim = job.simulate()
    kw = dict(model_error_cov=job.model_error_cov, force_increment_cov=job.force_increment_cov,
              noise_cov=job.noise_cov(sim), steady=True)
    return job, sim, kw


def _estimator(job, kw):
    return Estimator(job.filter_model(), job.sensors, job.forces, job.dt, **kw)


def _pieces(Y, n, seed=0):
    cuts = np.sort(np.random.default_rng(seed).choice(np.arange(1, Y.shape[0]), size=n - 1, replace=False))
    return np.split(Y, cuts)


class _Fatigue:
    """on_piece: the fatigue counts of a piece (a picklable callable)."""

    def __init__(self, W):
        self.W = W

    def __call__(self, est, i):
        acc = FatigueAccumulator(self.W.shape[0], SNCurve.ec3(36))
        acc.update(est.strains @ self.W.T)
        return est.forces, acc


def test_zero_state_end_is_the_recursion():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(6, 6))
    F, L, Y = A / (1.2 * np.max(np.abs(np.linalg.eigvals(A)))), rng.normal(size=(6, 2)), rng.normal(size=(1001, 2))
    x = np.zeros(6)
    for y in Y:
        x = F @ x + L @ y
    for block in (1, 37, 256, 5000):
        np.testing.assert_allclose(zero_state_end(F, L, Y, block), x, rtol=1e-12, atol=1e-13 * np.abs(x).max())


def test_pieces_filtered_at_once_equal_the_sequential_stream(record):
    job, sim, kw = record
    Y = sim.measurements
    sequential = _estimator(job, kw).update(Y)
    W = stress_operator(job.structure, range(job.structure.n_strain))
    out = estimate_in_parallel(_estimator(job, kw), _pieces(Y, 10), on_piece=_Fatigue(W))
    forces = np.vstack([f for f, _ in out])
    np.testing.assert_allclose(forces, sequential.forces, rtol=1e-9, atol=1e-9 * np.abs(sequential.forces).max())
    counts = out[0][1]
    for _, acc in out[1:]:
        counts.merge(acc)
    np.testing.assert_array_equal(counts.summary().cycles, rainflow(sequential.strains @ W.T).total())


def test_on_a_two_worker_dask_cluster(record):
    distributed = pytest.importorskip("distributed")
    job, sim, kw = record
    Y = sim.measurements
    sequential = _estimator(job, kw).update(Y)
    W = stress_operator(job.structure, range(job.structure.n_strain))
    with (distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster,
          distributed.Client(cluster) as client):
        out = estimate_in_parallel(_estimator(job, kw), _pieces(Y, 6, seed=1),
                                   map_pieces=lambda f, xs: client.gather(client.map(f, xs, pure=False)),
                                   on_piece=_Fatigue(W))
    forces = np.vstack([f for f, _ in out])
    np.testing.assert_allclose(forces, sequential.forces, rtol=1e-9, atol=1e-9 * np.abs(sequential.forces).max())
    counts = out[0][1]
    for _, acc in out[1:]:
        counts.merge(acc)
    one = FatigueAccumulator(W.shape[0], SNCurve.ec3(36))
    one.update(sequential.strains @ W.T)
    np.testing.assert_array_equal(counts.summary().cycles, one.summary().cycles)
    np.testing.assert_allclose(counts.summary().damage, one.summary().damage, rtol=1e-9)


def test_the_time_parallel_filter_needs_a_fresh_steady_estimator(record):
    job, sim, kw = record
    with pytest.raises(AKFInputError, match="steady-state estimator"):
        TimeParallel(_estimator(job, kw | {"steady": False}))
    used = _estimator(job, kw)
    used.update(sim.measurements[:10])
    with pytest.raises(AKFInputError, match="record's start"):
        TimeParallel(used)
    with pytest.raises(AKFInputError, match="same outputs"):
        FatigueAccumulator(2, SNCurve.ec3(36)).merge(FatigueAccumulator(3, SNCurve.ec3(36)))


def _measured_files(tmp_path, files=8):
    return measured_s17_files(tmp_path, files, {"fatigue": {"detail_category": 36}, "strains": ["strain:13", "strain:1"]})


@pytest.mark.parametrize("cluster", [False, True], ids=["joblib", "dask LocalCluster"])
def test_akf_estimate_of_many_files_in_parallel_equals_the_sequential_run(tmp_path, cluster):
    """The files of a record filtered at once (2 workers) write what the sequential run writes: the
    forces and strains to 1e-9, the fatigue counts exactly, the same diagnostics."""
    import pandas as pd

    from akf.estimate import estimate_job
    from akf.job import Job
    from akf.parallel import scheduler

    job = Job.from_dict(_measured_files(tmp_path), "estimate")
    sequential = estimate_job(job, str(tmp_path / "seq"), plot=False)
    with scheduler("local:2" if cluster else None):
        parallel = estimate_job(job, str(tmp_path / "par"), plot=True, n_jobs=2 if not cluster else -1)
    a, b = (pd.read_csv(r.files["timeseries"]).sort_values(["quantity", "channel", "time"], kind="stable")
            .reset_index(drop=True) for r in (sequential, parallel))       # rows are grouped per chunk, per file
    assert list(a.columns) == list(b.columns) and a.shape == b.shape
    pd.testing.assert_frame_equal(a.drop(columns="estimated"), b.drop(columns="estimated"))
    scale = a.groupby("quantity")["estimated"].transform(lambda v: np.abs(v).max())
    assert np.all(np.abs(a["estimated"] - b["estimated"]) <= 1e-9 * scale)
    fa, fb = pd.read_csv(sequential.files["fatigue"]), pd.read_csv(parallel.files["fatigue"])
    np.testing.assert_array_equal(fa["cycles"], fb["cycles"])
    np.testing.assert_allclose(fa[["max_range_MPa", "damage", "del_MPa"]], fb[["max_range_MPa", "damage", "del_MPa"]], rtol=1e-8)
    assert parallel.metrics["loglik"] == pytest.approx(sequential.metrics["loglik"], rel=1e-9)
    for s, p in zip(sequential.metrics["sensors"], parallel.metrics["sensors"]):
        assert p["consistency"] == pytest.approx(s["consistency"], rel=1e-9)
        assert p["whiteness"] == pytest.approx(s["whiteness"], abs=1e-12)
    for s, p in zip(sequential.metrics["forces"], parallel.metrics["forces"]):
        assert p["channel"] == s["channel"] and p["time_of_peak"] == s["time_of_peak"]
        assert [p["rms"], p["peak"]] == pytest.approx([s["rms"], s["peak"]], rel=1e-9)
    assert any("time-parallel" in n for n in parallel.notes) and "fatigue_figure" in parallel.files
    assert not (tmp_path / "par" / ".pieces").exists()


def test_a_time_parallel_run_refuses_what_it_cannot_do(tmp_path):
    from akf.estimate import estimate_job
    from akf.job import Job

    data = _measured_files(tmp_path, files=3)
    with pytest.raises(AKFInputError, match="smoothing"):
        estimate_job(Job.from_dict({**data, "filter": data["filter"] | {"smooth": True}}, "estimate"),
                     str(tmp_path / "a"), n_jobs=2)
    with pytest.raises(AKFInputError, match="steady-state"):
        estimate_job(Job.from_dict({**data, "filter": data["filter"] | {"steady": False}}, "estimate"),
                     str(tmp_path / "b"), n_jobs=2)
    with pytest.raises(AKFInputError, match="not resumed"):
        estimate_job(Job.from_dict(data, "estimate"), str(tmp_path / "c"), n_jobs=2, stop_after=1)


def test_akf_estimate_n_jobs_on_the_command_line(tmp_path, capsys):
    import json

    import tomlkit

    from akf.cli import main

    (tmp_path / "job.toml").write_text(tomlkit.dumps(_measured_files(tmp_path, files=4)))
    assert main(["estimate", str(tmp_path / "job.toml"), "--n-jobs", "2", "--json", "--no-plot",
                 "--out", str(tmp_path / "o")]) == 0
    d = json.loads(capsys.readouterr().out)
    assert any("time-parallel: 4 files" in n for n in d["notes"]) and d["complete"] and "fatigue" in d["files"]
