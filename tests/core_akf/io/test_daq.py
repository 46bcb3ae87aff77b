"""Measured data: readers of each format, channel maps with units, records in many files, the
streamed estimate (chunk by chunk, resumable) against the one-piece estimate."""
import json
import os
import tracemalloc
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from helpers import ROOT, run_estimate

from akf.cli import main
from akf.job import load_job_file
from core_akf.checks import AKFInputError
from core_akf.diagnostics import RunningDiagnostics
from core_akf.filter import CheckpointError, Estimator, estimate
from core_akf.filter.results import force_statistics, sensor_diagnostics
from core_akf.io import Reader, Record, Timing, conversion, register_reader
from core_akf.io import readers as readers_module
from core_akf.models import s17_truss

DAQ = ROOT / "examples" / "daq"
FORMATS = ["record.csv", "record.parquet", "record.tdms", "record.uff", "record.h5"]
SENSORS = ["acc:4:y", "acc:6:y", "acc:8:y", "acc:12:y", "acc:6:x", "strain:5", "strain:9", "strain:13", "strain:26"]
FORCES = ["4:y", "6:y", "8:y", "12:y"]
KW = dict(model_error_cov=1e-16, force_increment_cov=1e5, noise_cov={"acc": 0.2, "strain": 4e-14})


def _job(file, **measurements):
    """The sample job (examples/daq/s17-tdms.toml) reading ``file`` with ``measurements`` keys."""
    job = load_job_file(DAQ / "s17-tdms.toml")
    job["measurements"] = {"file": str(file)} | measurements
    return job


def _channel_map(name):
    """The TDMS job's channel map; CSV and Parquet record no units, so the job gives them all."""
    meas = load_job_file(DAQ / "s17-tdms.toml")["measurements"]
    meas.pop("file")
    if name.endswith((".csv", ".parquet")):
        meas["units"] = {"ACC_4Y": "g", "ACC_6Y": "g", "ACC_8Y": "mm/s^2", "ACC_12Y": "m/s^2", "ACC_6X": "g",
                         "SG5": "microstrain", "SG9": "µε", "SG13": "mV/V", "SG26": "microstrain"}
    return meas


def _forces(out):
    ts = pd.read_csv(out / "timeseries.csv") if (out / "timeseries.csv").exists() else pd.read_parquet(
        out / "timeseries.parquet")
    f = ts[ts.quantity == "force"]
    return np.column_stack([f[f.channel == c]["estimated"].to_numpy() for c in FORCES]), ts


@pytest.fixture(scope="module")
def si_forces(tmp_path_factory):
    """Forces estimated from the SI reference (columns named like the sensors), streamed."""
    out = tmp_path_factory.mktemp("si")
    run_estimate(_job(DAQ / "record-si.csv"), str(out), plot=False)
    return _forces(out)[0]


@pytest.mark.parametrize("name", FORMATS)
def test_each_format_with_channel_map_gives_the_si_estimate(name, tmp_path, si_forces):
    """Round trip: simulated SI measurements -> a DAQ file (channel names, microstrain, g, mm/s^2,
    mV/V of a quarter bridge, an inverted accelerometer), written by the format's library ->
    read with the channel map -> the same forces as from the SI data, to 1e-12."""
    res = run_estimate(_job(DAQ / name, **_channel_map(name)), str(tmp_path), plot=False)
    assert res.complete and res.metrics["n_steps"] == 1024
    forces, _ = _forces(tmp_path)
    np.testing.assert_allclose(forces, si_forces, rtol=0, atol=1e-12 * np.max(np.abs(si_forces)))


def test_streamed_estimate_equals_the_one_piece_estimate(tmp_path, si_forces):
    """The SI record streamed in chunks of 100 steps against core_akf.filter.estimate on the whole array."""
    df = pd.read_csv(DAQ / "record-si.csv")
    ref = estimate(s17_truss().scaled(1.05), SENSORS, FORCES, df[SENSORS].to_numpy(), df.time[1], **KW)
    np.testing.assert_allclose(si_forces, ref.forces, rtol=0, atol=1e-12 * np.max(np.abs(ref.forces)))
    run_estimate(_job(DAQ / "record-si.csv", chunk=100 * df.time[1]), str(tmp_path), plot=False)
    np.testing.assert_allclose(_forces(tmp_path)[0], ref.forces, rtol=0, atol=1e-12 * np.max(np.abs(ref.forces)))


def _split_tdms(folder, pieces=10, gap=0):
    """record.tdms cut into ``pieces`` TDMS files (npTDMS), named out of time order."""
    from nptdms import ChannelObject, TdmsFile, TdmsWriter

    folder.mkdir()
    src = TdmsFile.read(DAQ / "record.tdms")
    chans = src["DAQ"].channels()
    n, dt = len(chans[0]), chans[0].properties["wf_increment"]
    edges = np.linspace(0, n, pieces + 1).astype(int)
    for i, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
        start = a + (gap if i == pieces // 2 else 0)
        with TdmsWriter(folder / f"part-{(7 * i) % pieces:02d}.tdms") as w:
            w.write_segment([ChannelObject("DAQ", c.name, c[start:b], properties={
                "unit_string": c.properties["unit_string"], "wf_increment": dt, "wf_start_offset": start * dt})
                for c in chans])


def test_record_split_over_ten_files_equals_the_joined_record(tmp_path, capsys):
    """akf estimate on a folder of 10 TDMS pieces (names out of time order, chunks crossing the
    file boundaries) gives exactly the forces of the joined file."""
    _split_tdms(tmp_path / "pieces")
    meas = _channel_map("record.tdms")
    for name, file in (("joined", DAQ / "record.tdms"), ("split", tmp_path / "pieces")):
        job = _job(file, chunk=0.0125, **meas)
        job["name"] = name
        with open(tmp_path / f"{name}.toml", "w") as fh:
            fh.write(_toml(job))
        assert main(["estimate", str(tmp_path / f"{name}.toml"), "--out", str(tmp_path / name), "--json", "--no-plot"]) == 0
        assert json.loads(capsys.readouterr().out)["n_steps"] == 1024
    joined, split = _forces(tmp_path / "joined")[0], _forces(tmp_path / "split")[0]
    np.testing.assert_array_equal(split, joined)


def _toml(job):
    """A job dict as TOML (the few value types a job has)."""
    def value(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, dict):
            return "{" + ", ".join(f"{json.dumps(k)} = {value(x)}" for k, x in v.items()) + "}"
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v)
    top = [f"{k} = {value(v)}" for k, v in job.items() if not isinstance(v, dict)]
    tables = [f"[{k}]\n" + "\n".join(f"{json.dumps(a)} = {value(b)}" for a, b in v.items())
              for k, v in job.items() if isinstance(v, dict)]
    return "\n".join(top) + "\n\n" + "\n\n".join(tables) + "\n"


@pytest.mark.parametrize("gap, message", [(-2, "an overlap of 0.000488281 s \\(2 steps\\)")])
def test_an_overlap_between_files_is_refused(tmp_path, gap, message):
    _split_tdms(tmp_path / "pieces", gap=gap)
    with pytest.raises(AKFInputError, match=message):
        Record(tmp_path / "pieces", SENSORS, **{k: v for k, v in _channel_map("record.tdms").items()})


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_resumed_run_continues_from_the_last_written_chunk(tmp_path, fmt):
    """Stopped after 3 chunks, then resumed: the same time series and summary, bit for bit, as a
    run without a stop."""
    job = _job(DAQ / "record.tdms", chunk=0.02, **_channel_map("record.tdms"))
    job["output"]["format"] = fmt
    whole = tmp_path / "whole"
    run_estimate(job, str(whole), plot=False)
    part = tmp_path / "part"
    first = run_estimate(job, str(part), plot=False, stop_after=3)
    assert not first.complete and (part / ".akf-resume.npz").exists()
    res = run_estimate(job, str(part), resume=True, plot=False)
    assert res.complete and res.resumed_at == 3 * 82 and not (part / ".akf-resume.npz").exists()
    a, ta = _forces(whole)
    b, tb = _forces(part)
    assert len(ta) == len(tb)
    np.testing.assert_array_equal(b, a)
    pd.testing.assert_frame_equal(pd.read_csv(part / "summary.csv"), pd.read_csv(whole / "summary.csv"))
    with pytest.raises(AKFInputError, match="nothing to resume"):
        run_estimate(job, str(part), resume=True, plot=False)
    run_estimate(job, str(part), plot=False, stop_after=1)
    other = _job(DAQ / "record.tdms", chunk=0.02, **_channel_map("record.tdms") | {"invert": []})
    with pytest.raises(CheckpointError, match="the job changed .*\\(\\[measurements\\] invert"):
        run_estimate(other, str(part), resume=True, plot=False)


def test_units_are_converted_by_pint_with_daq_conventions():
    one = np.array([1.0])
    assert conversion("microstrain", "strain", "c")(one)[0] == pytest.approx(1e-6)
    assert conversion("µε", "strain", "c")(one)[0] == pytest.approx(1e-6)
    assert conversion("um/m", "strain", "c")(one)[0] == pytest.approx(1e-6)
    assert conversion("g", "acc", "c")(one)[0] == pytest.approx(9.80665)      # gravity, not gram
    assert conversion("mg", "acc", "c")(one)[0] == pytest.approx(9.80665e-3)
    assert conversion("mm/s^2", "acc", "c")(one)[0] == pytest.approx(1e-3)
    assert conversion("in/s", "vel", "c")(one)[0] == pytest.approx(0.0254)
    assert conversion("mm", "disp", "c")(one)[0] == pytest.approx(1e-3)
    r = 0.5    # mV/V
    assert conversion("mV/V", "strain", "c", 2.0, "full")(np.array([r]))[0] == pytest.approx(r * 1e-3 / 2.0)
    assert conversion("mV/V", "strain", "c", 2.0, "half")(np.array([r]))[0] == pytest.approx(2 * r * 1e-3 / 2.0)
    assert conversion("mV/V", "strain", "c", 2.0)(np.array([r]))[0] == pytest.approx(4 * 5e-4 / (2.0 * (1 + 1e-3)))


BASE_MAP = load_job_file(DAQ / "s17-tdms.toml")["measurements"]["channels"]


@pytest.mark.parametrize("kw, message", [
    (dict(units={"SG5": "bananas"}), "channel 'SG5 .*unknown unit 'bananas'"),
    (dict(units={"SG5": "furlongs"}), "unit 'furlongs' is not a unit of strain"),
    (dict(units={"SG5": "m/s^2"}), "unit 'm/s\\^2' is not a unit of strain"),
    (dict(units={"ACC_4Y": "microstrain"}), "not a unit of acc"),
    (dict(gauge_factor=None), "bridge output in 'mV/V': give its gauge_factor"),
    (dict(gauge_factor={"SG13": 2.1, "SG5": 2.0}), "SG5.*applies to a bridge output"),
    (dict(bridge="diagonal"), "unknown bridge type 'diagonal'"),
    (dict(channels=BASE_MAP | {"SG9": "strain:5"}), "sensor 'strain:5' is mapped twice"),
    (dict(channels={k: v for k, v in BASE_MAP.items() if k != "SG26"}), "\\['strain:26'\\] have no channel"),
    (dict(channels=BASE_MAP | {"SG26": "strain:77"}), "'strain:77', which is not among the job's sensors"),
    (dict(channels={k: v for k, v in BASE_MAP.items() if k != "SG5"} | {"NOPE": "strain:5"}),
     "no channel\\(s\\) \\['NOPE'\\]"),
    (dict(invert=["SG99"]), "\\['SG99'\\] that are not mapped to a sensor"),
    (dict(remove_offset=-1.0), "remove_offset must be"),
])
def test_channel_map_errors(kw, message):
    meas = _channel_map("record.tdms") | kw
    with pytest.raises(AKFInputError, match=message):
        Record(DAQ / "record.tdms", SENSORS, **{k: v for k, v in meas.items() if v is not None})


def test_missing_format_library_names_the_extra(monkeypatch):
    import importlib

    real = importlib.import_module
    monkeypatch.setattr(importlib, "import_module",
                        lambda name, *a: (_ for _ in ()).throw(ImportError(name)) if name == "nptdms" else real(name, *a))
    with pytest.raises(AKFInputError, match=r'python -m pip install .*"') as info:
        Record(DAQ / "record.tdms", SENSORS, **_channel_map("record.tdms"))
    # the hint was pip install "akf-toolkit[tdms]", which fails (the package is not on the index):
    # it names the source folder, or the path pip installed from
    target = str(info.value).split('"')[1]
    assert target.endswith("[tdms]")
    folder = target[:-len("[tdms]")]
    assert folder == "akf-toolkit" or (Path(folder) / "pyproject.toml").exists() or Path(folder).exists()


def test_unknown_extension_and_mixed_formats(tmp_path):
    (tmp_path / "x.xyz").write_text("1")
    with pytest.raises(AKFInputError, match="no reader for extension '.xyz'"):
        Record(tmp_path / "x.xyz", ["strain:5"])
    with pytest.raises(AKFInputError, match="different formats"):
        Record([DAQ / "record.csv", DAQ / "record.tdms"], SENSORS)


def test_offset_removal_and_sign_flip(tmp_path):
    df = pd.read_csv(DAQ / "record-si.csv")
    shifted = df.copy()
    shifted["strain:5"] += 35e-6            # zero drift of a gauge
    shifted["acc:6:x"] *= -1.0
    shifted.to_csv(tmp_path / "d.csv", index=False, float_format="%.17g")
    rec = Record(tmp_path / "d.csv", SENSORS, invert=["acc:6:x"], remove_offset=0.02)
    _, Y = rec.read(size=100)
    n0 = int(round(0.02 / df.time[1]))
    expected = df[SENSORS].to_numpy() - df[SENSORS].to_numpy()[:n0].mean(axis=0)
    np.testing.assert_allclose(Y, expected, rtol=0, atol=1e-12)
    _, Y = Record(tmp_path / "d.csv", SENSORS, invert=["acc:6:x"], remove_offset=True).read()
    np.testing.assert_allclose(Y.mean(axis=0), 0, atol=1e-13)


def test_a_reader_of_ones_own_format_is_registered():
    """The reader interface is open: a class for a text format of one's own."""
    @register_reader
    class SpaceSeparated(Reader):
        format, extensions = "ssv-test", (".ssv",)

        def __init__(self, path, time_column="time", group=None):
            super().__init__(path, time_column, group)
            self.data = np.loadtxt(self.path, skiprows=1)
            self.names = open(self.path).readline().split()[1:]

        def channels(self):
            return self.names

        def timing(self):
            return Timing(self.data[0, 0], self.data[1, 0] - self.data[0, 0], self.data.shape[0])

        def chunks(self, channels, size):
            cols = [self.names.index(c) + 1 for c in channels]
            for a in range(0, self.data.shape[0], size):
                yield self.data[a:a + size, cols]
    try:
        import tempfile
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "r.ssv")
            with open(path, "w") as fh:
                fh.write("t SG5\n" + "".join(f"{k * 1e-3} {np.sin(k)}\n" for k in range(50)))
            rec = Record(path, ["strain:5"], channels={"SG5": "strain:5"}, units={"SG5": "microstrain"})
            _, Y = rec.read(size=7)
            np.testing.assert_allclose(Y[:, 0], 1e-6 * np.sin(np.arange(50)))
    finally:
        readers_module._READERS.pop("ssv-test")


@pytest.mark.parametrize("steady", [True, False])
def test_estimator_in_chunks_equals_one_piece_and_restores(steady):
    df = pd.read_csv(DAQ / "record-si.csv")
    Y, dt = df[SENSORS].to_numpy(), df.time[1]
    model = s17_truss().scaled(1.05)
    ref = estimate(model, SENSORS, FORCES, Y, dt, steady=steady, **KW)
    est = Estimator(model, SENSORS, FORCES, dt, steady=steady, **KW)
    sizes = [1, 5, 300, 64, 2, 400, 252]
    edges = np.cumsum([0] + sizes)
    parts, diag = [], RunningDiagnostics(Y.shape[0])
    for a, b in zip(edges[:-1], edges[1:]):
        if a == 372:       # carry the filter over into a new object, as a resumed run does
            est = Estimator(model, SENSORS, FORCES, dt, steady=steady, **KW).restore(est.state())
        parts.append(est.update(Y[a:b]))
        diag.update(parts[-1])
    scale = np.max(np.abs(ref.forces))
    np.testing.assert_allclose(np.vstack([p.forces for p in parts]), ref.forces, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(np.concatenate([p.time for p in parts]), ref.time, rtol=0, atol=1e-12)
    for one, run in zip(sensor_diagnostics(ref), diag.sensors()):
        assert one["channel"] == run["channel"]
        for k in ("measured_rms", "innovation_rms", "consistency", "whiteness", "lag1_autocorrelation"):
            assert run[k] == pytest.approx(one[k], rel=1e-9, abs=1e-12)
    for one, run in zip(force_statistics(ref), diag.forces()):
        assert run["peak"] == pytest.approx(one["peak"], rel=1e-9) and run["time_of_peak"] == one["time_of_peak"]
    other = Estimator(model, SENSORS, FORCES[:3], dt, steady=steady, **KW)
    with pytest.raises(CheckpointError, match="another filter"):
        other.restore(est.state())


def test_streaming_memory_does_not_grow_with_the_record():
    """Peak memory traced while filtering 10 and 40 chunks of a synthetic record: the same."""
    model = s17_truss()
    rng = np.random.default_rng(0)
    scale = np.array([10.0] * 5 + [1e-5] * 4)

    def peak(n_chunks):
        est = Estimator(model, SENSORS, FORCES, 2.0 ** -12, **KW)
        diag = RunningDiagnostics(n_chunks * 4096)
        tracemalloc.start()
        for _ in range(n_chunks):
            diag.update(est.update(rng.normal(size=(4096, 9)) * scale))
        top = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        return top
    short, long = peak(10), peak(40)
    assert long < 1.1 * short, (short, long)


def test_locate_over_a_folder_of_impact_records(tmp_path, capsys):
    """akf locate on a folder of TDMS impact records: one row per file in events.csv (the three
    simulated impacts found at their nodes), a row with the reason for a file that cannot be
    used, the figure, and each event's ranking."""
    import shutil

    from nptdms import ChannelObject, TdmsFile, TdmsWriter

    events = tmp_path / "events"
    shutil.copytree(DAQ.parent / "impacts", events, ignore=shutil.ignore_patterns("*.py", "*.toml"))
    src = TdmsFile.read(events / "impact-0001.tdms")
    with TdmsWriter(events / "impact-0004.tdms") as w:      # a dead gauge: constant
        w.write_segment([ChannelObject("DAQ", c.name, c[:] * (0 if c.name == "SG9" else 1), properties=c.properties)
                         for c in src["DAQ"].channels()])
    job = load_job_file(DAQ.parent / "impacts" / "truss-impacts.toml")
    job["measurements"]["file"] = str(events)
    job["locate"]["max_splits"] = 6
    (tmp_path / "job.toml").write_text(_toml(job))
    assert main(["locate", str(tmp_path / "job.toml"), "--no-tune", "--json", "--out", str(tmp_path / "out")]) == 0
    out = json.loads(capsys.readouterr().out)
    table = pd.read_csv(out["files"]["events"])
    assert list(table.columns[:7]) == ["file", "node", "direction", "confidence", "margin", "peak_force_N",
                                       "time_of_peak_s"]
    assert table["node"].tolist()[:3] == [14, 6, 11] and not os.path.isabs(table["file"][0])
    assert np.allclose(table["time_of_peak_s"][:3], 0.982, atol=0.002)
    assert table["peak_force_N"][0] > table["peak_force_N"][2] > table["peak_force_N"][1] > 4e3
    assert np.isnan(table["node"][3]) and "'SG9' (strain:9) is constant" in table["error"][3]
    assert os.path.exists(out["files"]["events_figure"])
    assert (tmp_path / "out" / "events" / "impact-0002" / "ranking.csv").exists()


def test_locate_on_an_impact_record_with_a_gauge_at_half_the_rate(tmp_path, capsys):
    """SG5 recorded at 500 Hz beside the others at 1 kHz: the event is found at its node as from the
    full record, with a warning that names the channel's rate (it was taken silently, and the
    periodic gains of its cycle took 0.15 s per candidate: 107 s for the file)."""
    import shutil

    from nptdms import ChannelObject, TdmsFile, TdmsWriter

    events = tmp_path / "events"
    events.mkdir()
    src = TdmsFile.read(DAQ.parent / "impacts" / "impact-0001.tdms")
    with TdmsWriter(events / "impact-0001.tdms") as w:
        w.write_segment([ChannelObject("DAQ", c.name, c[::2], properties=dict(
            c.properties, wf_increment=2 * c.properties["wf_increment"])) if c.name == "SG5" else
            ChannelObject("DAQ", c.name, c[:], properties=c.properties) for c in src["DAQ"].channels()])
    shutil.copy(DAQ.parent / "impacts" / "impact-0001.tdms", events / "impact-0002.tdms")
    job = load_job_file(DAQ.parent / "impacts" / "truss-impacts.toml")
    job["measurements"]["file"] = str(events)
    job["locate"]["max_splits"] = 6
    (tmp_path / "job.toml").write_text(_toml(job))
    assert main(["locate", str(tmp_path / "job.toml"), "--no-tune", "--json", "--out", str(tmp_path / "out")]) == 0
    out = json.loads(capsys.readouterr().out)
    table = pd.read_csv(out["files"]["events"])
    assert table["node"].tolist() == [14, 14]
    assert abs(table["peak_force_N"][0] / table["peak_force_N"][1] - 1) < 0.05, table["peak_force_N"].tolist()
    assert "strain:5 samples at 500 Hz, every 2nd step of the 1000 Hz grid" in table["warnings"][0]
    assert "500 Hz" not in str(table["warnings"][1])


@pytest.mark.parametrize("kind", ["tdms", "csv"])
def test_an_empty_file_among_a_records_files_is_skipped_and_named(tmp_path, kind):
    """A DAQ session stopped at once leaves a file without a data row: a TDMS one was joined
    silently, a CSV one refused the whole record.  It is skipped with a warning; the record is the
    one without it; a record of empty files only is refused."""
    df = pd.read_csv(DAQ / "record-si.csv")
    folder = tmp_path / "rec"
    folder.mkdir()
    cuts = [(0, 400), (400, 400), (400, len(df))]
    if kind == "csv":
        for i, (a, b) in enumerate(cuts):
            df.iloc[a:b].to_csv(folder / f"part-{i}.csv", index=False)
    else:
        from nptdms import ChannelObject, TdmsWriter

        dt = df.time[1]
        for i, (a, b) in enumerate(cuts):
            with TdmsWriter(folder / f"part-{i}.tdms") as w:
                w.write_segment([ChannelObject("DAQ", c, df[c].to_numpy()[a:b], properties={
                    "wf_increment": dt, "wf_start_offset": a * dt}) for c in SENSORS])
    rec = Record(folder, SENSORS)
    assert rec.warnings == [f"{folder / f'part-1.{kind}'}: no data row (an empty file); skipped"]
    t, Y = rec.read()
    np.testing.assert_array_equal(Y, df[SENSORS].to_numpy())
    for f in folder.iterdir():
        if f.name != f"part-1.{kind}":
            f.unlink()
    with pytest.raises(AKFInputError, match="0 data rows"):
        Record(folder, SENSORS)
    (folder / "part-1.again").write_bytes((folder / f"part-1.{kind}").read_bytes())
    (folder / "part-1.again").rename(folder / f"part-2.{kind}")
    with pytest.raises(AKFInputError, match="none of the record's 2 files has a data row"):
        Record(folder, SENSORS)


def test_record_chunks_from_a_later_step_skip_the_files_before(tmp_path):
    """A resumed record starts at a chunk boundary inside a later file and gives the same chunks."""
    _split_tdms(tmp_path / "pieces")
    meas = _channel_map("record.tdms")
    rec = Record(tmp_path / "pieces", SENSORS, **meas)
    whole = dict(rec.chunks(96))
    opened = []
    real = rec._open
    rec._open = lambda p: opened.append(os.path.basename(p)) or real(p)
    later = dict(rec.chunks(96, start=5 * 96))
    assert sorted(later) == [k for k in sorted(whole) if k >= 480]
    for k, Y in later.items():
        np.testing.assert_array_equal(Y, whole[k])
    assert len(opened) == 6          # steps 480.. lie in the last 6 of the 10 files (of 102-103 steps)


def test_a_wrong_unit_in_the_channel_map_is_named(tmp_path):
    """ACC_8Y declared in m/s^2 while the file holds mm/s^2: the streamed summary names the channel
    and the unit mistake it looks like."""
    meas = _channel_map("record.tdms")
    meas["units"] = dict(meas["units"], ACC_8Y="m/s^2")          # the file holds mm/s^2
    res = run_estimate(_job(DAQ / "record.tdms", **meas), str(tmp_path), plot=False)
    text = " ".join(res.metrics["warnings"])
    assert "acc:8:y" in text and "millimetres" in text and "check the channel map" in text


@pytest.mark.parametrize("first_line", ["root:x:0:0:root:/root:/bin/bash", 'PRETTY_NAME="Debian GNU/Linux 12"',
                                        "root:$y$j9T$abc$def:19000:0:99999:7:::"])
def test_a_file_that_is_no_table_is_not_quoted(tmp_path, first_line):
    """A data path pointing at a system file was refused with its first line in the message."""
    path = tmp_path / "passwd"
    path.write_text(first_line + "\ndaemon:x:1:1:daemon:/usr/sbin:/usr/sbin/nologin\n")
    with pytest.raises(AKFInputError, match="no time column 'time'; found 1 column") as info:
        Record(path, ["strain:13"], format="csv")
    assert first_line.split(":")[0].split("=")[0] not in str(info.value).replace(str(path), "")


def test_an_hdf5_dataset_declared_longer_than_its_data_is_refused(tmp_path):
    """A recording cut short leaves a dataset of the declared length whose unwritten part reads as
    the fill value: it was calibrated on those zeros."""
    h5py = pytest.importorskip("h5py")
    path = tmp_path / "cut.h5"
    with h5py.File(path, "w") as f:
        f.attrs["dt"] = 1 / 4096
        ds = f.create_dataset("SG13", shape=(100_000,), chunks=(4096,), dtype="f8")
        ds[:8192] = 1e-6 * np.sin(np.arange(8192))
        f.create_dataset("SG5", data=1e-6 * np.ones(100_000), chunks=(4096,), compression="gzip")
    with pytest.raises(AKFInputError, match="dataset 'SG13' declares 100000 samples but holds data for only about "
                                            "8192 of them"):
        Record(path, ["strain:13", "strain:5"], channels={"SG13": "strain:13", "SG5": "strain:5"}).read()
    with h5py.File(path, "w") as f:                      # contiguous, never written
        f.attrs["dt"] = 1 / 4096
        f.create_dataset("SG13", shape=(1000,), dtype="f8")
    with pytest.raises(AKFInputError, match="holds data for only about 0 of them"):
        Record(path, ["strain:13"], channels={"SG13": "strain:13"}).read()


def test_a_read_that_fails_in_the_file_names_the_file_and_the_samples(tmp_path, monkeypatch):
    """A TDMS segment index claiming 1e12 values ended in "Invalid argument" without the file's name."""
    from core_akf.io import readers

    real = readers.TdmsReader.chunks

    def failing(self, channels, size):
        class Broken:
            def __len__(self):
                return 10 ** 12

            def __getitem__(self, key):
                raise OSError(22, "Invalid argument")
        self._series = dict(self._series) | {channels[0]: Broken()}
        self._timing = readers.Timing(0.0, 1 / 4096, 10 ** 12)
        return real(self, channels, size)

    monkeypatch.setattr(readers.TdmsReader, "chunks", failing)
    with pytest.raises(AKFInputError, match=r"record\.tdms: samples 0\.\.\d+ of channel .* cannot be read \(OSError: "
                                            r"Invalid argument\): the file's index claims 1000000000000 samples"):
        Record(DAQ / "record.tdms", SENSORS, **_channel_map("record.tdms")).read()
