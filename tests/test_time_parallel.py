"""Months of data on many cores (issue 23, item 6): the steady-state AKF over a record's pieces
filtered at the same time (zero-state ends, a pass over the boundaries, every piece from its start
state) equals the sequential stream, also on a 2-worker dask cluster, and the pieces' rainflow
counts merge into the one-piece counts exactly."""
import numpy as np
import pytest

from akf.examples import example
from core_akf.exceptions import AKFInputError
from core_akf.fatigue import FatigueAccumulator, SNCurve, rainflow, stress_operator
from core_akf.streaming import Estimator, TimeParallel, estimate_in_parallel, zero_state_end


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
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as client:
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
