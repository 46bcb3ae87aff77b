"""Output folders and resume: links that lead out of the folder, umask, interrupted and damaged runs."""
import json
import os

import numpy as np
import pandas as pd
import pytest
from helpers import PLACE_3D, SIMULATION, measured_job

from akf.cli import main


def test_streamed_run_into_a_folder_whose_timeseries_is_a_link_to_a_file_elsewhere(tmp_path, capsys):
    elsewhere = tmp_path / "precious.csv"
    elsewhere.write_text("keep me\n")
    out = tmp_path / "out"
    out.mkdir()
    os.symlink(elsewhere, out / "timeseries.csv")
    assert main(["estimate", str(measured_job(tmp_path)), "--no-plot", "--out", str(out)]) == 2
    assert "leads outside the output folder" in capsys.readouterr().err
    assert elsewhere.read_text() == "keep me\n"


def test_streamed_parquet_run_into_a_folder_whose_parts_are_a_link_to_a_folder_elsewhere(tmp_path, capsys):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "part-00000.parquet").write_text("not ours")
    out = tmp_path / "out"
    out.mkdir()
    os.symlink(elsewhere, out / "timeseries.parquet")
    job = measured_job(tmp_path, '[output]\nformat = "parquet"\n')
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
    job = measured_job(tmp_path)
    job.write_text(job.read_text().replace('name = "s17-tdms"', f'name = "{name}"'))
    assert main(["estimate", str(job), "--no-plot"]) == 2
    assert "must be a plain name" in capsys.readouterr().err
    assert not (tmp_path / "escape").exists() and not os.path.exists(tmp_path / "akf-out")


@pytest.mark.parametrize("name", ["../../escape", "/tmp/escape-abs", ".hidden"])
def test_show_confines_its_figure_to_the_output_folder(tmp_path, capsys, name):
    job = tmp_path / "job.toml"
    job.write_text(f'name = "{name}"\n[structure]\nmodel = "s17_truss"\n')
    out = tmp_path / "a" / "b"
    assert main(["show", str(job), "--out", str(out)]) == 2
    assert "name must be a plain name" in capsys.readouterr().err
    assert not list(tmp_path.rglob("*.png")) and not os.path.exists("/tmp/escape-abs.png")


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
    path = str(measured_job(tmp_path))
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
    path = measured_job(tmp_path)
    out = tmp_path / "o"
    estimate_job(load_job(str(path), "estimate"), str(out), plot=False, stop_after=2)
    size = (out / "timeseries.csv").stat().st_size
    assert main(["estimate", str(path), "--no-plot", "--out", str(out)]) == 2
    assert "holds an interrupted run" in capsys.readouterr().err and (out / "timeseries.csv").stat().st_size == size
    assert main(["estimate", str(path), "--no-plot", "--out", str(out), "--overwrite"]) == 0
    assert not (out / ".akf-resume.npz").exists()
    assert main(["estimate", str(path), "--no-plot", "--out", str(out)]) == 0       # a finished run: simply runs


def test_ctrl_c_while_streaming_names_the_partial_file_and_the_resume(tmp_path, capsys, monkeypatch):
    """The message said every written file was complete while timeseries.csv was a partial file
    kept for --resume; the resumed run then equals an uninterrupted one."""
    import akf.estimate.pipeline as pipeline

    path = measured_job(tmp_path)
    out, whole = tmp_path / "o", tmp_path / "whole"
    real, calls = pipeline.Pipeline.take, []

    def take(self, est):
        calls.append(1)
        if len(calls) == 4:
            raise KeyboardInterrupt
        return real(self, est)

    monkeypatch.setattr(pipeline.Pipeline, "take", take)
    assert main(["estimate", str(path), "--no-plot", "--out", str(out)]) == 130
    err = capsys.readouterr().err
    assert "akf: interrupted: timeseries.csv is partial and kept with the checkpoint for --resume, which goes on " \
           "from step 246 of" in err, err
    monkeypatch.setattr(pipeline.Pipeline, "take", real)
    assert main(["estimate", str(path), "--no-plot", "--out", str(out), "--resume"]) == 0
    assert main(["estimate", str(path), "--no-plot", "--out", str(whole)]) == 0
    assert (out / "timeseries.csv").read_bytes() == (whole / "timeseries.csv").read_bytes()


@pytest.mark.parametrize("at_chunk", [1, 4])
def test_a_full_disk_removes_what_cannot_be_resumed_and_keeps_what_can(tmp_path, capsys, monkeypatch, at_chunk):
    """A run that failed on a full disk left 3 MB of partial files behind, which filled it."""
    import errno

    import akf.estimate.files as files

    path = measured_job(tmp_path)
    out = tmp_path / "o"
    real, calls = files.TimeseriesWriter.write, []

    def full(self, frame):
        calls.append(1)
        if len(calls) == at_chunk:
            with open(self.path, "ab") as fh:                  # a torn row, as a full disk leaves it
                fh.write(b"0.1,force,4:y,N,12")
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, frame)

    monkeypatch.setattr(files.TimeseriesWriter, "write", full)
    assert main(["estimate", str(path), "--no-plot", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    left = sorted(f for f in os.listdir(out) if not f.startswith((".akf-run", ".akf-files")))
    if at_chunk == 1:
        assert "before the run's first checkpoint: the partial files it started were removed (timeseries.csv)" in err
        assert left == []
    else:
        assert "timeseries.csv (partial) and the checkpoint .akf-resume.npz are kept, so that --resume goes on from " \
               "step 246" in err, err
        assert left == [".akf-resume.npz", "timeseries.csv"]
        monkeypatch.setattr(files.TimeseriesWriter, "write", real)
        whole = tmp_path / "whole"
        assert main(["estimate", str(path), "--no-plot", "--out", str(out), "--resume"]) == 0
        assert main(["estimate", str(path), "--no-plot", "--out", str(whole)]) == 0
        assert (out / "timeseries.csv").read_bytes() == (whole / "timeseries.csv").read_bytes()


@pytest.mark.parametrize("command", ["estimate", "place"])
def test_a_file_akf_did_not_write_is_never_overwritten(tmp_path, capsys, command):
    """--overwrite replaced a user's own summary.csv (or layout.csv) in the output folder; a rerun
    into a folder akf wrote still runs."""
    out = tmp_path / "o"
    out.mkdir()
    name = {"estimate": "summary.csv", "place": "layout.csv"}[command]
    (out / name).write_text("mine\n")
    args = {"estimate": ["estimate", "--example", "s17-case4", "--duration", "0.05"],
            "place": ["place", "--example", "th-case5", "--generations", "1", "--population", "4"]}[command]
    args = args + ["--no-plot", "--json", "--out", str(out)]
    assert main(args + ["--overwrite"]) == 2
    assert f"{name} exists and was not written there by akf" in capsys.readouterr().err
    assert (out / name).read_text() == "mine\n"
    os.remove(out / name)
    assert main(args) == 0 and main(args + ["--overwrite"]) == 0          # akf's own files: replaced
    assert name in (out / ".akf-files").read_text().split()


@pytest.mark.parametrize("where", ["akf-out/s17-case4", "mine"])
def test_a_folder_of_an_earlier_akf_is_rerun_into(tmp_path, capsys, monkeypatch, where):
    """A folder written before akf listed its files (no .akf-files) is adopted when it lies under
    akf-out/ (every command's default) or holds akf's own marks (its time series here); the rerun
    that the README's command makes simply runs."""
    monkeypatch.chdir(tmp_path)
    out = tmp_path / where
    args = ["estimate", "--example", "s17-case4", "--duration", "0.05", "--no-plot", "--json", "--out", str(out)]
    assert main(args) == 0
    capsys.readouterr()
    os.remove(out / ".akf-files")                        # as an earlier akf left it
    assert main(args) == 0
    assert "summary.csv" in (out / ".akf-files").read_text().split()


DAMAGE = {"truncated": "is truncated or not a checkpoint", "foreign": "is not a checkpoint of akf estimate",
          "nan": "NaN or infinite values in 'P'", "nan state": "NaN or infinite values in 'z'",
          "edited": "was changed after it was written (its checksum",
          "another job": "was written by another job ('someone-else', not 's17-tdms')",
          "edited output": "timeseries.csv was changed after the checkpoint was written",
          "cut output": "timeseries.csv is shorter than the checkpoint says"}


@pytest.mark.parametrize("damage", list(DAMAGE))
def test_resume_from_a_damaged_checkpoint(tmp_path, capsys, damage):
    """A torn or tampered checkpoint or partial output is refused by name (the NaN and the other
    job's cases under a recomputed checksum: what the entries are checked for)."""
    from akf.estimate import estimate_job
    from akf.estimate.files import _checksum
    from akf.job import load_job
    path = measured_job(tmp_path)
    out = tmp_path / "o"
    estimate_job(load_job(str(path), "estimate"), str(out), plot=False, stop_after=2)
    ck = out / ".akf-resume.npz"
    saved = dict(np.load(ck))
    if damage == "truncated":
        ck.write_bytes(ck.read_bytes()[:200])
    elif damage == "foreign":
        np.savez(ck, something=np.ones(3))
        os.replace(str(ck) + ".npz" if os.path.exists(str(ck) + ".npz") else ck, ck)
    elif damage in ("edited output", "cut output"):
        text = (out / "timeseries.csv").read_bytes()
        cut = int(saved["position"]) // 2
        (out / "timeseries.csv").write_bytes(text[:cut] + (b"9" + text[cut + 1:] if damage == "edited output" else b""))
    else:
        if damage == "nan":
            saved["P"] = saved["P"] * np.nan
        elif damage == "nan state":
            saved["z"] = saved["z"] * np.nan
        elif damage == "another job":
            saved["job"] = np.array(json.dumps(json.loads(str(saved["job"])) | {"name": "someone-else"}, sort_keys=True))
        else:
            saved["next_step"] = saved["next_step"] + 1
        if damage != "edited":
            saved["checksum"] = np.array(_checksum(saved))
        with open(ck, "wb") as fh:
            np.savez(fh, **saved)
    assert main(["estimate", str(path), "--no-plot", "--out", str(out), "--resume"]) == 2
    err = capsys.readouterr().err
    assert DAMAGE[damage] in err, err


def test_a_hard_linked_backup_keeps_its_content(tmp_path, capsys):
    """Outputs hard-linked into a backup (cp -al, rsnapshot) were changed in place with the run's."""
    from akf.estimate import estimate_job
    from akf.job import load_job
    path = measured_job(tmp_path)
    out, backup = tmp_path / "o", tmp_path / "backup"
    estimate_job(load_job(str(path), "estimate"), str(out), plot=False, stop_after=2)
    backup.mkdir()
    for f in os.listdir(out):
        if os.path.isfile(out / f):
            os.link(out / f, backup / f)
    kept = {f: (backup / f).read_bytes() for f in os.listdir(backup)}
    assert main(["estimate", str(path), "--no-plot", "--out", str(out), "--resume"]) == 0
    assert main(["estimate", str(path), "--no-plot", "--out", str(out), "--overwrite"]) == 0
    assert {f: (backup / f).read_bytes() for f in os.listdir(backup)} == kept
    assert (out / "timeseries.csv").stat().st_size > len(kept["timeseries.csv"])


def test_place_rerun_into_a_finished_runs_folder_runs_and_an_interrupted_one_asks(tmp_path, capsys):
    job = tmp_path / "truss.toml"
    job.write_text('name = "truss"\ndt = 0.001953125\nforces = ["8:y"]\n[structure]\nmodel = "s17_truss"\n'
                   + PLACE_3D.replace("strain:35", "strain:21").replace("strain:36", "strain:26")
                   .replace("108", "8").replace("106", "6") + SIMULATION)
    args = ["place", str(job), "--no-plot", "--json", "--out", str(tmp_path / "o")]
    assert main(args) == 0 and main(args) == 0
    ck = tmp_path / "o" / "checkpoint.json"
    from core_akf.evolution import load_checkpoint, save_checkpoint

    data = load_checkpoint(str(ck))
    data["finished"] = False
    save_checkpoint(str(ck), data)
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "interrupted run (generation 2 of 2)" in err and "with --resume to continue it, or with --overwrite" in err
    assert main(args + ["--overwrite"]) == 0
