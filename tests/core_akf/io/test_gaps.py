"""Gaps between a record's files: predicted through (missing samples) up to ``max_gap``, a restart
from the prior after a longer one; either way streamed, resumable bit for bit, and named."""
import numpy as np
import pandas as pd
import pytest
from helpers import ROOT, run_estimate

from akf.job import load_job_file
from core_akf.io import Record

DAQ = ROOT / "examples" / "daq"


def _two_files(folder, gap_s):
    """record.tdms cut in two TDMS files with ``gap_s`` seconds of nothing between them (no sample lost)."""
    from nptdms import ChannelObject, TdmsFile, TdmsWriter

    folder.mkdir()
    chans = TdmsFile.read(DAQ / "record.tdms")["DAQ"].channels()
    n, dt = len(chans[0]), chans[0].properties["wf_increment"]
    gap = int(round(gap_s / dt))
    for i, (a, b, offset) in enumerate([(0, n // 2, 0), (n // 2, n, n // 2 + gap)]):
        with TdmsWriter(folder / f"part-{i}.tdms") as w:
            w.write_segment([ChannelObject("DAQ", c.name, c[a:b], properties={
                "unit_string": c.properties["unit_string"], "wf_increment": dt, "wf_start_offset": offset * dt})
                for c in chans])
    return n, gap, dt


def _job(folder, **measurements):
    job = load_job_file(DAQ / "s17-tdms.toml")
    job["measurements"] = load_job_file(DAQ / "s17-tdms.toml")["measurements"] | {"file": str(folder)} | measurements
    return job


def _timeseries(out):
    ts = pd.read_csv(out / "timeseries.csv")
    return ts[ts.quantity == "force"]


def test_a_ten_second_gap_is_predicted_through_and_a_resumed_run_is_bit_identical(tmp_path):
    pytest.importorskip("nptdms")
    n, gap, dt = _two_files(tmp_path / "pieces", 10.0)
    job = _job(tmp_path / "pieces", chunk=0.5)
    whole = run_estimate(job, str(tmp_path / "whole"), plot=False)
    assert whole.complete and whole.metrics["n_steps"] == n + gap
    assert any("a gap of 10 s" in note and "predicts through it" in note for note in whole.notes)
    ts = _timeseries(tmp_path / "whole")
    assert len(ts) == 4 * (n + gap) and np.isfinite(ts.estimated).all()
    missing = {d["channel"]: d["missing_fraction"] for d in whole.metrics["sensors"]}
    assert all(f == pytest.approx(gap / (n + gap)) for f in missing.values())
    part = tmp_path / "part"
    first = run_estimate(job, str(part), plot=False, stop_after=5)          # stopped inside the gap
    assert not first.complete
    resumed = run_estimate(job, str(part), resume=True, plot=False)
    assert resumed.complete
    pd.testing.assert_frame_equal(_timeseries(part), ts)
    pd.testing.assert_frame_equal(pd.read_csv(part / "summary.csv"), pd.read_csv(tmp_path / "whole" / "summary.csv"))


def test_a_gap_longer_than_max_gap_restarts_the_filter(tmp_path):
    pytest.importorskip("nptdms")
    n, gap, dt = _two_files(tmp_path / "pieces", 10.0)
    res = run_estimate(_job(tmp_path / "pieces", max_gap=5.0), str(tmp_path / "out"), plot=False)
    assert res.complete
    assert any("longer than max_gap = 5 s, the filter restarts" in note for note in res.notes)
    ts = _timeseries(tmp_path / "out")
    t = np.sort(ts.time.unique())
    assert len(t) == n and np.isfinite(ts.estimated).all()
    assert t[n // 2] - t[n // 2 - 1] == pytest.approx((gap + 1) * dt)
    forces = {f["channel"]: f for f in res.metrics["forces"]}
    assert all(np.isfinite(f["rms"]) and f["rms"] > 0 for f in forces.values())


def test_a_gap_off_the_time_grid_is_refused(tmp_path):
    pytest.importorskip("nptdms")
    from nptdms import ChannelObject, TdmsWriter

    folder = tmp_path / "p"
    folder.mkdir()
    for i, offset in enumerate([0.0, 0.0105]):            # 10 steps of 1 ms, then 0.5 ms off the grid
        with TdmsWriter(folder / f"{i}.tdms") as w:
            w.write_segment([ChannelObject("g", "acc:4:y", np.zeros(10), properties={"wf_increment": 1e-3,
                                                                                    "wf_start_offset": offset})])
    with pytest.raises(ValueError, match="a gap of 0.0005 s \\(0.5 steps, not a whole number\\)"):
        Record(folder, ["acc:4:y"])


def test_a_long_gap_predicted_through_comes_chunk_by_chunk(tmp_path):
    """A gap of 10^9 steps (max_gap raised to cover it) was one block of NaN rows: 67 GB allocated
    at the first chunk, an internal MemoryError."""
    pytest.importorskip("nptdms")
    n, _, dt = _two_files(tmp_path / "pieces", 1e9 * 0.000244140625)
    meas = _job(tmp_path / "pieces")["measurements"]
    rec = Record(tmp_path / "pieces", load_job_file(DAQ / "s17-tdms.toml")["sensors"],
                 **{k: meas[k] for k in ("channels", "units", "gauge_factor", "bridge", "invert")}, max_gap=1e12)
    assert rec.n_steps == n + 10**9 and not rec.gaps[0].restart
    chunks = rec.chunks(1000)
    firsts = [next(chunks) for _ in range(3)]
    assert [(step, Y.shape[0]) for step, Y in firsts] == [(0, 1000), (1000, 1000), (2000, 1000)]
    assert np.isfinite(firsts[0][1][:n // 2]).all() and np.isnan(firsts[0][1][n // 2:]).all()
    assert np.isnan(firsts[2][1]).all()


def test_the_size_announced_counts_the_rows_written_not_a_restart_gap(tmp_path):
    """A gap of 2441 s past max_gap writes nothing, but the warning announced 4800 MB for it."""
    pytest.importorskip("nptdms")
    n, _, _ = _two_files(tmp_path / "pieces", 1e7 * 0.000244140625)
    res = run_estimate(_job(tmp_path / "pieces"), str(tmp_path / "out"), plot=False)
    assert res.complete and any("restarts from its prior" in note for note in res.notes)
    assert not any("will hold about" in w for w in res.metrics["warnings"]), res.metrics["warnings"]
    assert len(_timeseries(tmp_path / "out")) == 4 * n


def test_an_output_that_cannot_fit_on_the_disk_is_refused_before_the_run(tmp_path, monkeypatch):
    """A gap predicted through over 10^8 steps: a time series of about 48 GB on a disk with 1 GB free."""
    pytest.importorskip("nptdms")
    import shutil
    from collections import namedtuple

    from core_akf.checks import AKFInputError

    _two_files(tmp_path / "pieces", 1e8 * 0.000244140625)
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage(10**12, 10**12 - 10**9, 10**9))
    with pytest.raises(AKFInputError, match=r"timeseries.csv will hold about 4800\d MB .* but the disk of .* has "
                                            r"1000 MB free: list fewer channels"):
        run_estimate(_job(tmp_path / "pieces", max_gap=1e6), str(tmp_path / "out"), plot=False)
    assert not (tmp_path / "out" / "timeseries.csv").exists()
