"""Channels at different sampling rates, each set in files of its own: the filter steps at the
fastest rate and a slower channel updates at its own samples only (no resampling)."""
import numpy as np
import pandas as pd
import pytest
from helpers import ROOT, run_estimate

from akf.job import load_job_file
from core_akf.checks import AKFInputError
from core_akf.filter import estimate
from core_akf.io import open_record
from core_akf.io.record import MixedRecord
from core_akf.models import s17_truss

DAQ = ROOT / "examples" / "daq"
ACC = ["acc:4:y", "acc:6:y", "acc:8:y", "acc:12:y", "acc:6:x"]
GAUGES = ["strain:5", "strain:9", "strain:13", "strain:26"]
FORCES = ["4:y", "6:y", "8:y", "12:y"]
KW = dict(model_error_cov=1e-16, force_increment_cov=1e5, noise_cov={"acc": 0.2, "strain": 4e-14})


def _split(folder, every=16, gauge_start=0):
    """record-si.csv as accelerometers at 4096 Hz and gauges at 4096 / ``every`` Hz, in two files."""
    folder.mkdir()
    df = pd.read_csv(DAQ / "record-si.csv")
    df[["time"] + ACC].to_csv(folder / "acc.csv", index=False)
    df[["time"] + GAUGES].iloc[gauge_start::every].to_csv(folder / "gauges.csv", index=False)
    return df


def test_gauges_at_256_hz_give_the_single_rate_filter_fed_nan_between_their_samples(tmp_path):
    df = _split(tmp_path / "rec")
    Y = df[ACC + GAUGES].to_numpy().copy()
    off = np.ones(len(df), bool)
    off[::16] = False
    Y[off, len(ACC):] = np.nan
    ref = estimate(s17_truss().scaled(1.05), ACC + GAUGES, FORCES, Y, df.time[1], steady=True, **KW)
    job = load_job_file(DAQ / "s17-tdms.toml")
    job["measurements"] = {"file": str(tmp_path / "rec"), "chunk": 100 * df.time[1]}
    res = run_estimate(job, str(tmp_path / "out"), plot=False)
    ts = pd.read_csv(tmp_path / "out" / "timeseries.csv")
    f = ts[ts.quantity == "force"]
    forces = np.column_stack([f[f.channel == c].estimated.to_numpy() for c in FORCES])
    np.testing.assert_allclose(forces, ref.forces, rtol=0, atol=1e-10 * np.abs(ref.forces).max())
    missing = {d["channel"]: d["missing_fraction"] for d in res.metrics["sensors"]}
    assert missing["acc:4:y"] == 0 and missing["strain:9"] == pytest.approx(15 / 16)
    assert any("at 256 Hz" in line for line in res.channels)


def test_a_record_of_two_rates_reads_on_the_fastest_grid(tmp_path):
    df = _split(tmp_path / "rec", every=4, gauge_start=2)
    rec = open_record(tmp_path / "rec", ACC + GAUGES)
    assert isinstance(rec, MixedRecord) and rec.n_steps == len(df) and rec.dt == pytest.approx(df.time[1])
    whole = rec.read()[1]
    parts = np.vstack([Y for _, Y in rec.chunks(37)])
    np.testing.assert_array_equal(parts, whole)
    resumed = np.vstack([Y for _, Y in rec.chunks(37, 37 * 5)])
    np.testing.assert_array_equal(resumed, whole[37 * 5:])
    np.testing.assert_array_equal(whole[2::4, 5:], df[GAUGES].to_numpy()[2::4])
    assert np.isnan(whole[3::4, 5:]).all() and not np.isnan(whole[:, :5]).any()


def test_a_rate_that_does_not_divide_into_the_fastest_is_named(tmp_path):
    folder = tmp_path / "rec"
    folder.mkdir()
    t = np.arange(300) * 1e-3
    pd.DataFrame({"time": t, "acc:4:y": np.sin(t)}).to_csv(folder / "a.csv", index=False)
    pd.DataFrame({"time": t[::3][:60] * 1.5, "strain:9": np.cos(t[:60]) * 1e-6}).to_csv(folder / "b.csv", index=False)
    with pytest.raises(AKFInputError, match=r"strain:9 sample every 0.0045 s \(222.222 Hz\), which is not a whole number "
                                            r"of the fastest channels' step 0.001 s \(1000 Hz"):
        open_record(folder, ["acc:4:y", "strain:9"])
    pd.DataFrame({"time": t[:60] * 3, "acc:6:y": np.cos(t[:60])}).to_csv(folder / "b.csv", index=False)
    with pytest.raises(AKFInputError, match=r"sensor\(s\) \['strain:9'\] have no channel"):
        open_record(folder, ["acc:4:y", "acc:6:y", "strain:9"])


def _one_file_of_two_rates(path, df, every, gauge_start, fmt):
    """The accelerometers at the record's rate and the gauges at 1/``every`` of it, from
    ``gauge_start``, in one TDMS or HDF5 file: each channel with its own time step."""
    dt = float(df.time[1])
    grids = {c: (dt, 0.0) for c in ACC} | {c: (every * dt, gauge_start * dt) for c in GAUGES}
    data = {c: df[c].to_numpy() for c in ACC} | {c: df[c].to_numpy()[gauge_start::every] for c in GAUGES}
    if fmt == "tdms":
        from nptdms import ChannelObject, TdmsWriter
        with TdmsWriter(path) as w:
            w.write_segment([ChannelObject("daq", c, data[c], properties={"wf_increment": grids[c][0],
                                                                          "wf_start_offset": grids[c][1]})
                             for c in ACC + GAUGES])
    else:
        import h5py
        with h5py.File(path, "w") as f:
            f.attrs["dt"] = dt                           # the group's step: the accelerometers'
            for c in ACC + GAUGES:
                f[c] = data[c]
                if c in GAUGES:                          # the gauges' own
                    f[c].attrs["dt"], f[c].attrs["t0"] = grids[c]


@pytest.mark.parametrize("fmt", ["tdms", "h5"])
def test_channels_at_their_own_rates_in_one_file_read_as_in_files_of_their_own(tmp_path, fmt):
    pytest.importorskip("nptdms" if fmt == "tdms" else "h5py")
    df = _split(tmp_path / "rec", every=4, gauge_start=2)
    path = tmp_path / f"one.{fmt}"
    _one_file_of_two_rates(path, df, 4, 2, fmt)
    rec = open_record(path, ACC + GAUGES)
    assert isinstance(rec, MixedRecord) and rec.n_steps == len(df) and rec.ratios == [1, 4]
    whole = rec.read()[1]
    np.testing.assert_array_equal(whole, open_record(tmp_path / "rec", ACC + GAUGES).read()[1])
    np.testing.assert_array_equal(np.vstack([Y for _, Y in rec.chunks(37, 37 * 5)]), whole[37 * 5:])
    assert any("at 1024 Hz" in line for line in rec.describe())
    # one rate set alone is an ordinary record of that file
    gauges = open_record(path, GAUGES)
    assert not isinstance(gauges, MixedRecord) and gauges.dt == pytest.approx(4 * df.time[1])
    np.testing.assert_array_equal(gauges.read()[1], df[GAUGES].to_numpy()[2::4])


def test_a_file_of_two_rates_opened_as_one_grid_names_its_rates(tmp_path):
    pytest.importorskip("nptdms")
    from core_akf.io import open_file

    df = _split(tmp_path / "rec", every=4, gauge_start=2)
    _one_file_of_two_rates(tmp_path / "one.tdms", df, 4, 2, "tdms")
    reader = open_file(tmp_path / "one.tdms")
    assert reader.rate_sets() == [ACC, GAUGES]
    with pytest.raises(AKFInputError, match=r"different time grids \(acc:4:y, .*acc:6:x every 0.000244141 s; "
                                            r"strain:5, .*strain:26 every 0.000976562 s\); open it with "
                                            r"core_akf.io.open_record"):
        reader.timing()
    reader.restrict(GAUGES)
    assert reader.timing().n_steps == len(df[2::4])


def test_akf_estimate_on_one_tdms_file_of_two_rates_gives_the_single_rate_filter_fed_nan(tmp_path):
    pytest.importorskip("nptdms")
    df = _split(tmp_path / "rec")
    _one_file_of_two_rates(tmp_path / "one.tdms", df, 16, 0, "tdms")
    Y = df[ACC + GAUGES].to_numpy().copy()
    off = np.ones(len(df), bool)
    off[::16] = False
    Y[off, len(ACC):] = np.nan
    ref = estimate(s17_truss().scaled(1.05), ACC + GAUGES, FORCES, Y, df.time[1], steady=True, **KW)
    job = load_job_file(DAQ / "s17-tdms.toml")
    job["measurements"] = {"file": str(tmp_path / "one.tdms"), "chunk": 100 * df.time[1]}
    run_estimate(job, str(tmp_path / "out"), plot=False)
    ts = pd.read_csv(tmp_path / "out" / "timeseries.csv")
    f = ts[ts.quantity == "force"]
    forces = np.column_stack([f[f.channel == c].estimated.to_numpy() for c in FORCES])
    np.testing.assert_allclose(forces, ref.forces, rtol=0, atol=1e-10 * np.abs(ref.forces).max())


def test_channels_of_different_lengths_beside_a_time_channel_are_named_not_a_traceback(tmp_path):
    nptdms = pytest.importorskip("nptdms")
    from core_akf.io import open_file

    with nptdms.TdmsWriter(tmp_path / "x.tdms") as w:
        w.write_segment([nptdms.ChannelObject("g", "time", np.arange(10) * 1e-3),
                         nptdms.ChannelObject("g", "a", np.ones(10), properties={"wf_increment": 1e-3}),
                         nptdms.ChannelObject("g", "b", np.ones(5))])
    with pytest.raises(AKFInputError, match=r"channels of different lengths \[5, 10\]"):
        open_file(tmp_path / "x.tdms").timing()
    with nptdms.TdmsWriter(tmp_path / "y.tdms") as w:
        w.write_segment([nptdms.ChannelObject("g", "a", np.ones(10), properties={"wf_increment": 1e-3}),
                         nptdms.ChannelObject("g", "b", np.ones(5))])
    with pytest.raises(AKFInputError, match=r"different time grids \(a every 0.001 s; b no wf_increment\)"):
        open_file(tmp_path / "y.tdms").timing()
