"""Impact localisation (IMP): role splits, the batched scan against a plain time-varying AKF,
the paper's cases, tuning, reconstruction, data files, CLI and bad input."""
import json
import math

import numpy as np
import pandas as pd
import pytest

from akf.cli import main
from akf.examples.impact import example_scenario  # noqa: E402
from core_akf import AKFInputError
from core_akf.filter import estimate
from core_akf.metrics import rms_error
from impactloc import (
    Covariances,
    candidate_locations,
    default_covariances,
    force_summary,
    locate,
    role_splits,
    scan,
    tune_covariances,
    tune_covariances_ml,
)
from impactloc.scan import ImpactModel, location_errors


@pytest.fixture(scope="module")
def truss1():
    return example_scenario("imp-truss-case1")


def test_role_splits_count_and_roles(truss1):
    splits = role_splits(truss1.sensors, 4, "strain")
    assert len(splits) == math.comb(7, 4) == 35
    assert len({s.ad for s in splits}) == 35
    for s in splits:
        assert len(s.ad) == 4 and len(s.se) == 6 and not set(s.ad) & set(s.se)
        assert all(truss1.sensors[i].startswith("strain") for i in s.ad)
    sample = role_splits(truss1.sensors, 4, "strain", max_splits=10, seed=3)
    assert len(sample) == 10 and len({s.ad for s in sample}) == 10
    assert sample == role_splits(truss1.sensors, 4, "strain", max_splits=10, seed=3)


def test_batched_steady_scan_equals_time_varying_filter_one_at_a_time(truss1):
    """Per (location, split): the batched steady-state kernel against core_akf.estimate with the
    time-varying filter and Estimate.response at the AD sensors, after a 0.5 s transient (the slowest filter modes settle to 1e-6)."""
    s, Y, dt = truss1.structure, truss1.measurements, truss1.dt
    splits = role_splits(truss1.sensors, 4, "strain")[:3]
    cov = default_covariances(truss1.sensors, Y)
    model = ImpactModel(s, truss1.sensors, dt, n_modes=None)
    skip = int(0.5 / dt)
    for loc in candidate_locations(s, "y", [6, 14, 15]):
        ab, rel = location_errors(model, loc, splits, Y, [cov], skip)
        for j, sp in enumerate(splits):
            se = [truss1.sensors[i] for i in sp.se]
            ad = [truss1.sensors[i] for i in sp.ad]
            est = estimate(s, se, [loc], Y[:, list(sp.se)], dt, model_error_cov=cov.model_error,
                           force_increment_cov=cov.force_increment, noise_cov=cov.noise, steady=False)
            ref = rms_error(est.response(ad)[skip:], Y[skip:, list(sp.ad)])
            # steady vs time-varying filter after 0.5 s: the gain has converged to ~1e-8, and the
            # reduced and the full model differ by rounding only (n_modes=None)
            np.testing.assert_allclose(ab[0, j], ref, rtol=1e-6)


def test_reduced_scan_with_static_correction_ranks_like_the_full_model():
    sc = example_scenario("imp-plate")
    splits = role_splits(sc.sensors, 4, "strain", max_splits=8, seed=0)
    cov = default_covariances(sc.sensors, sc.measurements)
    cands = candidate_locations(sc.structure, "w", [15, 20, 21, 22, 27])
    full = scan(sc.structure, sc.sensors, sc.measurements, sc.dt, splits, candidates=cands, covariances=cov, n_modes=None)
    red = scan(sc.structure, sc.sensors, sc.measurements, sc.dt, splits, candidates=cands, covariances=cov, n_modes="auto")
    assert ImpactModel(sc.structure, sc.sensors, sc.dt, "auto").n_modes == 30   # the bending modes
    assert full.identified == red.identified == (21, "w")
    # the true location fits about equally well; the wrong ones differ (up to 2x) but stay far worse
    assert red.summary["mean"].iloc[0] == pytest.approx(full.summary["mean"].iloc[0], rel=0.25)
    assert red.summary["node"].iloc[1] == full.summary["node"].iloc[1] == 15
    assert red.margin > 0.8 * full.margin


@pytest.mark.parametrize("name,noise,node", [
    ("imp-truss-case1", "abs", 14), ("imp-truss-case1", "rel10", 14),
    ("imp-truss-case2", "abs", 14), ("imp-truss-case2", "rel10", 14),
    ("imp-plate", "abs", 21), ("imp-plate", "rel10", 21),
])
def test_paper_cases_find_the_impact_node(name, noise, node):
    sc = example_scenario(name, noise=noise)
    res = locate(sc.structure, sc.sensors, sc.measurements, sc.dt, n_ad=sc.n_ad, ad_kinds=sc.ad_kinds,
                 direction=sc.direction, tune=False)
    assert res.identified == (node, sc.direction)
    best = res.scan.summary.iloc[0]
    assert best["mean"] < res.scan.summary["mean"].iloc[1]
    assert res.scan.confidence > 0.8 and res.scan.margin > 2
    assert res.reconstruction.summary.peak == pytest.approx(sc.true_force.max(), rel=0.25)


@pytest.mark.parametrize("node,seed", [(4, 1), (9, 2), (11, 3), (16, 4)])
def test_other_impact_nodes_are_found(node, seed):
    """Not tuned to node 14: impacts elsewhere (with other noise seeds) are found too."""
    sc = example_scenario("imp-truss-case1", impact_node=node, seed=seed)
    res = locate(sc.structure, sc.sensors, sc.measurements, sc.dt, n_ad=4, direction="y", tune=False,
                 max_splits=12, seed=seed)
    assert res.identified == (node, "y")


def test_tuning_lowers_ad_error_and_force_error(truss1):
    sc = truss1
    res = locate(sc.structure, sc.sensors, sc.measurements, sc.dt, n_ad=4, direction="y",
                 tuning={"population": 8, "generations": 4})
    t = res.tuning
    assert t.tuned_error < t.initial_error
    assert list(t.logbook["generation"]) == [0, 1, 2, 3, 4]
    assert np.all(np.diff(t.logbook["best"]) <= 0)                       # elitism
    before = rms_error(res.initial.force, sc.true_force)
    after = rms_error(res.reconstruction.force, sc.true_force)
    assert after < 0.5 * before
    strain_before = np.mean(rms_error(res.initial.estimate.strains, sc.simulation.strains))
    strain_after = np.mean(rms_error(res.reconstruction.estimate.strains, sc.simulation.strains))
    assert strain_after < strain_before


def test_maximum_likelihood_tuning_fits_every_level_and_helps_the_force(truss1):
    """tune="ml": the levels that make the record likeliest (every one fitted: the likelihood sees
    the absolute levels), the likelihood up, the force history closer to the truth than with the
    assumed levels, and the AD errors of the same split sample as the GA's reported."""
    sc = truss1
    res = locate(sc.structure, sc.sensors, sc.measurements, sc.dt, n_ad=4, direction="y", tune="ml")
    t = res.tuning
    assert t.method == "ml" and res.to_dict()["tuning"] == "ml"
    assert sorted(t.genes) == ["force_increment", "model_error", "noise_acc", "noise_strain"]
    assert t.logbook["loglik_after"].iloc[0] > t.logbook["loglik_before"].iloc[0]
    assert res.reconstruction.estimate is not res.initial.estimate          # the fitted levels are used
    assert rms_error(res.reconstruction.force, sc.true_force) < 0.5 * rms_error(res.initial.force, sc.true_force)
    assert t.tuned_error < t.initial_error
    splits = role_splits(sc.sensors, 4, "strain")
    again = tune_covariances_ml(sc.structure, sc.sensors, sc.measurements, sc.dt, (14, "y"), splits,
                                start=default_covariances(sc.sensors, sc.measurements))
    assert again.covariances == t.covariances and again.initial_error == t.initial_error


@pytest.mark.parametrize("tune, tuning, message", [("fast", None, "tune must be"), (1, None, "tune must be"),
                                                   ("ml", {"population": 8}, "do not apply")])
def test_a_tuning_method_that_does_not_exist_is_named(truss1, tune, tuning, message):
    sc = truss1
    with pytest.raises(AKFInputError, match=message):
        locate(sc.structure, sc.sensors, sc.measurements, sc.dt, n_ad=4, direction="y", tune=tune, tuning=tuning,
               max_splits=4)


def test_tuning_is_reproducible_whatever_the_number_of_workers(truss1):
    sc = truss1
    splits = role_splits(sc.sensors, 4, "strain")
    cov = default_covariances(sc.sensors, sc.measurements)
    kw = dict(start=cov, population=8, generations=2, n_splits=4, seed=7)
    a = tune_covariances(sc.structure, sc.sensors, sc.measurements, sc.dt, (14, "y"), splits, n_jobs=1, **kw)
    b = tune_covariances(sc.structure, sc.sensors, sc.measurements, sc.dt, (14, "y"), splits, n_jobs=2, **kw)
    assert a.covariances == b.covariances
    assert a.tuned_error == b.tuned_error


def test_scan_in_parallel_equals_serial(truss1):
    sc = truss1
    splits = role_splits(sc.sensors, 4, "strain", max_splits=6)
    cov = default_covariances(sc.sensors, sc.measurements)
    cands = candidate_locations(sc.structure, "y", [6, 8, 14, 15])
    a = scan(sc.structure, sc.sensors, sc.measurements, sc.dt, splits, candidates=cands, covariances=cov, n_jobs=1)
    b = scan(sc.structure, sc.sensors, sc.measurements, sc.dt, splits, candidates=cands, covariances=cov, n_jobs=2)
    np.testing.assert_array_equal(a.errors, b.errors)


def test_force_summary_of_a_half_sine():
    dt, T, peak = 1e-4, 0.004, 5e3
    t = np.arange(2000) * dt
    f = np.where((t >= 0.05) & (t <= 0.05 + T), peak * np.sin(np.pi * (t - 0.05) / T), 0.0)
    s = force_summary(f, dt, level=0.0 + 1e-9)
    assert s.peak == pytest.approx(peak, rel=1e-3)
    assert s.time_of_peak == pytest.approx(0.052, abs=dt)
    assert s.impulse == pytest.approx(2 * peak * T / np.pi, rel=1e-3)
    assert s.duration == pytest.approx(T, abs=2 * dt)


def _job(tmp_path, sc, **over):
    df = pd.DataFrame(sc.measurements, columns=sc.sensors)
    df.insert(0, "time", np.arange(len(df)) * sc.dt)
    df.to_csv(tmp_path / "impact.csv", index=False)
    sensors = ", ".join(f'"{s}"' for s in sc.sensors)
    text = f"""name = "t"
dt = {over.get('dt', sc.dt)}
sensors = [{sensors}]
[structure]
model = "s17_truss"
[locate]
n_ad = {over.get('n_ad', 4)}
ad_kinds = ["strain"]
direction = "y"
max_splits = 8
tune = false
candidates = {over.get('candidates', [6, 13, 14, 15])}
[measurements]
file = "impact.csv"
"""
    (tmp_path / "job.toml").write_text(text)
    return str(tmp_path / "job.toml")


def test_cli_locate_job_from_csv_and_json(tmp_path, truss1, capsys):
    job = _job(tmp_path, truss1)
    assert main(["locate", job, "--json", "--out", str(tmp_path / "out"), "--no-plot"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["identified"] == 14 and 0 <= d["confidence"] <= 1
    assert d["peak_force"] == pytest.approx(1e4, rel=0.25)
    assert [r["node"] for r in d["ranking"]][0] == 14 and {"node", "mean", "std"} <= set(d["ranking"][0])


def test_cli_locate_tunes_by_maximum_likelihood(tmp_path, capsys):
    assert main(["locate", "--example", "imp-truss-case1", "--tune", "ml", "--no-plot", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "covariance tuning (maximum likelihood): AD error" in out and "identified: node 14" in out
    assert main(["locate", "--example", "imp-truss-case1", "--tune", "ml", "--no-tune", "--out", str(tmp_path)]) == 2
    assert "give one of them" in capsys.readouterr().err


def test_cli_locate_example_json(tmp_path, capsys):
    assert main(["locate", "--example", "imp-truss-case2", "--noise", "rel10", "--json", "--no-tune",
                 "--out", str(tmp_path)]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["identified"] == 14 == d["true_node"]
    assert len(d["ranking"]) == 16


def test_bad_input_is_reported(tmp_path, truss1, capsys):
    sc = truss1
    with pytest.raises(AKFInputError, match="only 7 installed"):
        role_splits(sc.sensors, 8, "strain")
    with pytest.raises(AKFInputError, match="unknown node/joint 99"):
        candidate_locations(sc.structure, "y", [99])
    Y = sc.measurements.copy()
    Y[100, 2] = np.inf                                   # NaN is a missing sample; inf is an error
    with pytest.raises(AKFInputError, match="infinite"):
        locate(sc.structure, sc.sensors, Y, sc.dt, n_ad=4, direction="y", tune=False)
    with pytest.raises(AKFInputError, match="unknown AD sensor kind"):
        role_splits(sc.sensors, 2, "strian")
    with pytest.raises(AKFInputError, match="force_increment"):
        Covariances(1e-16, 0.0, {"strain": 1e-12})
    # data / model rate mismatch and a missing column, through the job file
    assert main(["locate", _job(tmp_path, sc, dt=sc.dt / 2), "--no-plot"]) == 2
    assert "does not match" in capsys.readouterr().err
    df = pd.read_csv(tmp_path / "impact.csv").drop(columns=["strain:9"])
    job = _job(tmp_path, sc)
    df.to_csv(tmp_path / "impact.csv", index=False)
    assert main(["locate", job, "--no-plot"]) == 2
    assert "strain:9" in capsys.readouterr().err


def test_an_impact_is_found_in_a_record_with_missing_samples():
    """2 % of the samples missing in channel blocks: the scan skips them and finds node 14."""
    sc = example_scenario("imp-truss-case1")
    Y, rng = np.array(sc.measurements, float), np.random.default_rng(5)
    while np.isnan(Y).mean() < 0.02:
        j, a = rng.integers(Y.shape[1]), rng.integers(0, Y.shape[0] - 10)
        Y[a:a + rng.integers(1, 10), j] = np.nan
    res = locate(sc.structure, sc.sensors, Y, sc.dt, n_ad=4, direction="y", tune=False, max_splits=12, seed=1)
    assert res.identified == (14, "y")
    assert np.isfinite(res.reconstruction.force).all()
