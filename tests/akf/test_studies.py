"""The paper studies (``akf study``) on short records: the papers' qualitative findings.

Where our simulation does not reproduce a published finding the test is ``xfail(strict=True)``
with the reason (studies/README.md discusses it): if a change makes it pass, we want to know.
"""
import os

import numpy as np
import pytest

from akf.cli import main
from akf.studies import run_study


@pytest.fixture(scope="module")
def s17(tmp_path_factory):
    return run_study("s17_truss", out=str(tmp_path_factory.mktemp("s17")), quick=True)


@pytest.fixture(scope="module")
def th(tmp_path_factory):
    """The thesis study on short records (~40 s): its tests are marked slow."""
    return run_study("th_plate", out=str(tmp_path_factory.mktemp("th")), quick=True)


def _rms(study, case):
    t = study.table
    return t[t["case"] == case].set_index("load")["rms_error_N"].sort_index().to_numpy()


def _avg(study, case):
    return float(study.summary.set_index("case").loc[case, "avg_strain_error_ue"])


def test_s17_outputs_are_tidy(s17):
    t = s17.table
    assert len(t) == 9 * 4 and set(t["load"]) == {"4:y", "6:y", "8:y", "12:y"}
    assert t["rms_error_N"].notna().all()
    for key in ("table", "summary", "fig19_rms", "fig21_configs", "spectra", "forces_case4"):
        assert os.path.getsize(s17.files[key]) > 0


def test_s17_acceleration_only_diverges_under_errors(s17):
    """Case 1: fine for zero-mean loads without errors; with 5 % model error + 2 % noise the
    undetectable filter drifts (its error grows along the record)."""
    s = s17.summary.set_index("case")
    assert not s.loc["1a", "detectable"] and not s.loc["1b", "detectable"]
    ref = s17.table.query("case == '1a'")["reference_rms_N"].to_numpy()
    assert np.all(_rms(s17, "1a") < 0.02 * np.sort(ref))
    assert np.all(_rms(s17, "1b") > 50 * _rms(s17, "1a"))
    assert s.loc["1b", "max_drift_ratio"] > 3 and s.loc["1b", "max_drift_ratio"] > 2 * s.loc["1a", "max_drift_ratio"]
    assert s.loc["4", "max_drift_ratio"] < 2


def test_s17_strain_only_beats_acceleration_only_and_multimetric_beats_both(s17):
    """Fig. 19: acceleration-only >> strain-only > multi-metric at every load."""
    assert np.all(_rms(s17, "3") < _rms(s17, "2b"))
    assert _rms(s17, "3").mean() < 0.4 * _rms(s17, "2b").mean()
    assert np.all(_rms(s17, "4") < _rms(s17, "3"))


def test_s17_sensors_near_the_loads_estimate_them_better(s17):
    """Fig. 21-23: moving the accelerometer from joint 12 to 16 (set 2) hurts the load at 12;
    sensors away from all loads (set 4) are worse everywhere than set 1."""
    t = s17.table.set_index(["case", "load"])["rms_error_N"]
    assert t["set2", "12:y"] > 2 * t["4", "12:y"]
    assert np.all(_rms(s17, "set4") > 2 * _rms(s17, "4"))


@pytest.mark.slow
def test_th_outputs_are_tidy(th):
    assert len(th.table) == 11 * 363
    assert th.table["rms_error_ue"].notna().all()
    for case in ("2", "3d", "5c"):
        assert os.path.getsize(th.files[f"case{case}"]) > 0


@pytest.mark.slow
def test_th_acceleration_only_diverges(th):
    """Case 1 (accelerations only): undetectable; forced, it is far worse and drifts."""
    s = th.summary.set_index("case")
    assert not s.loc["1", "detectable"]
    assert _avg(th, "1") > 4 * _avg(th, "3d") and _avg(th, "1") > 4 * _avg(th, "2")
    assert s.loc["1", "median_drift_ratio"] > 1.5 * s.loc["3d", "median_drift_ratio"]


@pytest.mark.slow
def test_th_case3_errors_add_up_and_model_error_dominates(th):
    """Cases 3a-3d: none < noise only < model error only < both (thesis 0.91/1.06/4.56/4.59)."""
    a, b, c, d = (_avg(th, k) for k in ("3a", "3b", "3c", "3d"))
    assert a < b < c < d


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="not reproduced: with our loads three strain gauges (case 2) beat "
                   "two gauges + one accelerometer (case 3d) on the stiff plate; see studies/README.md")
def test_th_multimetric_beats_strain_only_on_stiff_plate(th):
    assert _avg(th, "3d") < _avg(th, "2")


@pytest.mark.slow
def test_th_arbitrary_layout_is_worse(th):
    """Case 4 ("arbitrary" placement) is worse than the chosen multi-metric layout 3d."""
    assert _avg(th, "4") > 1.5 * _avg(th, "3d")


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="not reproduced: the thesis' case 4 is ~1000x case 3; ours is ~2x "
                   "(its accelerometer sits on the clamped edge; see studies/README.md)")
def test_th_arbitrary_layout_is_ten_times_worse(th):
    assert _avg(th, "4") > 10 * _avg(th, "3d")


@pytest.mark.slow
def test_th_flexible_plate_two_gauges_suffice(th):
    """Case 5: on the flexible plate two strain gauges (5d) do about as well as three sensors
    (5a, 5b) and clearly better than one gauge + one accelerometer (5c, undetectable)."""
    s = th.summary.set_index("case")
    assert abs(_avg(th, "5d") / _avg(th, "5b") - 1) < 0.1
    assert _avg(th, "5d") < 2 * _avg(th, "5a")
    assert not s.loc["5c", "detectable"]
    assert _avg(th, "5c") > 2 * _avg(th, "5d")


def test_flexible_plate_first_frequency_matches_plate_strip_theory():
    """TH case 5 plate: f1 against the clamped-free plate strip, (1.8751^2 / 2 pi) sqrt(D / rho h) / L^2
    (the thesis states 0.14 Hz for these dimensions; see studies/README.md)."""
    from akf.examples import TH_FLEXIBLE_PLATE
    from akf.job import build_structure

    p = TH_FLEXIBLE_PLATE
    D = p["E"] * p["thickness"] ** 3 / (12 * (1 - p["nu"] ** 2))
    f1 = 1.8751 ** 2 / (2 * np.pi) * np.sqrt(D / (p["rho"] * p["thickness"])) / p["ly"] ** 2
    # plate strip vs Euler-Bernoulli cantilever: Poisson's ratio and the 10 x 10 mesh, ~2 %
    assert build_structure(p).frequencies(1)[0] == pytest.approx(f1, rel=0.03)


def test_cli_study_list_and_unknown(capsys):
    assert main(["study", "--list"]) == 0
    out = capsys.readouterr().out
    assert "s17_truss" in out and "th_plate" in out
    assert main(["study", "no-such-study"]) == 2
    assert "available" in capsys.readouterr().err


def test_the_learning_study_is_the_worked_example_of_the_guide(tmp_path):
    """akf study learning (quick): the likelihood peaks at the truss, the calibration finds it, and
    smoothing helps the calibrated model only, with bands that fit its errors (the numbers of
    docs/guide/learning.md, on 1 s of record)."""
    res = run_study("learning", out=str(tmp_path), quick=True)
    scan = res.table.set_index("stiffness_factor")["loglik"]
    assert scan.idxmax() == 1.0 and scan[1.05] < scan[1.0] and scan[0.95] < scan[1.0]
    s = res.summary.set_index(["model", "estimator"])
    assert s.loc[("calibrated", "filtered"), "stiffness_factor"] == pytest.approx(1.0, abs=0.005)
    err = s["force_rms_error_N"]
    assert (err["calibrated", "smoothed"] < err["calibrated", "filtered"] < 40 < 100 < err["as given", "filtered"]
            < err["as given", "smoothed"])
    assert 0.8 < s.loc[("calibrated", "smoothed"), "error_over_std_rms"] < 1.2 < 5 < s.loc[("as given", "smoothed"),
                                                                                          "error_over_std_rms"]
    assert os.path.exists(res.files["likelihood_figure"]) and os.path.exists(res.files["smoothed_figure"])


def test_the_accelerations_study_is_the_worked_example_of_the_force_model_guide(tmp_path):
    """akf study accelerations (quick): the random walk is refused, dummies and Matérn are
    detectable; the Matérn-3/2 estimate beats the drifting random walk and the dummies, its bands
    fit its errors; the likelihood of the time scale peaks inside the scanned range
    (docs/guide/forcemodels.md, on 1 s of record)."""
    res = run_study("accelerations", out=str(tmp_path), quick=True)
    verdicts = res.data["verdicts"]
    assert not verdicts["random walk"].detectable and verdicts["Matérn-3/2"].detectable
    s = res.summary.set_index("estimator")
    rel = s.filter(like="force_error_rel_")
    assert (rel.loc["Matérn-3/2, given, smoothed"] < 0.35).all()
    assert (rel.loc["Matérn-3/2, given, smoothed"] < 0.5 * rel.loc["random walk + dummy displacements"]).all()
    assert (rel.loc["random walk (drifts)"] > 1.0).all()
    assert 0.8 < s.loc["Matérn-3/2, given, smoothed", "error_over_std_rms"] < 1.2
    peak = int(res.table["loglik"].idxmax())
    assert 0 < peak < len(res.table) - 1
    assert os.path.exists(res.files["accelerations_figure"]) and os.path.exists(res.files["timescale_figure"])
