"""Records that disagree with themselves: time channels of another length, columns twice, a
frequency response for a time record, files of one record that state different units."""
import re

import numpy as np
import pandas as pd
import pytest
from helpers import ROOT, read_channels, run_estimate

DAQ = ROOT / "examples" / "daq"


@pytest.mark.parametrize("extra", [-3, 5])
def test_hdf5_time_channel_shorter_or_longer_than_the_data(tmp_path, extra):
    h5py = pytest.importorskip("h5py")
    n = 100
    with h5py.File(tmp_path / "r.h5", "w") as f:
        f.create_dataset("time", data=np.arange(n + extra) * 1e-3)
        f.create_dataset("acc:4:y", data=np.zeros(n))
        f.create_dataset("acc:6:y", data=np.ones(n))
    with pytest.raises(ValueError, match=f"time channel 'time' has {n + extra} samples but the data channels have {n}"):
        read_channels(tmp_path / "r.h5")


@pytest.mark.parametrize("extra", [-3, 5])
def test_tdms_time_channel_shorter_or_longer_than_the_data(tmp_path, extra):
    nptdms = pytest.importorskip("nptdms")
    n = 100
    with nptdms.TdmsWriter(tmp_path / "r.tdms") as w:
        w.write_segment([nptdms.ChannelObject("g", "time", np.arange(n + extra) * 1e-3),
                         nptdms.ChannelObject("g", "acc:4:y", np.zeros(n)),
                         nptdms.ChannelObject("g", "acc:6:y", np.ones(n))])
    with pytest.raises(ValueError, match=f"has {n + extra} samples but the data channels have {n}"):
        read_channels(tmp_path / "r.tdms")


def test_csv_with_two_columns_of_the_same_name(tmp_path):
    (tmp_path / "r.csv").write_text("time,acc:4:y,acc:6:y,acc:4:y\n" + "".join(f"{k / 1e3},1,2,3\n" for k in range(10)))
    with pytest.raises(ValueError, match="column 'acc:4:y' appears twice \\(columns 2 and 4\\)"):
        read_channels(tmp_path / "r.csv")


def test_parquet_with_two_columns_of_the_same_name(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    t = pa.table([pa.array(np.arange(10) / 1e3), pa.array(np.ones(10)), pa.array(np.zeros(10))],
                 names=["time", "acc:4:y", "acc:4:y"])
    pq.write_table(t, tmp_path / "r.parquet")
    with pytest.raises(ValueError, match="column 'acc:4:y' appears twice"):
        read_channels(tmp_path / "r.parquet", sensors=("acc:4:y",))


def test_uff58_frequency_response_is_not_a_time_record(tmp_path):
    pyuff = pytest.importorskip("pyuff")
    f = np.linspace(0, 100, 51)
    sets = [pyuff.prepare_58(binary=0, id1=name, func_type=4, rsp_node=k, rsp_dir=2, ref_node=1, ref_dir=2,
                             ord_data_type=6, abscissa_spacing=1, num_pts=f.size, x=f, data=(1 + 2j) * np.ones(f.size),
                             abscissa_spec_data_type=18, abscissa_axis_units_lab="Hz", ordinate_spec_data_type=12,
                             ordinate_axis_units_lab="m/s^2/N", orddenom_spec_data_type=13, z_axis_spec_data_type=0)
            for k, name in ((4, "acc:4:y"), (6, "acc:6:y"))]
    pyuff.UFF(str(tmp_path / "frf.uff")).write_sets(sets, mode="overwrite")
    with pytest.raises(ValueError, match="is a frequency response function \\(FRF\\), not a time response"):
        read_channels(tmp_path / "frf.uff")


def _csv_rows(n=200):
    return ["time,acc:4:y,acc:6:y"] + [f"{k / 1e3},{np.sin(k / 7):.6f},{np.cos(k / 5):.6f}" for k in range(n)]


@pytest.mark.parametrize("broken, row, fields", [
    (lambda rows: rows.__setitem__(120, "{},{}".format(*rows[120].split(",", 1)).replace(
        ",0.", ",0,").replace(",-0.", ",-0,")), 120, 5),                               # decimal commas
    (lambda rows: rows.__setitem__(60, rows[60] + ",7"), 60, 4),                      # a separator too many
    (lambda rows: rows.__setitem__(200, rows[200][:6]), 200, 2),                       # a row torn at the end
    (lambda rows: rows.__setitem__(33, rows[33].rsplit(",", 1)[0]), 33, 2)])          # a cell and its comma lost
def test_a_csv_row_of_another_width_is_named_not_shifted_into_other_channels(tmp_path, broken, row, fields):
    # pandas drops an extra field without a word when it picks columns, and the row's later cells
    # land in other channels; a short row became missing samples
    rows = _csv_rows()
    broken(rows)
    (tmp_path / "r.csv").write_text("\n".join(rows) + "\n")
    with pytest.raises(ValueError, match=f"data row {row} has {fields} fields where the header names 3"):
        read_channels(tmp_path / "r.csv")


@pytest.mark.parametrize("newline", ["\n", "\r\n"])
def test_csv_rows_with_empty_cells_quotes_blank_lines_and_no_final_newline_are_read(tmp_path, newline, monkeypatch):
    from core_akf.io import readers

    monkeypatch.setattr(readers, "WIDTH_BLOCK", 256)            # rows cut across the blocks the check reads
    rows = _csv_rows()
    rows[0] = '"time","acc:4:y","acc:6:y"'
    rows[50] = rows[50].rsplit(",", 1)[0] + ","                 # a missing sample: an empty cell
    rows.insert(90, "")                                        # a blank line, skipped as pandas skips it
    (tmp_path / "r.csv").write_text(newline.join(rows))
    t, Y = read_channels(tmp_path / "r.csv")[:2]
    assert Y.shape == (200, 2) and np.isnan(Y[49, 1]) and np.isfinite(np.delete(Y, 49, axis=0)).all()


def _two_tdms(folder, unit_of_second, scale=1.0, channel="ACC_4Y"):
    """record.tdms cut in two files; the second states ``unit_of_second`` for ``channel`` and holds
    its values times ``scale``."""
    from nptdms import ChannelObject, TdmsFile, TdmsWriter

    folder.mkdir()
    chans = TdmsFile.read(DAQ / "record.tdms")["DAQ"].channels()
    n, dt = len(chans[0]), chans[0].properties["wf_increment"]
    for i, (a, b) in enumerate([(0, n // 2), (n // 2, n)]):
        with TdmsWriter(folder / f"part-{i}.tdms") as w:
            w.write_segment([ChannelObject("DAQ", c.name, c[a:b] * (scale if i and c.name == channel else 1.0),
                                           properties={"wf_increment": dt, "wf_start_offset": a * dt,
                                                       "unit_string": unit_of_second if i and c.name == channel
                                                       else c.properties["unit_string"]})
                             for c in chans])


def _sample_job(file):
    from akf.job import load_job_file

    job = load_job_file(DAQ / "s17-tdms.toml")
    job["measurements"]["file"] = str(file)
    return job


@pytest.mark.parametrize("unset", ["", "NONE"])
def test_a_file_that_states_no_unit_where_another_does_is_refused(tmp_path, unset):
    """It was read as SI beside files in g: one file's accelerations 9.81 times too small, silently."""
    pytest.importorskip("nptdms")
    from akf.job import Job
    from core_akf.checks import AKFInputError

    _two_tdms(tmp_path / "rec", unset)
    with pytest.raises(AKFInputError, match=r"channel 'ACC_4Y' \(acc:4:y\) states 'g' in part-0.tdms, no unit in "
                                            r"part-1.tdms: a file without a unit would be read as SI \(m/s\^2\); "
                                            r"give the channel's unit: units = {'ACC_4Y': "):
        Job.from_dict(_sample_job(tmp_path / "rec"), "estimate").open_live_record()
    job = _sample_job(tmp_path / "rec")
    job["measurements"]["units"] = job["measurements"]["units"] | {"ACC_4Y": "g"}       # the way out
    record, _, warnings = Job.from_dict(job, "estimate").open_live_record()
    assert warnings == [] and record.n_steps == 1024


def test_files_in_different_units_are_each_converted_and_named(tmp_path):
    """A DAQ re-scaled between two files (g, then m/s^2): each file by its own unit gives the forces of
    the one file, with a warning naming both; the same unit spelled otherwise is no warning."""
    pytest.importorskip("nptdms")
    whole = run_estimate(_sample_job(DAQ / "record.tdms"), str(tmp_path / "whole"), plot=False)
    _two_tdms(tmp_path / "rec", "m/s^2", scale=9.80665)
    split = run_estimate(_sample_job(tmp_path / "rec"), str(tmp_path / "split"), plot=False)
    assert any("channel 'ACC_4Y' (acc:4:y) is recorded in different units: 'g' in part-0.tdms, 'm/s^2' in "
               "part-1.tdms; each file is converted by its own" in w for w in split.metrics["warnings"])
    assert not any("different units" in w for w in whole.metrics["warnings"])
    a, b = (pd.read_csv(tmp_path / d / "timeseries.csv") for d in ("whole", "split"))
    np.testing.assert_allclose(b.estimated, a.estimated, rtol=1e-9, atol=1e-9 * np.abs(a.estimated).max())
    _two_tdms(tmp_path / "same", "m/s2", channel="ACC_12Y")          # m/s^2 in the first
    same = run_estimate(_sample_job(tmp_path / "same"), str(tmp_path / "same-out"), plot=False)
    assert not any("different units" in w for w in same.metrics["warnings"])


@pytest.mark.parametrize("how", ["copy", "link"])
def test_a_file_twice_in_a_record_is_named_as_such(tmp_path, how):
    """A file copied (a download saved twice) or linked into a record's folder was named as an overlap
    of so many steps."""
    pytest.importorskip("nptdms")
    import os
    import shutil

    from core_akf.checks import AKFInputError

    _two_tdms(tmp_path / "rec", "g")
    (shutil.copy if how == "copy" else os.symlink)(tmp_path / "rec" / "part-1.tdms", tmp_path / "rec" / "part-1 (1).tdms")
    message = "they are one file (a link to it)" if how == "link" else "is one a copy of the other?"
    with pytest.raises(AKFInputError, match=r"part-1 \(1\).tdms and .*part-1.tdms hold the same time span \(512 steps "
                                            rf"from 0.125 s\): {re.escape(message)}; remove one from the record"):
        _sample_record(tmp_path / "rec")


def _sample_record(file):
    from akf.job import Job

    return Job.from_dict(_sample_job(file), "estimate").open_record()


@pytest.mark.parametrize("change, message", [
    (dict(files=None), "the record's files must be a path, a glob pattern, a folder or a list of those; got NoneType"),
    (dict(files=3), "got int"),
    (dict(units=["g"]), r"units must map file channels to units, e.g. \{'SG13': 'microstrain'\}; got list"),
    (dict(gauge_factor="2.1"), r"gauge_factor must be a number \(a gauge factor, about 2\), got '2.1'"),
    (dict(gauge_factor={"SG13": "2.1"}), r"gauge_factor\['SG13'\] must be a number"),
    (dict(remove_offset="yes"), "remove_offset must be true, false or a positive time"),
    (dict(max_gap=True), "max_gap must be a time >= 0"),
])
def test_record_arguments_of_the_wrong_type_are_named(change, message):
    """Each was a TypeError or ValueError from inside Python or numpy (a gauge factor as text compared
    with 0, units as a list made into a dict, a path of None iterated)."""
    from core_akf.checks import AKFInputError
    from core_akf.io import Record

    meas = _sample_job(DAQ / "record.tdms")["measurements"]
    kw = {k: meas[k] for k in ("channels", "gauge_factor", "bridge", "invert")} | change
    sensors = list(meas["channels"].values())
    with pytest.raises(AKFInputError, match=message):
        Record(kw.pop("files", DAQ / "record.tdms"), sensors, **kw)


def test_one_channel_to_invert_may_be_given_as_its_name():
    from core_akf.io import Record

    meas = _sample_job(DAQ / "record.tdms")["measurements"]
    kw = {k: meas[k] for k in ("channels", "gauge_factor", "bridge")}
    sensors = list(meas["channels"].values())
    one = Record(DAQ / "record.tdms", sensors, invert="ACC_6X", **kw).read()[1]
    listed = Record(DAQ / "record.tdms", sensors, invert=["ACC_6X"], **kw).read()[1]
    np.testing.assert_array_equal(one, listed)
