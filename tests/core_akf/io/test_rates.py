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
