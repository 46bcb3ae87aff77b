"""Figures whose point can be seen (issue 36): each figure kind keeps the property that shows what
it is drawn for."""
import matplotlib
import numpy as np
import pandas as pd
import pytest

from akf import figures

matplotlib.use("Agg")


@pytest.fixture
def drawn(monkeypatch):
    """The figures the plot functions save, kept for the test to read."""
    import core_akf.figures as core

    kept = []
    original = core.save_figure

    def keep(fig, path, *args, **kw):
        kept.append(fig)
        return original(fig, path, *args, **kw)
    monkeypatch.setattr(core, "save_figure", keep)
    return kept


def test_a_smoothed_estimate_has_a_zoom_where_its_band_fills_the_axis(tmp_path, drawn):
    """Forces of about 1 kN with sigma 8-20 N over 2 s: on the whole record the band is a line, so
    each force gets a zoom whose axis spans at most 10 x 2 sigma, with the window shaded."""
    t = np.arange(8192) / 4096
    rng = np.random.default_rng(0)
    forces = np.column_stack([1e3 * np.sin(2 * np.pi * 13 * t), 600 * np.sin(2 * np.pi * 3 * t + 1)])
    forces += rng.normal(0, 5, forces.shape)
    std = np.column_stack([np.full(t.size, 8.0), np.full(t.size, 20.0)])
    figures.plot_estimate(t, forces, ["6:y", "12:y"], str(tmp_path / "e.png"), "t", reference=forces, force_std=std)
    fig = drawn[-1]
    zooms = [ax for ax in fig.axes if ax.get_title().startswith("zoom")]
    assert len(zooms) == 2
    for ax, sigma in zip(zooms, (8.0, 20.0)):
        low, high = ax.get_ylim()
        assert 2 * 2 * sigma < high - low <= 10 * 2 * sigma
    whole = [ax for ax in fig.axes if ax not in zooms]
    assert all(any(p.get_alpha() == 0.25 for p in ax.patches) for ax in whole[:2])       # the window, shaded
    a, b = figures.band_window(forces[:, 0], std[:, 0])
    assert b - a >= 5 and np.ptp(forces[a:b, 0]) <= figures.BAND_SPAN * 2 * 8.0


@pytest.mark.parametrize("three_d", [False, True], ids=["planar", "3-D"])
def test_the_fatigue_scale_starts_where_damage_matters_and_its_bars_are_linear(tmp_path, three_d):
    """Damage from 1e-14 to 1 (a truss where most members barely work): the colours span the
    largest down to 1e-4 of it, the rest one colour (the bar is extended), and the ranking's
    axis is linear; on the S17 truss and on a 3-D truss."""
    from core_akf.models import footbridge, s17_truss

    truss = footbridge(n_panels=4) if three_d else s17_truss()
    channels = [f"strain:{k}" for k in range(1, truss.n_strain + 1)]
    damage = np.logspace(-14, 0, truss.n_strain)
    fig = figures.plot_fatigue(truss, channels, damage, str(tmp_path / "f.png"), "t")
    ranking = [ax for ax in fig.axes if ax.get_title().startswith("the ten outputs")][0]
    assert ranking.get_xscale() == "linear"
    mappable = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"][0]
    low, high = mappable.get_ylim()
    assert high / low == pytest.approx(1e4) and high == pytest.approx(1.0)


def test_event_discs_sit_under_the_node_numbers(tmp_path, drawn):
    """events.png: each located impact's disc is drawn below the node numbers, which stay readable."""
    from core_akf.models import s17_truss

    frame = pd.DataFrame({"node": [6, 14, None], "confidence": [1.0, 0.5, None], "peak_force_N": [4e3, 2e3, None]})
    figures.plot_events(s17_truss(), frame, str(tmp_path / "ev.png"), "t")
    ax = drawn[-1].axes[0]
    numbers = [t for t in ax.texts if t.get_text().isdigit()]
    discs = [c for c in ax.collections if len(c.get_offsets()) == 2]
    assert numbers and discs and max(d.get_zorder() for d in discs) < min(t.get_zorder() for t in numbers)


def test_show_numbers_a_3d_model_thinned_and_titles_it_with_its_name(tmp_path, drawn, capsys):
    """akf show on the 1011-DOF footbridge: node and member numbers written, at most 60 of each
    (every k-th, said on the figure), the title names the model."""
    from akf.cli import main
    from core_akf.figures import NUMBERS_3D

    assert main(["show", "footbridge", "--out", str(tmp_path)]) == 0
    ax = drawn[-1].axes[0]
    nodes = [t for t in ax.texts if t.get_color() == "k" and t.get_text().isdigit()]
    members = [t for t in ax.texts if t.get_color() == "tab:blue" and t.get_text().isdigit()]
    assert 0 < len(nodes) <= NUMBERS_3D and 0 < len(members) <= NUMBERS_3D
    assert ax.get_title().startswith("footbridge") and "every 6th" in " ".join(t.get_text() for t in ax.texts)


def test_show_of_a_job_puts_every_symbol_in_the_legend_and_prints_the_filters_frequencies(tmp_path, drawn, capsys):
    """akf show JOB.toml (S17 case 4: loads on accelerometer nodes, a filter 5 % stiff): the legend
    names loads, accelerometers and gauges, the rings are drawn over the crosses, and the filter's
    frequencies are printed beside the truth's."""
    from akf.cli import main

    assert main(["estimate", "--example", "s17-case4", "--print-job"]) == 0
    (tmp_path / "job.toml").write_text(capsys.readouterr().out)
    assert main(["show", str(tmp_path / "job.toml"), "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "the filter's model (stiffness_factor 1.05): 31.12, 92.62" in out and "30.37, 90.39" in out
    ax = drawn[-1].axes[0]
    labels = ax.get_legend_handles_labels()[1]
    assert "accelerometer" in labels and "strain gauge" in labels and any(lab.startswith("load") for lab in labels)
    rings = [line for line in ax.lines if line.get_label() == "accelerometer"]
    crosses = [line for line in ax.lines if line.get_label().startswith("load")]
    assert rings[0].get_zorder() > crosses[0].get_zorder() and rings[0].get_markersize() > crosses[0].get_markersize()
    assert ax.get_title().startswith("s17-case4 (S17 truss)")
