"""A model of one's own (a 3-D frame from its matrices): place, estimate, show and locate on it."""
import json
import os
import shutil

import numpy as np
import pandas as pd
import pytest
from helpers import PLACE_3D, ROOT, SIMULATION

from akf.cli import main
from core_akf.models import s17_truss


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


def test_fatigue_placement_on_a_model_of_ones_own_without_a_youngs_modulus(frame3d, tmp_path, capsys):
    """objective = "fatigue" asked for a Young's modulus that no [place] key could give; the
    relative DEL error does not depend on a uniform E, so it runs without one, and a model with
    E = 1 Pa or 200 GPa gives the same fitness."""
    from core_akf.loads import sine
    from sensoropt.encoding import CandidateSet
    from sensoropt.objective import FatigueErrorObjective

    d, structure = frame3d
    job = d / "fatigue3d.toml"
    job.write_text('name = "fatigue3d"\n' + structure + 'strains = "S.mtx"\nextensometers = [[101, 118], [103, 117]]\n'
                   + PLACE_3D + 'objective = "fatigue"\n' + SIMULATION)
    assert main(["place", str(job), "--json", "--out", str(tmp_path / "o")]) == 0
    res = json.loads(capsys.readouterr().out)
    assert len(res["sensors"]) == 3 and 0 < res["fatigue_error"] < 100
    s = s17_truss()
    loads = sine(np.arange(512) * 1 / 512, 3.0, 300.0)[:, None]
    enc = CandidateSet(s, candidates=["strain:5", "strain:13", "acc:8:y"], n_sensors=2)
    layouts = [["strain:5", "acc:8:y"], ["strain:5", "strain:13"]]
    own = FatigueErrorObjective(s, ["8:y"], loads, 1 / 512, enc, window=1.0, youngs_modulus=1.0).evaluate(layouts)
    steel = FatigueErrorObjective(s, ["8:y"], loads, 1 / 512, enc, window=1.0).evaluate(layouts)
    np.testing.assert_allclose(own, steel, rtol=1e-9)


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
