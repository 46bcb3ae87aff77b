"""Binary records that lie, found by fuzzing the TDMS, HDF5, UFF and Parquet readers: time grids
stated as text, arrays, NaN or times too large to step from; damaged bytes; samples no sensor can
read (overflow codes); digital channels; units that count raw values; date-time stamps."""
import re

import numpy as np
import pandas as pd
import pytest
from helpers import ROOT

from core_akf.checks import AKFInputError
from core_akf.io import Record, conversion

DAQ = ROOT / "examples" / "daq"
CHANNELS = {"ACC_4Y": "acc:4:y", "ACC_6Y": "acc:6:y", "SG5": "strain:5"}
UNITS = {"ACC_4Y": "g", "ACC_6Y": "g", "SG5": "microstrain"}
DT = 1 / 4096


def _samples(n=512):
    """The first ``n`` rows of the sample record (file units), with its time column."""
    return pd.read_csv(DAQ / "record.csv").iloc[:n][["time", *CHANNELS]]


def _read(path, **kw):
    return Record(path, list(CHANNELS.values()), channels=CHANNELS, units=UNITS, **kw).read()


def _tdms(path, frame, props=None, time=None):
    nptdms = pytest.importorskip("nptdms")
    props = {"wf_increment": DT, "wf_start_offset": 0.0} if props is None else props
    channels = [nptdms.ChannelObject("DAQ", c, frame[c].to_numpy(), properties=dict(props)) for c in CHANNELS]
    if time is not None:
        channels.append(nptdms.ChannelObject("DAQ", "time", time))
    with nptdms.TdmsWriter(path) as w:
        w.write_segment([nptdms.GroupObject("DAQ"), *channels])


def _h5(path, frame, attrs=None, data=None):
    h5py = pytest.importorskip("h5py")
    with h5py.File(path, "w", track_order=True) as f:
        for key, value in ({"dt": DT} if attrs is None else attrs).items():
            f.attrs[key] = value
        for c in CHANNELS:
            f.create_dataset(c, data=frame[c].to_numpy() if data is None or c not in data else data[c])


@pytest.mark.parametrize("props, message", [
    ({"wf_increment": "abc"}, "channel 'ACC_4Y': wf_increment is 'abc', not a finite number of seconds"),
    ({"wf_increment": np.nan}, "wf_increment is nan, not a finite number"),
    ({"wf_increment": 0.0}, "the time step 0.0 s is not positive"),
    ({"wf_increment": DT, "wf_start_offset": np.nan}, "wf_start_offset is nan, not a finite number"),
    ({"wf_increment": DT, "wf_start_offset": 1e300}, "the first time 1e\\+300 s is so large that steps of 0.000244141 s"),
])
def test_a_tdms_time_grid_that_is_no_number_of_seconds_is_named(tmp_path, props, message):
    """Text or NaN in wf_increment ended in an internal error; a start of 1e300 s ran, with every
    peak "at 1e300 s" and the steps indistinguishable."""
    _tdms(tmp_path / "r.tdms", _samples(), props)
    with pytest.raises(AKFInputError, match=message):
        _read(tmp_path / "r.tdms")


@pytest.mark.parametrize("attrs, message", [
    ({"dt": np.array([DT, DT])}, "attribute dt of the group is an array of 2 values, not a finite number"),
    ({"dt": "0.001 s"}, "attribute dt of the group is '0.001 s', not a finite number"),
    ({"dt": b"x"}, "attribute dt of the group is 'x', not a finite number"),
    ({"dt": -DT}, "the time step -0.000244140625 s is not positive"),
    ({"dt": DT, "t0": "x"}, "attribute t0 of the group is 'x'"),
])
def test_an_hdf5_time_grid_that_is_no_number_of_seconds_is_named(tmp_path, attrs, message):
    """An array or text in the attribute dt ended in an internal error; a negative dt was taken."""
    _h5(tmp_path / "r.h5", _samples(), attrs)
    with pytest.raises(AKFInputError, match=message):
        _read(tmp_path / "r.h5")


def test_a_stated_step_beside_a_time_channel_must_be_a_number(tmp_path):
    _tdms(tmp_path / "r.tdms", _samples(), {"wf_increment": "fast"}, time=_samples()["time"].to_numpy())
    with pytest.raises(AKFInputError, match="wf_increment .* is 'fast', not a finite number"):
        _read(tmp_path / "r.tdms")


@pytest.mark.parametrize("fmt", ["h5", "tdms"])
def test_damaged_bytes_give_a_read_or_an_error_naming_the_file(tmp_path, fmt):
    """Every 64-byte stretch of the file zeroed in turn: each read either succeeds or raises an
    AKFInputError naming the file; a damaged HDF5 index ended in "internal error in
    LinkProxy.iterate: RuntimeError" before."""
    path = tmp_path / f"r.{fmt}"
    (_h5 if fmt == "h5" else _tdms)(path, _samples(256))
    good = path.read_bytes()
    errors = 0
    for start in range(0, len(good), 64):
        damaged = bytearray(good)
        damaged[start:start + 64] = bytes(len(damaged[start:start + 64]))
        path.write_bytes(bytes(damaged))
        try:
            _read(path)
        except AKFInputError as exc:
            errors += 1
            assert str(path) in str(exc) or "channel" in str(exc), str(exc)
    assert errors > 0


@pytest.mark.parametrize("value", [9.9e37, -1e300, 3e6])
def test_a_sample_no_sensor_can_read_is_named_with_its_step(tmp_path, value):
    """1e300 in one acceleration sample ran to exit 0 with NaN estimates and "invalid value" warnings;
    an overflow code such as 9.9e37 is named as such, with its channel, step and time."""
    frame = _samples()
    frame.loc[300, "ACC_6Y"] = value
    _h5(tmp_path / "r.h5", frame)
    with pytest.raises(AKFInputError, match=f"channel 'ACC_6Y' \\(acc:6:y\\): 1 of 512 samples of steps 0..511, the "
                                            f"first {re.escape(f'{value * 9.80665:.4g}')} m/s\\^2 at step 300 \\(t = 0.0732422 s\\) "
                                            "are beyond what an accelerometer reads .* overflow code"):
        _read(tmp_path / "r.h5")


def test_a_channel_mostly_beyond_reach_is_a_unit_not_a_spike(tmp_path):
    """Microstrain read as m/m keeps its unit hint; an accelerometer mostly beyond reach asks for its unit."""
    _samples().to_csv(tmp_path / "r.csv", index=False)
    with pytest.raises(AKFInputError, match="strain channel 'SG5' \\(strain:5\\) has an RMS of .* it looks like "
                                            "microstrain"):
        Record(tmp_path / "r.csv", ["strain:5"], channels={"SG5": "strain:5"}, units={"SG5": "m/m"}).read()
    with pytest.raises(AKFInputError, match="channel 'ACC_4Y' \\(acc:4:y\\): 512 of 512 samples .* beyond what an "
                                            "accelerometer reads \\(\\|x\\| > 1e\\+06 m/s\\^2\\); is the channel's unit"):
        Record(tmp_path / "r.csv", ["acc:4:y"], channels={"ACC_4Y": "acc:4:y"}, units={"ACC_4Y": "Gm/s^2"}).read()


def test_a_true_false_channel_is_not_a_measurement(tmp_path):
    """A digital line mapped to a sensor was read as 0/1 microstrain, silently."""
    frame = _samples()
    frame["SG5"] = frame["SG5"] > 0
    frame.to_parquet(tmp_path / "r.parquet")
    with pytest.raises(AKFInputError, match="channel 'SG5' holds true/false values"):
        _read(tmp_path / "r.parquet")
    _h5(tmp_path / "r.h5", _samples(), data={"SG5": frame["SG5"].to_numpy()})
    with pytest.raises(AKFInputError, match="channel 'SG5' holds true/false values"):
        _read(tmp_path / "r.h5")


def test_a_uff_sample_beyond_reach_is_named(tmp_path):
    """UFF values were taken without any check of their range (pyuff writes inf as 1.8e308)."""
    pyuff = pytest.importorskip("pyuff")
    frame = _samples()
    frame.loc[7, "ACC_4Y"] = np.inf
    sets = [pyuff.prepare_58(binary=0, id1=c, func_type=1, rsp_node=1, rsp_dir=2, ref_node=0, ref_dir=0,
                             ord_data_type=4, abscissa_spacing=1, num_pts=len(frame), x=frame["time"].to_numpy(),
                             data=frame[c].to_numpy(), abscissa_spec_data_type=17, abscissa_axis_units_lab="s",
                             ordinate_spec_data_type=0, ordinate_axis_units_lab=UNITS[c], orddenom_spec_data_type=0,
                             z_axis_spec_data_type=0) for c in CHANNELS]
    pyuff.UFF(str(tmp_path / "r.uff")).write_sets(sets, mode="overwrite")
    with pytest.raises(AKFInputError, match="channel 'ACC_4Y' \\(acc:4:y\\): 1 of 512 samples .* at step 7"):
        _read(tmp_path / "r.uff")


@pytest.mark.parametrize("unit, what", [("counts", "a count of raw values \\(ADC counts, bits or bytes\\)"),
                                        ("kbyte", "a count of raw values \\(ADC counts, bits or bytes\\)"),
                                        ("dB", "a logarithmic level"), ("Np", "a logarithmic level")])
def test_a_unit_that_counts_raw_values_or_a_level_is_no_strain(unit, what):
    """pint counts "counts", "byte" (x8) and "dB" (x1.26) as dimensionless, so they were taken as strain."""
    with pytest.raises(AKFInputError, match=f"'{unit}' is {what}, not a unit of strain"):
        conversion(unit, "strain", "SG5")
    assert conversion("1", "strain", "SG5").scale == 1.0 and conversion("ppm", "strain", "SG5").scale == 1e-6


def test_date_time_stamps_are_read_as_seconds(tmp_path):
    """TDMS and Parquet store time stamps as date-times, and CSV exports write them as ISO 8601 text:
    the grid is read from them, starting at the first stamp's seconds since 1970 (they were refused
    as text, or ended in an internal error)."""
    frame = _samples()
    t_ref, Y_ref = _read_csv(tmp_path, frame)
    start = np.datetime64("2026-12-05T10:00:00", "ns")
    stamps = start + (frame["time"].to_numpy() * 1e9).round().astype("timedelta64[ns]")
    _tdms(tmp_path / "r.tdms", frame, props={}, time=stamps)
    dated = frame.assign(time=stamps)
    dated.to_parquet(tmp_path / "r.parquet")
    dated.assign(time=pd.Series(stamps).dt.strftime("%Y-%m-%dT%H:%M:%S.%f+00:00")).to_csv(tmp_path / "r.csv", index=False)
    epoch = (start - np.datetime64("1970-01-01", "ns")) / np.timedelta64(1, "s")
    for path in (tmp_path / "r.tdms", tmp_path / "r.parquet", tmp_path / "r.csv"):
        record = Record(path, list(CHANNELS.values()), channels=CHANNELS, units=UNITS)
        t, Y = record.read()
        assert record.dt == pytest.approx(DT, rel=1e-5)        # the libraries give the stamps in µs
        assert t[0] == epoch and np.array_equal(Y, Y_ref)
        assert np.allclose(t - t[0], t_ref, rtol=0, atol=1e-6)
    dated.loc[5, "time"] = dated["time"][4]
    dated.to_parquet(tmp_path / "r.parquet")
    with pytest.raises(AKFInputError, match="time repeats at data row 6"):
        _read(tmp_path / "r.parquet")


def _read_csv(tmp_path, frame):
    frame.to_csv(tmp_path / "ref.csv", index=False)
    return _read(tmp_path / "ref.csv")


@pytest.mark.parametrize("ext", ["tdms", "h5", "uff", "parquet", "csv"])
def test_a_text_file_in_a_binary_format_s_name_is_named_not_quoted(tmp_path, ext):
    """npTDMS said "Segment does not start with b'TDSm', but with b'root'" of a system file named
    .tdms, and the message passed that on."""
    path = tmp_path / f"passwd.{ext}"
    path.write_bytes(b"root:x:0:0:root:/root:/bin/bash\n\xff\xfesecret-token:x:1:1\n")
    with pytest.raises(AKFInputError) as info:
        _read(path)
    text = str(info.value).replace(str(path), "")
    assert str(path) in str(info.value)
    assert "root" not in text and "secret" not in text, text


def test_a_tdms_file_without_channels_is_named(tmp_path):
    """npTDMS opens a short text file as a TDMS file without channels: it was reported as "sensor(s)
    [...] have no channel in any file of the record", or, in a folder of impacts, as an event."""
    (tmp_path / "notes.tdms").write_text("not a TDMS file\n")
    with pytest.raises(AKFInputError, match="notes.tdms: no channels: is it a TDMS file of measurements"):
        _read(tmp_path / "notes.tdms")
