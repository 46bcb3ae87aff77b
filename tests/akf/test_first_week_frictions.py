"""The first week's frictions, each test named after the input it tries, and one name per concept."""
import json
import os
import shutil

import numpy as np
import pandas as pd
import pytest
from helpers import ROOT, measured_job, read_channels, two_dof

from akf.cli import main
from core_akf.models import s17_truss


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
    assert main(["estimate", str(measured_job(tmp_path)), "--out", str(out), "--json"]) == 0
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
        two_dof(fixed=[1, 2])


def test_an_extensometer_that_is_not_a_pair():
    with pytest.raises(ValueError, match="extensometer 1 is .*: an extensometer is a pair of node ids"):
        two_dof(extensometers=[(1, 2, 1)])


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
        read_channels(tmp_path / "s.h5")
    with h5py.File(tmp_path / "m.h5", "w") as f:
        f.attrs["dt"] = 1e-3
        f.create_dataset("acc:4:y", data=np.zeros((20, 2)))
    with pytest.raises(ValueError, match="a channel is a 1-D dataset"):
        read_channels(tmp_path / "m.h5")


def test_tdms_channel_with_a_nan_sample_is_missing_and_an_infinite_one_an_error(tmp_path):
    nptdms = pytest.importorskip("nptdms")
    y, other = np.random.default_rng(0).normal(size=(2, 50))
    y[17] = np.nan
    with nptdms.TdmsWriter(tmp_path / "r.tdms") as w:
        w.write_segment([nptdms.ChannelObject("g", "acc:4:y", y, properties={"wf_increment": 1e-3}),
                         nptdms.ChannelObject("g", "acc:6:y", other, properties={"wf_increment": 1e-3})])
    Y = read_channels(tmp_path / "r.tdms")[1]
    assert np.isnan(Y[17, 0]) and np.isnan(Y).sum() == 1
    y[17] = np.inf
    with nptdms.TdmsWriter(tmp_path / "i.tdms") as w:
        w.write_segment([nptdms.ChannelObject("g", "acc:4:y", y, properties={"wf_increment": 1e-3}),
                         nptdms.ChannelObject("g", "acc:6:y", other, properties={"wf_increment": 1e-3})])
    with pytest.raises(ValueError, match="channel 'acc:4:y' has 1 infinite sample.*row 18"):
        read_channels(tmp_path / "i.tdms")


def test_csv_separated_by_semicolons(tmp_path):
    (tmp_path / "r.csv").write_text("time;acc:4:y\n0;1\n0,001;2\n")
    with pytest.raises(ValueError, match="the header looks ';'-separated"):
        read_channels(tmp_path / "r.csv", sensors=("acc:4:y",))


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
        two_dof(M=np.diag([10.0, 0.0]))


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
