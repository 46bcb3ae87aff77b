"""What a user meets in a first week (issue: no lost results, records and outputs that cannot be
silently corrupted): each test is named after the input it tries."""
import json
import os
import shutil

import numpy as np
import pandas as pd
import pytest
import scipy.io
import scipy.sparse

from akf.cli import main
from core_akf.models import s17_truss

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OFFSET = 100

SIMULATION = """[filter]
model_error_cov = 1e-16
force_increment_cov = 1e4
[simulation]
duration = 1.0
relative_noise = 0.02
[[simulation.loads]]
components = [{type = "sine", frequency = 3.0, amplitude = 300.0}]
"""


@pytest.fixture(scope="module")
def frame3d(tmp_path_factory):
    """The S17 truss exported as a model of one's own in 3-D coordinates (z = 0): K.mtx, M.mtx,
    dofs.csv, nodes.csv, a strain operator S.mtx (the 34 member strains) and the start of a job."""
    s = s17_truss()
    d = tmp_path_factory.mktemp("frame3d")
    ids = np.arange(1, s.n_nodes + 1) + OFFSET
    dofs = [(int(i), c) for i in ids for c in "xy"]
    (d / "dofs.csv").write_text("node,direction\n" + "".join(f"{n},{c}\n" for n, c in dofs))
    (d / "nodes.csv").write_text("node,x,y,z\n" + "".join(
        f"{i},{float(s.nodes[i - OFFSET - 1][0])!r},{float(s.nodes[i - OFFSET - 1][1])!r},0.0\n" for i in ids))
    scipy.io.mmwrite(d / "K.mtx", scipy.sparse.coo_matrix(s.meta["K_full"]), symmetry="symmetric")
    scipy.io.mmwrite(d / "M.mtx", scipy.sparse.coo_matrix(s.meta["M_full"]), symmetry="symmetric")
    S = np.zeros((s.n_strain, len(dofs)))
    S[:, s.free_dofs] = s.strain_matrix
    scipy.io.mmwrite(d / "S.mtx", scipy.sparse.coo_matrix(S))
    fixed = ", ".join(f'"{j + OFFSET}:{c}"' for j, cs in s.meta["supports"].items() for c in cs)
    structure = f"""dt = 0.001953125
forces = ["108:y"]
[structure]
model = "matrices"
K = "K.mtx"
M = "M.mtx"
dofs = "dofs.csv"
nodes = "nodes.csv"
fixed = [{fixed}]
damping = 0.007
"""
    return d, structure


PLACE_3D = """[place]
candidates = ["strain:5", "strain:13", "strain:35", "strain:36", "acc:108:y", "acc:106:y"]
budget = {strain = 2, acc = 1}
window = 0.25
population = 6
generations = 2
"""


def test_place_on_a_3d_model_of_ones_own_with_operator_rows_and_extensometers(frame3d, tmp_path, capsys):
    """The layout figure failed on strain outputs without a member (`node id must be an integer,
    got None`) after the whole GA had run; now the layout is written with where each sensor is."""
    d, structure = frame3d
    job = d / "place3d.toml"
    job.write_text('name = "place3d"\n' + structure + 'strains = "S.mtx"\nextensometers = [[101, 118], [103, 117]]\n'
                   + PLACE_3D + SIMULATION)
    out = tmp_path / "o"
    assert main(["place", str(job), "--json", "--out", str(out)]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["warnings"] == [] and (out / "layout.png").stat().st_size > 0
    table = pd.read_csv(out / "layout.csv")
    assert list(table["sensor"]) == res["sensors"] and len(res["positions"]) == 3
    by = {r["sensor"]: r for r in res["positions"]}
    for label, row in by.items():
        if label in ("strain:35", "strain:36"):           # extensometers 1 and 2 after the 34 operator rows
            assert row["source"] == f"extensometer {int(label[7:]) - 34}" and row["node"] in (101, 103)
            assert row["z"] == 0.0
        elif label.startswith("strain:"):
            assert row["source"] == f"operator row {label[7:]}" and row["node"] is None
        else:
            assert row["source"] == "dof" and row["node"] in (106, 108) and row["x"] == pytest.approx(
                {106: 3.0, 108: 4.0}[row["node"]])


def test_place_whose_figure_fails_still_writes_and_prints_its_layout(tmp_path, capsys, monkeypatch):
    import sensoropt.plots

    def broken(*args, **kw):
        raise RuntimeError("no font")
    monkeypatch.setattr(sensoropt.plots, "plot_layout", broken)
    job = tmp_path / "truss.toml"
    job.write_text('name = "truss"\ndt = 0.001953125\nforces = ["8:y"]\n[structure]\nmodel = "s17_truss"\n'
                   + PLACE_3D.replace("strain:35", "strain:21").replace("strain:36", "strain:26")
                   .replace("108", "8").replace("106", "6") + SIMULATION)
    assert main(["place", str(job), "--out", str(tmp_path / "o")]) == 0
    cap = capsys.readouterr()
    assert "best layout:" in cap.out and "figure layout.png not drawn (RuntimeError: no font)" in cap.err
    assert (tmp_path / "o" / "layout.csv").exists() and (tmp_path / "o" / "convergence.png").exists()
    assert not (tmp_path / "o" / "layout.png").exists()


def test_show_footbridge_draws_the_3d_structure(tmp_path, capsys):
    assert main(["show", "footbridge", "--out", str(tmp_path), "--json"]) == 0
    assert (tmp_path / "footbridge.png").stat().st_size > 0


def test_plot_structure_takes_forces_as_strings_and_draws_gauges(tmp_path):
    from core_akf.figures import plot_structure

    fig = plot_structure(s17_truss(), tmp_path / "s.png", forces=["8:y", (12, "y")], sensors=["strain:5", "acc:4:y"])
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert "load 1: node 8 (y)" in labels and "load 2: node 12 (y)" in labels


def test_estimate_on_a_model_without_strain_outputs(frame3d, tmp_path, capsys):
    """Only a displacement and an accelerometer on a model of one's own without extensometers:
    the summary crashed with `No objects to concatenate`."""
    d, structure = frame3d
    job = d / "nostrain.toml"
    job.write_text('name = "nostrain"\nsensors = ["disp:108:y", "acc:106:y"]\n' + structure + SIMULATION)
    assert main(["estimate", str(job), "--json", "--out", str(tmp_path / "o")]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["avg_strain_error"] is None and res["rms_force"]["108:y"] < 100.0
    ts = pd.read_csv(tmp_path / "o" / "timeseries.csv")
    assert set(ts["quantity"]) == {"force"}


def test_locate_over_a_folder_with_a_file_name_that_is_not_utf8_and_a_broken_file(tmp_path, capsys):
    """One event file that fails must not lose the events already located; a file name that is not
    valid UTF-8 is located like any other and shown with escapes."""
    for name in ("impact-0001.tdms", "impact-0002.tdms", "truss-impacts.toml"):
        shutil.copy(os.path.join(ROOT, "examples", "impacts", name), tmp_path)
    os.rename(tmp_path / "impact-0002.tdms", os.path.join(os.fsencode(tmp_path), b"impact-\xff.tdms"))
    (tmp_path / "impact-0000.tdms").write_bytes(b"not a TDMS file")
    job = tmp_path / "truss-impacts.toml"
    assert main(["locate", str(job), "--no-tune", "--no-plot", "--out", str(tmp_path / "o")]) == 0
    events = pd.read_csv(tmp_path / "o" / "events.csv")
    assert len(events) == 3
    assert events["file"].str.endswith("impact-\\xff.tdms").sum() == 1
    assert events["node"].notna().sum() == 2
    assert events.loc[events["file"].str.endswith("impact-0000.tdms"), "error"].iloc[0]


# ----------------------------------------------------------------- records that disagree with themselves
def _read(path, sensors=("acc:4:y", "acc:6:y"), **kw):
    from core_akf.io import Record

    record = Record(str(path), list(sensors), **kw)
    return record.read()


@pytest.mark.parametrize("extra", [-3, 5])
def test_hdf5_time_channel_shorter_or_longer_than_the_data(tmp_path, extra):
    h5py = pytest.importorskip("h5py")
    n = 100
    with h5py.File(tmp_path / "r.h5", "w") as f:
        f.create_dataset("time", data=np.arange(n + extra) * 1e-3)
        f.create_dataset("acc:4:y", data=np.zeros(n))
        f.create_dataset("acc:6:y", data=np.ones(n))
    with pytest.raises(ValueError, match=f"time channel 'time' has {n + extra} samples but the data channels have {n}"):
        _read(tmp_path / "r.h5")


@pytest.mark.parametrize("extra", [-3, 5])
def test_tdms_time_channel_shorter_or_longer_than_the_data(tmp_path, extra):
    nptdms = pytest.importorskip("nptdms")
    n = 100
    with nptdms.TdmsWriter(tmp_path / "r.tdms") as w:
        w.write_segment([nptdms.ChannelObject("g", "time", np.arange(n + extra) * 1e-3),
                         nptdms.ChannelObject("g", "acc:4:y", np.zeros(n)),
                         nptdms.ChannelObject("g", "acc:6:y", np.ones(n))])
    with pytest.raises(ValueError, match=f"has {n + extra} samples but the data channels have {n}"):
        _read(tmp_path / "r.tdms")


def test_csv_with_two_columns_of_the_same_name(tmp_path):
    (tmp_path / "r.csv").write_text("time,acc:4:y,acc:6:y,acc:4:y\n" + "".join(f"{k / 1e3},1,2,3\n" for k in range(10)))
    with pytest.raises(ValueError, match="column 'acc:4:y' appears twice \\(columns 2 and 4\\)"):
        _read(tmp_path / "r.csv")


def test_parquet_with_two_columns_of_the_same_name(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    t = pa.table([pa.array(np.arange(10) / 1e3), pa.array(np.ones(10)), pa.array(np.zeros(10))],
                 names=["time", "acc:4:y", "acc:4:y"])
    pq.write_table(t, tmp_path / "r.parquet")
    with pytest.raises(ValueError, match="column 'acc:4:y' appears twice"):
        _read(tmp_path / "r.parquet", sensors=("acc:4:y",))


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
        _read(tmp_path / "frf.uff")


# ----------------------------------------------------------------- output folders and resume
DAQ = os.path.join(ROOT, "examples", "daq")


def _measured_job(tmp_path, extra=""):
    """The S17 case-4 job on the SI CSV record, short chunks (20 ms), as a job file in ``tmp_path``."""
    text = open(os.path.join(DAQ, "s17-tdms.toml")).read()
    head = text[:text.index("[measurements]")]
    job = tmp_path / "job.toml"
    job.write_text(head + f'[measurements]\nfile = "{os.path.join(DAQ, "record-si.csv")}"\nchunk = 0.02\n' + extra)
    return job


def test_streamed_run_into_a_folder_whose_timeseries_is_a_link_to_a_file_elsewhere(tmp_path, capsys):
    elsewhere = tmp_path / "precious.csv"
    elsewhere.write_text("keep me\n")
    out = tmp_path / "out"
    out.mkdir()
    os.symlink(elsewhere, out / "timeseries.csv")
    assert main(["estimate", str(_measured_job(tmp_path)), "--no-plot", "--out", str(out)]) == 2
    assert "leads outside the output folder" in capsys.readouterr().err
    assert elsewhere.read_text() == "keep me\n"


def test_streamed_parquet_run_into_a_folder_whose_parts_are_a_link_to_a_folder_elsewhere(tmp_path, capsys):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "part-00000.parquet").write_text("not ours")
    out = tmp_path / "out"
    out.mkdir()
    os.symlink(elsewhere, out / "timeseries.parquet")
    job = _measured_job(tmp_path, '[output]\nformat = "parquet"\n')
    assert main(["estimate", str(job), "--no-plot", "--out", str(out)]) == 2
    assert "leads outside the output folder" in capsys.readouterr().err
    assert (elsewhere / "part-00000.parquet").read_text() == "not ours"


def test_figure_written_through_a_linked_subfolder_is_refused(tmp_path):
    from akf.outputs import OutputFolder
    from core_akf.outputs import write_csv

    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "out").mkdir()
    os.symlink(tmp_path / "elsewhere", tmp_path / "out" / "sub")
    with OutputFolder(str(tmp_path / "out")), pytest.raises(ValueError, match="leads outside the output folder"):
        write_csv(pd.DataFrame({"a": [1]}), str(tmp_path / "out" / "sub" / "x.csv"))
    assert list((tmp_path / "elsewhere").iterdir()) == []
    write_csv(pd.DataFrame({"a": [1]}), str(tmp_path / "out" / "sub" / "x.csv"))   # no run in it: the user's choice


@pytest.mark.parametrize("name", ["../escape", "a/b", ".hidden", "..\\\\x"])
def test_job_name_that_would_leave_the_output_folder(tmp_path, capsys, name, monkeypatch):
    monkeypatch.chdir(tmp_path)
    job = _measured_job(tmp_path)
    job.write_text(job.read_text().replace('name = "s17-tdms"', f'name = "{name}"'))
    assert main(["estimate", str(job), "--no-plot"]) == 2
    assert "must be a plain name" in capsys.readouterr().err
    assert not (tmp_path / "escape").exists() and not os.path.exists(tmp_path / "akf-out")


def test_outputs_are_created_with_the_users_umask(tmp_path, capsys):
    old = os.umask(0o022)
    try:
        assert main(["estimate", "--example", "s17-case4", "--duration", "0.2", "--out", str(tmp_path)]) == 0
    finally:
        os.umask(old)
    for name in ("timeseries.csv", "summary.csv", "estimate.png"):
        assert (tmp_path / name).stat().st_mode & 0o777 == 0o644, name


def test_resume_after_the_output_strains_or_the_format_or_the_filter_changed(tmp_path, capsys):
    from akf.estimate import estimate_job
    from akf.job import load_job
    from core_akf.filter import CheckpointError
    path = str(_measured_job(tmp_path))
    out = str(tmp_path / "o")
    estimate_job(load_job(path, "estimate"), out, plot=False, stop_after=2)
    for table, key, value, named in (("output", "strains", ["strain:1"], r"\[output\] strains"),
                                     ("output", "format", "parquet", r"\[output\] format"),
                                     ("filter", "stiffness_factor", 1.0, r"\[filter\] stiffness_factor"),
                                     ("filter", "steady", False, r"\[filter\] steady")):
        with pytest.raises(CheckpointError, match=named):
            estimate_job(load_job(path, "estimate", {f"{table}.{key}": value}), out, plot=False, resume=True)
    assert estimate_job(load_job(path, "estimate"), out, plot=False, resume=True).complete


def test_plain_rerun_into_an_interrupted_runs_folder(tmp_path, capsys):
    from akf.estimate import estimate_job
    from akf.job import load_job
    path = _measured_job(tmp_path)
    out = tmp_path / "o"
    estimate_job(load_job(str(path), "estimate"), str(out), plot=False, stop_after=2)
    size = (out / "timeseries.csv").stat().st_size
    assert main(["estimate", str(path), "--no-plot", "--out", str(out)]) == 2
    assert "holds an interrupted run" in capsys.readouterr().err and (out / "timeseries.csv").stat().st_size == size
    assert main(["estimate", str(path), "--no-plot", "--out", str(out), "--overwrite"]) == 0
    assert not (out / ".akf-resume.npz").exists()
    assert main(["estimate", str(path), "--no-plot", "--out", str(out)]) == 0       # a finished run: simply runs


@pytest.mark.parametrize("damage", ["truncated", "foreign", "nan"])
def test_resume_from_a_damaged_checkpoint(tmp_path, capsys, damage):
    from akf.estimate import estimate_job
    from akf.job import load_job
    path = _measured_job(tmp_path)
    out = tmp_path / "o"
    estimate_job(load_job(str(path), "estimate"), str(out), plot=False, stop_after=2)
    ck = out / ".akf-resume.npz"
    if damage == "truncated":
        ck.write_bytes(ck.read_bytes()[:200])
    elif damage == "foreign":
        np.savez(ck, something=np.ones(3))
        os.replace(str(ck) + ".npz" if os.path.exists(str(ck) + ".npz") else ck, ck)
    else:
        saved = dict(np.load(ck))
        saved["P"] = saved["P"] * np.nan
        with open(ck, "wb") as fh:
            np.savez(fh, **saved)
    assert main(["estimate", str(path), "--no-plot", "--out", str(out), "--resume"]) == 2
    err = capsys.readouterr().err
    assert {"truncated": "is truncated or not a checkpoint", "foreign": "is not a checkpoint of akf estimate",
            "nan": "NaN or infinite values in 'P'"}[damage] in err


def test_place_rerun_into_a_finished_runs_folder_runs_and_an_interrupted_one_asks(tmp_path, capsys):
    job = tmp_path / "truss.toml"
    job.write_text('name = "truss"\ndt = 0.001953125\nforces = ["8:y"]\n[structure]\nmodel = "s17_truss"\n'
                   + PLACE_3D.replace("strain:35", "strain:21").replace("strain:36", "strain:26")
                   .replace("108", "8").replace("106", "6") + SIMULATION)
    args = ["place", str(job), "--no-plot", "--json", "--out", str(tmp_path / "o")]
    assert main(args) == 0 and main(args) == 0
    ck = tmp_path / "o" / "checkpoint.json"
    data = json.loads(ck.read_text())
    data["finished"] = False
    ck.write_text(json.dumps(data))
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "interrupted run (generation 2 of 2)" in err and "with --resume to continue it, or with --overwrite" in err
    assert main(args + ["--overwrite"]) == 0


# ----------------------------------------------------------------- plausibility of a model of one's own
def _two_dof(**changes):
    from core_akf.models import from_matrices

    kw = dict(K=np.array([[2.0, -1.0], [-1.0, 1.0]]) * 1e6, M=np.eye(2) * 10.0, dofs=[(1, "x"), (2, "x")],
              nodes={1: (1.0, 0.0), 2: (2.0, 0.0)}) | changes
    return from_matrices(**kw)


def test_node_coordinates_in_mm_against_si_matrices():
    from core_akf.models.matrices import ModelWarning

    with pytest.warns(ModelWarning, match="are the coordinates in mm"):
        _two_dof(nodes={1: (1000.0, 0.0), 2: (2000.0, 0.0)}, extensometers=[(1, 2)])


def test_node_coordinates_in_m_give_no_unit_warning(recwarn):
    _two_dof(nodes={1: (1.0, 0.0), 2: (3.5, 0.0)})
    assert not [w for w in recwarn if "in mm" in str(w.message)]


def test_a_node_listed_twice(tmp_path):
    from core_akf.models.matrices import read_nodes

    with pytest.raises(ValueError, match="node 1 is listed twice"):
        _two_dof(nodes=[(1, (1.0, 0.0)), (2, (2.0, 0.0)), (1, (3.0, 0.0))])
    (tmp_path / "nodes.csv").write_text("node,x,y\n1,0,0\n2,1,0\n1,2,0\n")
    with pytest.raises(ValueError, match="node 1 is listed twice \\(data rows 1 and 3\\)"):
        read_nodes(tmp_path / "nodes.csv")


@pytest.mark.parametrize("sparse", [False, True])
def test_a_complex_stiffness_matrix(sparse):
    K = np.array([[2.0, -1.0], [-1.0, 1.0]]) * 1e6 * (1 + 0.04j)
    with pytest.raises(ValueError, match="K is complex"):
        _two_dof(K=scipy.sparse.csr_matrix(K) if sparse else K)


def test_damping_typed_as_a_percentage():
    from core_akf.structure import DampingWarning

    with pytest.raises(ValueError, match="damping is a ratio, not a percentage"):
        _two_dof(damping=2.0)
    with pytest.warns(DampingWarning, match="is it a percentage"):
        _two_dof(damping=0.5)


@pytest.mark.parametrize("n_modes", [2.5, "all", True, 0])
def test_n_modes_that_is_not_a_number_of_modes(n_modes):
    with pytest.raises(ValueError, match="n_modes must be a whole number of modes >= 1"):
        _two_dof(n_modes=n_modes)


def test_a_stiffness_factor_that_overflows(tmp_path, capsys):
    job = tmp_path / "j.toml"
    text = open(os.path.join(ROOT, "akf", "examples", "jobs", "s17-case4.toml")).read()
    job.write_text(text.replace("stiffness_factor = 1.05", "stiffness_factor = 1e308"))
    assert "1e308" in job.read_text()
    assert main(["estimate", str(job), "--no-plot", "--out", str(tmp_path / "o")]) == 2
    assert "stiffness_factor 1e+308 makes the stiffness matrix overflow" in capsys.readouterr().err


# ----------------------------------------------------------------- inputs a user types
CASE4 = os.path.join(ROOT, "akf", "examples", "jobs", "s17-case4.toml")


@pytest.mark.parametrize("encoding, message", [
    ("utf-16", "is UTF-16 text"), ("utf-16-le", "looks like UTF-16 text without a byte-order mark"),
    ("latin-1", "looks like Latin-1 / Windows-1252 text"), ("binary", "not a text file")])
def test_job_file_in_another_encoding(tmp_path, capsys, encoding, message):
    text = open(CASE4, encoding="utf-8").read().replace('name = "s17-case4"', 'name = "s17-café"')
    job = tmp_path / "job.toml"
    if encoding == "binary":
        job.write_bytes(bytes(range(256)))
    else:
        job.write_bytes(text.encode(encoding))
    assert main(["estimate", str(job), "--no-plot", "--out", str(tmp_path / "o")]) == 2
    assert message in capsys.readouterr().err


def test_job_file_with_a_utf8_byte_order_mark_is_read(tmp_path):
    from akf.job import load_job_file

    job = tmp_path / "job.toml"
    job.write_bytes(b"\xef\xbb\xbf" + open(CASE4, "rb").read())
    assert load_job_file(job)["name"] == "s17-case4"


@pytest.mark.parametrize("table", ["structure", "filter", "simulation"])
def test_a_top_level_key_after_a_table_header(tmp_path, capsys, table):
    text = open(CASE4).read()
    lines = [line for line in text.splitlines() if not line.startswith("dt =")]
    at = lines.index(f"[{table}]") + 1
    job = tmp_path / "job.toml"
    job.write_text("\n".join(lines[:at] + ["dt = 0.000244140625"] + lines[at:]) + "\n")
    assert main(["estimate", str(job), "--no-plot", "--out", str(tmp_path / "o")]) == 2
    assert f"'dt' sits in [{table}], but it is a top-level key" in capsys.readouterr().err


@pytest.mark.parametrize("unit, gauge_factor, message", [
    ("mV", 2.1, "is a voltage in 'mV', not a bridge ratio"),
    ("rad", None, "'rad' is an angle, not a strain"),
    ("deg", None, "'deg' is an angle, not a strain")])
def test_strain_units_that_are_not_strain(unit, gauge_factor, message):
    from core_akf.io.units import conversion

    with pytest.raises(ValueError, match=message):
        conversion(unit, "strain", "SG1", gauge_factor=gauge_factor)


@pytest.mark.parametrize("unit, scale", [("uE", 1e-6), ("µE", 1e-6), ("ue", 1e-6), ("με", 1e-6), ("mm/m", 1e-3)])
def test_common_strain_abbreviations(unit, scale):
    from core_akf.io.units import conversion

    assert conversion(unit, "strain", "SG1")(np.array([2.0]))[0] == pytest.approx(2 * scale)


@pytest.mark.parametrize("unit", ["g", "G", "gn"])
def test_gravity_as_daq_systems_write_it(unit):
    from core_akf.io.units import conversion

    assert conversion(unit, "acc", "ACC1")(np.array([1.0]))[0] == pytest.approx(9.80665)


def test_v_per_v_is_a_bridge_output():
    from core_akf.io.units import conversion

    c = conversion("V/V", "strain", "SG1", gauge_factor=2.0, bridge="full")
    assert c(np.array([1e-3]))[0] == pytest.approx(0.5e-3)


@pytest.mark.parametrize("address, message", [
    ("http://127.0.0.1:8787/status", "is a web address"), ("tcp://scheduler-host", "needs a host and a port"),
    ("tls://scheduler-host:8786", "no client certificate is configured"), ("ftp://h:21", "unknown address scheme")])
def test_scheduler_addresses_that_cannot_be_one(address, message):
    pytest.importorskip("distributed")
    from akf.parallel import check_scheduler

    with pytest.raises(ValueError, match=message):
        check_scheduler(address)


def test_scheduler_port_that_accepts_and_says_nothing_is_not_a_hang():
    pytest.importorskip("distributed")
    import socket
    import time

    from akf.parallel import probe_scheduler

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(4)
    t0 = time.perf_counter()
    try:
        with pytest.raises(ValueError, match="did not answer as a dask scheduler within 1 s"):
            probe_scheduler(f"tcp://127.0.0.1:{server.getsockname()[1]}", timeout=1.0)
    finally:
        server.close()
    assert time.perf_counter() - t0 < 30


def test_population_that_does_not_fit_in_memory(tmp_path, capsys):
    assert main(["place", "--example", "th-case5", "--population", "1000000000", "--out", str(tmp_path)]) == 2
    assert "a GA of population 1000000000 over 100 generations" in capsys.readouterr().err


def test_diversity_of_a_large_population_is_sampled():
    from sensoropt.encoding import DIVERSITY_SAMPLE, make_encoding

    enc = make_encoding(s17_truss(), kinds=("strain",), n_sensors=3)
    rng = np.random.default_rng(0)
    pop = [enc.random_layout(rng) for _ in range(DIVERSITY_SAMPLE + 300)]
    assert enc.diversity(pop) == pytest.approx(enc.diversity([pop[i] for i in np.linspace(
        0, len(pop) - 1, DIVERSITY_SAMPLE).astype(int)]))


# ----------------------------------------------------------------- the first week's frictions
def test_show_a_job_file_with_a_model_of_ones_own(frame3d, tmp_path, capsys):
    d, structure = frame3d
    job = d / "show.toml"
    job.write_text('name = "mine"\nsensors = ["strain:35", "acc:108:y"]\n' + structure
                   + 'strains = "S.mtx"\nextensometers = [[101, 118]]\n')
    assert main(["show", str(job), "--out", str(tmp_path), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["node_ids"] == [101, 118] and info["strain_outputs"] == 35 and info["dofs"] == 33
    assert info["strains"][0] == {"output": "strain:1", "is": "strain operator row", "nodes": None, "row": 1}
    assert info["strains"][34] == {"output": "strain:35", "is": "extensometer", "nodes": [101, 118], "row": None}
    assert info["frequencies_hz"][0] == pytest.approx(s17_truss().frequencies(1)[0], rel=1e-10)
    assert (tmp_path / "mine.png").stat().st_size > 0
    assert main(["show", str(job), "--no-plot"]) == 0
    assert "strain:35  extensometer 101-118" in capsys.readouterr().out


@pytest.mark.parametrize("command, example", [("estimate", "s17-case4"), ("place", "th-case5"),
                                              ("locate", "imp-truss-case1")])
def test_print_job_gives_a_template_that_runs(tmp_path, capsys, command, example):
    from akf.job import load_job

    assert main([command, "--example", example, "--print-job"]) == 0
    text = capsys.readouterr().out
    (tmp_path / "mine.toml").write_text(text)
    assert load_job(str(tmp_path / "mine.toml"), command).name == example
    assert text.startswith(f"# {example}")


def test_print_job_without_an_example(capsys):
    assert main(["estimate", "--print-job"]) == 2
    assert "give --example NAME" in capsys.readouterr().err


def test_candidate_set_is_exported():
    import sensoropt

    assert sensoropt.CandidateSet is sensoropt.encoding.CandidateSet and "CandidateSet" in sensoropt.__all__


def test_figures_of_a_measured_record_include_every_sensor_in_microstrain(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["estimate", str(_measured_job(tmp_path)), "--out", str(out), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert {"figure", "sensors_figure"} <= set(res["files"]) and (out / "sensors.png").stat().st_size > 0


def test_sensor_figure_labels_strain_in_microstrain_and_draws_every_sensor(tmp_path):
    from akf.figures import plot_sensors
    from core_akf.sensors import as_layout

    sensors = as_layout([f"strain:{m}" for m in range(1, 15)] + ["acc:4:y"])
    t = np.arange(50) * 1e-3
    y = np.ones((50, 15)) * 1e-6
    plot_sensors(t, y, y, sensors, str(tmp_path / "s.png"), "t")
    import matplotlib.image

    assert matplotlib.image.imread(tmp_path / "s.png").shape[0] > 500


def test_error_panel_at_a_thousand_outputs_ranks_the_worst(tmp_path, monkeypatch):
    import akf.figures as plots

    seen = {}
    original = plots._strain_error_panel

    def spy(ax, errors):
        original(ax, errors)
        seen["labels"] = [t.get_text() for t in ax.get_yticklabels()]
        seen["bars"] = len(ax.patches)
    monkeypatch.setattr(plots, "_strain_error_panel", spy)
    errors = {f"strain:{k}": k * 1e-9 for k in range(1, 1101)}
    plots.plot_estimate(np.arange(10.0), np.zeros((10, 1)), ["8:y"], str(tmp_path / "e.png"), "t",
                        reference=np.ones((10, 1)), strain_errors=errors)
    assert seen["bars"] == plots.WORST and seen["labels"][-1] == "strain:1100"


def test_flagship_locate_example_does_not_warn_about_a_bound_that_does_not_matter(tmp_path, capsys):
    """imp-truss-case1 tunes the model error to its lower bound: its filter model is exact, and a
    level 3 decades lower gives the same AD error, so it is settled, not a warning."""
    assert main(["locate", "--example", "imp-truss-case1", "--json", "--no-plot", "--out", str(tmp_path)]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["identified"] == 14 and not any("search bound" in w for w in d["warnings"])



def test_quiet_and_verbose_before_or_after_the_command(tmp_path, capsys):
    import logging

    assert main(["-q", "show", "s17_truss", "--no-plot"]) == 0
    assert logging.getLogger("akf").level == logging.WARNING
    assert main(["show", "s17_truss", "--no-plot", "-v"]) == 0
    assert logging.getLogger("akf").level == logging.DEBUG
    assert main(["show", "s17_truss", "--no-plot"]) == 0
    assert logging.getLogger("akf").level == logging.INFO and "TQDM_DISABLE" not in os.environ


def test_locate_events_log_instead_of_printing(tmp_path, caplog, capsys):
    """Used from Python, locate_events reports through the `akf` logger, not print."""
    import logging

    from akf.job import load_job
    from akf.locating import locate_events

    for name in ("impact-0001.tdms", "truss-impacts.toml"):
        shutil.copy(os.path.join(ROOT, "examples", "impacts", name), tmp_path)
    job = load_job(str(tmp_path / "truss-impacts.toml"), "locate")
    logger = logging.getLogger("akf")
    logger.propagate = True
    with caplog.at_level(logging.INFO, logger="akf"):
        locate_events(job, str(tmp_path / "o"), tune=False, plot=False, progress=True)
    assert any("impact-0001: node 14" in r.getMessage() for r in caplog.records)


def test_place_notes_a_default_force_increment_far_from_kilonewton_loads():
    from akf.placement import force_increment_notes

    t = np.arange(2000) * 1e-3
    kn = np.column_stack([5e3 * np.sin(2 * np.pi * 3 * t)])
    assert "set force_increment_cov = 4.4" in force_increment_notes(kn)[0]
    thesis_like = np.column_stack([50 * np.sin(2 * np.pi * 3 * t) + np.random.default_rng(0).normal(0, 0.7, t.size)])
    assert force_increment_notes(thesis_like) == []


def test_citation_and_license_agree_with_the_package():
    yaml = pytest.importorskip("yaml")
    try:
        import tomllib
    except ModuleNotFoundError:  # Python < 3.11
        import tomli as tomllib

    meta = tomllib.loads(open(os.path.join(ROOT, "pyproject.toml")).read())["project"]
    cff = yaml.safe_load(open(os.path.join(ROOT, "CITATION.cff")))
    assert cff["version"] == meta["version"] and cff["license"] == meta["license"]["text"] == "MIT"
    assert open(os.path.join(ROOT, "LICENSE")).read().startswith("MIT License")


def test_an_unexpected_error_is_one_line_not_a_traceback(tmp_path, capsys, monkeypatch):
    import akf.commands.show as show

    def broken(target):
        raise ZeroDivisionError("division by zero")
    monkeypatch.setattr(show, "_structure_of", broken)
    assert main(["show", "s17_truss", "--no-plot"]) == 1
    err = capsys.readouterr().err
    assert "internal error in broken: ZeroDivisionError" in err and "Traceback" not in err
    assert main(["show", "s17_truss", "--no-plot", "-v"]) == 1
    assert "Traceback" in capsys.readouterr().err


def test_a_model_whose_every_dof_is_fixed():
    with pytest.raises(ValueError, match="every DOF of the model is fixed"):
        _two_dof(fixed=[1, 2])


def test_an_extensometer_that_is_not_a_pair():
    with pytest.raises(ValueError, match="extensometer 1 is .*: an extensometer is a pair of node ids"):
        _two_dof(extensometers=[(1, 2, 1)])


def test_locate_over_a_folder_where_no_file_can_be_located(tmp_path, capsys):
    shutil.copy(os.path.join(ROOT, "examples", "impacts", "impact-0001.tdms"), tmp_path)
    text = open(os.path.join(ROOT, "examples", "impacts", "truss-impacts.toml")).read()
    (tmp_path / "job.toml").write_text(text.replace("n_ad = 4", "n_ad = 40"))
    assert main(["locate", str(tmp_path / "job.toml"), "--no-plot", "--out", str(tmp_path / "o")]) == 2
    assert "no impact located in any of the 1 file(s)" in capsys.readouterr().err
    assert (tmp_path / "o" / "events.csv").exists()


def test_hdf5_channels_that_do_not_hold_numbers_or_are_not_1d(tmp_path):
    h5py = pytest.importorskip("h5py")
    with h5py.File(tmp_path / "s.h5", "w") as f:
        f.create_dataset("time", data=np.arange(20) * 1e-3)
        f.create_dataset("acc:4:y", data=np.array([b"x"] * 20))
        f.create_dataset("acc:6:y", data=np.zeros(20))
    with pytest.raises(ValueError, match="channel 'acc:4:y' does not hold numbers"):
        _read(tmp_path / "s.h5")
    with h5py.File(tmp_path / "m.h5", "w") as f:
        f.attrs["dt"] = 1e-3
        f.create_dataset("acc:4:y", data=np.zeros((20, 2)))
    with pytest.raises(ValueError, match="a channel is a 1-D dataset"):
        _read(tmp_path / "m.h5")


def test_tdms_channel_with_a_nan_sample(tmp_path):
    nptdms = pytest.importorskip("nptdms")
    y = np.zeros(50)
    y[17] = np.nan
    with nptdms.TdmsWriter(tmp_path / "r.tdms") as w:
        w.write_segment([nptdms.ChannelObject("g", "acc:4:y", y, properties={"wf_increment": 1e-3}),
                         nptdms.ChannelObject("g", "acc:6:y", np.zeros(50), properties={"wf_increment": 1e-3})])
    with pytest.raises(ValueError, match="channel 'acc:4:y' has a missing/NaN or infinite sample at sample 18"):
        _read(tmp_path / "r.tdms")


def test_csv_separated_by_semicolons(tmp_path):
    (tmp_path / "r.csv").write_text("time;acc:4:y\n0;1\n0,001;2\n")
    with pytest.raises(ValueError, match="the header looks ';'-separated"):
        _read(tmp_path / "r.csv", sensors=("acc:4:y",))


def test_locate_example_honours_a_changed_locate_key(tmp_path, capsys, monkeypatch):
    """akf locate --example runs the example's job through run_locate_job: a [locate] key of the
    job (here tune = false, and fewer role splits) is honoured, and the truth is shown beside."""
    import akf.examples.impact as impact

    original = impact.load_example

    def changed(name, command=None):
        job = original(name, command)
        job["locate"] |= {"tune": False, "max_splits": 5}
        return job
    monkeypatch.setattr(impact, "load_example", changed)
    assert main(["locate", "--example", "imp-truss-case1", "--json", "--no-plot", "--out", str(tmp_path)]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d.get("ad_error_after_tuning") is None and d["true_node"] == 14 and d["identified"] == 14
    assert pd.read_csv(tmp_path / "ranking.csv")["n_splits"].max() == 5


@pytest.mark.parametrize("command", [["place", "--example", "th-case5"], ["locate", "--example", "imp-truss-case1"],
                                     ["estimate", "--example", "s17-case4"]])
def test_a_negative_seed(command, capsys):
    with pytest.raises(SystemExit) as stop:
        main(command + ["--seed", "-5"])
    assert stop.value.code == 2 and "a seed is a whole number >= 0" in capsys.readouterr().err


def test_ga_engine_refuses_a_negative_seed():
    from core_akf.evolution import GeneticAlgorithm

    with pytest.raises(ValueError, match="seed must be a whole number >= 0"):
        GeneticAlgorithm(None, None, generations=1, seed=-1)


def test_a_local_cluster_of_hundreds_of_workers_on_a_small_machine():
    pytest.importorskip("distributed")
    from akf.parallel import check_scheduler

    with pytest.raises(ValueError, match="would start 100000 worker processes"):
        check_scheduler("local:100000")


def test_matrices_model_without_its_files(tmp_path):
    from akf.job import build_structure

    with pytest.raises(ValueError, match='model = "matrices" needs K, M'):
        build_structure({"model": "matrices", "dofs": "d.csv", "nodes": "n.csv"})


def test_a_free_dof_without_mass():
    with pytest.raises(ValueError, match="1 free DOF\\(s\\) have no mass \\(2:x\\)"):
        _two_dof(M=np.diag([10.0, 0.0]))


# ----------------------------------------------------------------- one name per concept (issue 20, item 5)
def test_old_key_names_are_read_under_the_new_ones_with_a_warning():
    from akf.schema import parse_job

    job = {"dt": 0.001, "sensors": ["strain:5"], "forces": ["4:y"], "structure": {"model": "s17_truss"},
           "simulation": {"duration": 0.5}, "filter": {"reduce_modes": 12}}
    with pytest.warns(FutureWarning, match=r"\[filter\] reduce_modes is now called n_modes"):
        assert parse_job(job, "estimate").filter.n_modes == 12
    locate = {"dt": 0.001, "sensors": ["strain:5", "strain:9"], "structure": {"model": "s17_truss"},
              "locate": {"n_ad": 1, "direction": "y", "covariances": {"model_error": 1e-16, "force_increment": 1e6,
                                                                      "noise": {"strain": 1e-13}}},
              "simulation": {"duration": 0.5}, "forces": ["4:y"]}
    with pytest.warns(FutureWarning, match=r"\[locate.covariances\] model_error is now called model_error_cov"):
        c = parse_job(locate, "locate").locate.covariances
    assert (c.model_error_cov, c.force_increment_cov, c.noise_cov) == (1e-16, 1e6, {"strain": 1e-13})
    job["filter"] = {"reduce_modes": 12, "n_modes": 10}
    with pytest.raises(ValueError, match="has both 'reduce_modes' and 'n_modes'"):
        parse_job(job, "estimate")
