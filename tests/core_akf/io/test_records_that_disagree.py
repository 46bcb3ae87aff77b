"""Records that disagree with themselves: time channels of another length, columns twice, a
frequency response for a time record."""
import numpy as np
import pytest
from helpers import read_channels


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
