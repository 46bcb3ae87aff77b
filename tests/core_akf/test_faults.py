"""Sensor-fault tests (core_akf.faults) on synthetic channels, chunk by chunk, and through akf
estimate on the S17 case-4 record with a stuck accelerometer, spikes and clipping."""
import numpy as np
import pandas as pd
import pytest
from helpers import run_estimate

from akf.examples import example_job
from akf.job import Job
from core_akf.faults import FaultDetector, FaultSettings


def _signal(n=20000, seed=0):
    """A smooth band-limited signal in noise, as an oversampled sensor records it."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 4096
    return (np.sin(2 * np.pi * 13 * t) + 0.5 * np.sin(2 * np.pi * 71 * t + 1) + 0.01 * rng.standard_normal(n))[:, None]


def _run(detector, Y, size, E=None):
    flags = np.zeros(Y.shape, bool)
    for a in range(0, len(Y), size):
        flags[a:a + size] = detector.raw(Y[a:a + size], a)
        if E is not None:
            flags[a:a + size] |= detector.innovations(E[a:a + size], a)
    return flags


def test_each_raw_fault_is_found_with_its_span_whatever_the_chunks():
    y = _signal()
    rail = 0.8 * np.abs(y).max()
    clipped = np.abs(y[:, 0]) > rail
    y = np.clip(y, -rail, rail)
    y[3000:3100, 0] = 0.1                                         # stuck
    spikes = [500, 7000, 12001, 15555]
    y[spikes, 0] += np.array([0.5, -0.5, 0.4, -0.6])
    truth = clipped.copy()
    truth[3000:3100] = False
    truth[3000:3100] = True
    truth[spikes] = True
    found = {}
    for size in (20000, 999, 64):
        d = FaultDetector(["acc:4:y"])
        flags = _run(d, y, size)[:, 0]
        faults = d.faults()
        found[size] = [(f.kind, f.first, f.stop) for f in faults]
        flagged = np.zeros(len(y), bool)
        for f in faults:
            flagged[f.first:f.stop] = True
        assert flagged[truth].mean() == 1.0                       # every faulty sample reported
        assert flagged[~truth].mean() < 1e-3
        assert flags[truth].mean() > 0.95
        kinds = {f.kind for f in faults}
        assert kinds == {"stuck", "spike", "clipped"}
        stuck = [f for f in faults if f.kind == "stuck"]
        assert [(f.first, f.stop) for f in stuck] == [(3000, 3100)]
    assert found[999] == found[20000]


def test_clean_signals_raise_no_alarm():
    for seed in range(5):
        y = _signal(seed=seed)
        e = np.random.default_rng(seed + 10).standard_normal((len(y), 1))     # white innovations
        d = FaultDetector(["strain:9"])
        flags = _run(d, y, 4096, e)
        assert flags.mean() < 1e-3, d.faults()[:5]


def test_a_bias_in_the_innovations_is_a_drift_from_where_it_began():
    e = np.random.default_rng(3).standard_normal((20000, 1))
    e[8000:, 0] += 1.5
    d = FaultDetector(["strain:26"], FaultSettings(cusum_drift=1.0, cusum_threshold=60.0))    # a bias of 1.5 sigma
    flags = _run(d, _signal(), 4096, e)
    drift = [f for f in d.faults() if f.kind == "drift"]
    assert len(drift) == 1 and abs(drift[0].first - 8000) < 50 and drift[0].stop == 20000
    assert flags[8200:, 0].mean() > 0.99 and flags[:7900, 0].mean() < 1e-3


def test_a_detector_continues_from_its_saved_state():
    y = _signal()
    y[4000:4060, 0] = y[4000, 0]
    y[[900, 9000], 0] += 5.0
    whole = FaultDetector(["acc:4:y"])
    _run(whole, y, 1000)
    first = FaultDetector(["acc:4:y"])
    _run(first, y[:4000], 1000)                              # stopped inside the stuck span
    second = FaultDetector(["acc:4:y"]).restore(first.state())
    for a in range(4000, len(y), 1000):
        second.raw(y[a:a + 1000], a)
    assert second.faults() == whole.faults()


@pytest.fixture(scope="module")
def case4_faults(tmp_path_factory):
    data = example_job("s17-case4")
    job = Job.from_dict(data, "estimate")
    sim = job.simulate()
    loads = job.loads(sim.measurements.shape[0])
    Y, labels, rng = sim.measurements.copy(), data["sensors"], np.random.default_rng(0)
    N = len(Y)
    truth = np.zeros(Y.shape, bool)
    j = labels.index("acc:6:y")
    Y[int(0.3 * N):int(0.35 * N), j] = Y[int(0.3 * N), j]
    truth[int(0.3 * N):int(0.35 * N), j] = True
    j = labels.index("acc:12:y")
    idx = rng.choice(N, 12, replace=False)
    Y[idx, j] += 10 * np.std(Y[:, j]) * rng.choice([-1, 1], 12)
    truth[idx, j] = True
    j = labels.index("acc:8:y")
    rail = 0.8 * np.abs(Y[:, j]).max()
    truth[:, j] = np.abs(Y[:, j]) > rail
    Y[:, j] = np.clip(Y[:, j], -rail, rail)
    folder = tmp_path_factory.mktemp("faults")

    def run(name, record, mode):
        frame = pd.DataFrame(record, columns=labels)
        frame.insert(0, "time", np.arange(N) * data["dt"])
        frame.to_csv(folder / f"{name}.csv", index=False, float_format="%.17g")
        measured = {k: v for k, v in data.items() if k != "simulation"}
        measured["filter"] = dict(data["filter"], noise_cov=[float(v) ** 2 for v in sim.noise_std])
        measured["measurements"] = {"file": str(folder / f"{name}.csv"), "chunk": 0.25, "faults": mode}
        res = run_estimate(measured, str(folder / f"{name}-{mode}"), plot=False)
        ts = pd.read_csv(folder / f"{name}-{mode}" / "timeseries.csv")
        f = ts[ts.quantity == "force"]
        F = np.column_stack([f[f.channel == c].estimated.to_numpy() for c in data["forces"]])
        return res, float(np.sqrt(np.mean((F - loads) ** 2))), folder / f"{name}-{mode}"
    return run, sim.measurements, Y, truth, labels, data["dt"]


def test_faults_in_a_record_are_reported_and_dropped(case4_faults):
    run, clean, faulty, truth, labels, dt = case4_faults
    _, clean_error, _ = run("clean", clean, "flag")
    errors = {}
    for mode in ("flag", "drop"):
        res, errors[mode], out = run("faulty", faulty, mode)
        quality = pd.read_csv(out / "data_quality.csv")
        assert list(quality.columns) == ["channel", "kind", "start_s", "end_s", "samples", "evidence"]
        flagged = np.zeros(truth.shape, bool)
        for _, r in quality.iterrows():
            a = int(round(r.start_s / dt))
            flagged[a:a + int(r.samples), labels.index(r.channel)] = True
        for j in np.flatnonzero(truth.any(axis=0)):
            assert flagged[truth[:, j], j].mean() >= 0.95, labels[j]
        found = set(zip(quality.channel, quality.kind))
        assert {("acc:6:y", "stuck"), ("acc:12:y", "spike"), ("acc:8:y", "clipped")} <= found
        stuck = [f for f in res.metrics["faults"] if f["channel"] == "acc:6:y" and f["kind"] == "stuck"]
        assert len(stuck) == 1 and stuck[0]["start_s"] == pytest.approx(0.6, abs=dt) and stuck[0]["samples"] == 410
        assert any(w.startswith("acc:") and "samples;" in w for w in res.metrics["warnings"])
        assert len(res.metrics["faults"]) == len(quality)
    assert flagged[~truth].mean() < 0.01                        # with "drop" (measured 0.23 %)
    # measured: the faulty record 2.34x the clean record's force error as it is, 1.20x with the faults dropped
    assert errors["drop"] < 1.3 * clean_error < 2 * clean_error < errors["flag"]
