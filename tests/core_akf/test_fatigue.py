"""Fatigue from the estimated strains (issue 23): rainflow counting against the independent
``rainflow`` package (ASTM E1049-85), the EN 1993-1-9 curves, damage and damage-equivalent ranges,
streamed records in pieces and resumed, ``[output.fatigue]`` in jobs, and bad input by kind."""
import numpy as np
import pandas as pd
import pytest
import rainflow as reference_rainflow
from helpers import measured_s17_files

from akf.estimate import estimate_job
from akf.examples import example
from akf.job import Job
from core_akf.checks import AKFInputError
from core_akf.fatigue import (
    EC3_CATEGORIES,
    FatigueAccumulator,
    SNCurve,
    check_youngs_modulus,
    damage,
    equivalent_range,
    rainflow,
    stress_operator,
)
from core_akf.models import from_matrices, s17_truss


def _reference(series, curve, m, n_eq):
    """Cycles, max range, damage and DEL of one series from the rainflow package's cycles."""
    cycles = reference_rainflow.count_cycles(series)
    r = np.array([c[0] for c in cycles], float)
    n = np.array([c[1] for c in cycles], float)
    return n.sum(), r.max(), float(np.sum(n * curve.damage_per_cycle(r))), float((np.sum(n * r ** m) / n_eq) ** (1 / m))


SERIES = {
    "white noise": lambda rng: rng.normal(size=3000),
    "random walk, rounded (plateaus and ties)": lambda rng: np.round(np.cumsum(rng.normal(size=3000)), 1),
    "integers (many equal ranges)": lambda rng: rng.integers(-5, 6, size=2000).astype(float),
    "a few points": lambda rng: rng.normal(size=5),
    "sine with a trend": lambda rng: np.sin(np.linspace(0, 60, 4000)) + np.linspace(0, 3, 4000),
}


@pytest.mark.parametrize("kind", list(SERIES))
def test_rainflow_equals_the_rainflow_package(kind):
    """Every series kind, five at once in one batch: the same cycles (range and count) per column."""
    rng = np.random.default_rng(3)
    X = np.column_stack([SERIES[kind](rng) for _ in range(5)])
    c = rainflow(X)
    for j in range(5):
        mine = pd.Series(c.counts[c.output == j]).groupby(np.round(c.ranges[c.output == j], 9)).sum()
        ref = pd.DataFrame(reference_rainflow.count_cycles(X[:, j]), columns=["r", "n"])
        ref = ref.groupby(np.round(ref["r"], 9))["n"].sum()
        pd.testing.assert_series_equal(mine, ref, check_names=False, check_index_type=False)


def test_damage_and_equivalent_range_equal_the_package_count_to_1e_9():
    rng = np.random.default_rng(0)
    X = np.cumsum(rng.normal(size=(5000, 4)), axis=0) * 2e6          # Pa
    curve = SNCurve.ec3(56, gamma_mf=1.15)
    c = rainflow(X)
    got = np.column_stack([c.total(), c.max_range(), damage(c, curve), equivalent_range(c, 4.0, 1e7)])
    want = np.array([_reference(X[:, j], curve, 4.0, 1e7) for j in range(4)])
    np.testing.assert_allclose(got, want, rtol=1e-9)
    assert np.all(want[:, 2] > 0)


def test_the_ec3_curves_are_the_standards():
    """Δσ_C at 2e6, Δσ_D = 0.737 Δσ_C at 5e6, Δσ_L = 0.549 Δσ_D at 1e8; slopes 3 and 5; nothing
    below the cut-off; gamma_Mf divides the ranges."""
    for category in EC3_CATEGORIES:
        c = SNCurve.ec3(category)
        C, D, L = category * 1e6, c.ranges[1], c.ranges[2]
        assert D / C == pytest.approx(0.737, abs=5e-4) and L / D == pytest.approx(0.549, abs=5e-4)
        np.testing.assert_allclose(c.cycles_to_failure([C, D, L]), [2e6, 5e6, 1e8], rtol=1e-12)
        np.testing.assert_allclose(c.cycles_to_failure(2 * C), 2e6 / 8, rtol=1e-12)           # slope 3 above
        np.testing.assert_allclose(c.cycles_to_failure(0.9 * D), 5e6 * (1 / 0.9) ** 5, rtol=1e-9)  # slope 5
        assert c.damage_per_cycle(0.99 * c.cutoff) == 0.0
    np.testing.assert_allclose(SNCurve.ec3(71, gamma_mf=1.35).cycles_to_failure(71e6 / 1.35), 2e6, rtol=1e-12)
    own = SNCurve.from_points([[1e4, 300], [1e6, 100], [1e8, 40]])
    # log-log straight between points: the geometric middle of the ranges at the geometric middle of N
    np.testing.assert_allclose(own.cycles_to_failure([300e6, 100e6, 100e6 * np.sqrt(3), 40e6 * 1.01]),
                               [1e4, 1e6, 1e5, 1e8 * 1.01 ** -own.slopes[1]], rtol=1e-12)


def test_a_record_in_ten_pieces_counts_exactly_as_in_one():
    rng = np.random.default_rng(1)
    X = np.cumsum(rng.normal(size=(20000, 6)), axis=0) * 1e6
    curve = SNCurve.ec3(36)
    pieces = FatigueAccumulator(6, curve, 3.0, 2e6)
    cuts = np.sort(rng.choice(np.arange(1, 20000), size=9, replace=False))
    for i, part in enumerate(np.split(X, cuts)):
        if i == 5:                               # a checkpoint in the middle, restored into a new accumulator
            pieces = FatigueAccumulator(6, curve, 3.0, 2e6).restore(pieces.state())
        pieces.update(part)
    pieces.update(X[:0])                        # an empty chunk changes nothing
    one = FatigueAccumulator(6, curve, 3.0, 2e6)
    one.update(X)
    a, b = pieces.summary(), one.summary()
    np.testing.assert_array_equal(a.cycles, b.cycles)
    np.testing.assert_array_equal(a.max_range, b.max_range)
    np.testing.assert_allclose(a.damage, b.damage, rtol=1e-12)
    np.testing.assert_allclose(a.equivalent_range, b.equivalent_range, rtol=1e-12)
    np.testing.assert_array_equal(a.cycles, rainflow(X).total())
    # one sample at a time, for the first 300 steps
    single = FatigueAccumulator(6, curve, 3.0, 2e6)
    for row in X[:300]:
        single.update(row[None])
    np.testing.assert_array_equal(single.summary().cycles, rainflow(X[:300]).total())


def test_stresses_of_trusses_and_plates():
    from core_akf.models import th_plate

    truss = s17_truss()
    W = stress_operator(truss, [4, 12])
    assert W[0, 4] == W[1, 12] == truss.meta["E"] and np.count_nonzero(W) == 2
    plate = th_plate()
    ex, ey, g = plate.strain_label_index(["strain:40:ex", "strain:40:ey", "strain:40:gxy"])
    W = stress_operator(plate, [ex, ey, g])
    E, nu = plate.meta["E"], plate.meta["nu"]
    eps = np.zeros(plate.n_strain)
    eps[[ex, ey, g]] = 1e-4, -2e-5, 3e-5
    np.testing.assert_allclose(W @ eps, [E / (1 - nu ** 2) * (1e-4 - nu * 2e-5), E / (1 - nu ** 2) * (-2e-5 + nu * 1e-4),
                                         E / (2 * (1 + nu)) * 3e-5], rtol=1e-12)


# ----------------------------------------------------------------------------- in jobs
FATIGUE = {"detail_category": 36, "del_slope": 4.0}


def _counted_by_the_package(structure, strains, W, curve, m, n_eq):
    stresses = strains @ W.T
    return np.array([_reference(stresses[:, j], curve, m, n_eq) for j in range(stresses.shape[1])])


def test_estimate_job_fatigue_equals_the_package_on_the_estimated_stresses(tmp_path):
    """S17 case 4 with the true model: fatigue.csv has every member; its cycles, max range, damage
    and DEL equal the rainflow package's count of the same estimated stresses to 1e-9, and the
    estimated damage is within 5 % of the truth's on the members damaged most."""
    res = estimate_job(example("s17-case4", overrides={"output.fatigue": FATIGUE, "filter.stiffness_factor": 1.0,
                                                       "simulation.duration": 1.0}), str(tmp_path), plot=True)
    table = pd.read_csv(res.files["fatigue"])
    assert list(table.columns) == ["channel", "cycles", "max_range_MPa", "damage", "del_MPa", "damage_per_year",
                                   "damage_reference", "del_reference_MPa"]
    structure = s17_truss()
    assert list(table["channel"]) == structure.strain_labels
    est = estimate_job(example("s17-case4", overrides={"output.fatigue": FATIGUE, "filter.stiffness_factor": 1.0,
                                                       "simulation.duration": 1.0})).estimate
    W = stress_operator(structure, range(34))
    want = _counted_by_the_package(structure, est.strains, W, SNCurve.ec3(36), 4.0, 2e6)
    want[:, [1, 3]] /= 1e6                              # the package counts Pa; the table holds MPa
    np.testing.assert_allclose(table[["cycles", "max_range_MPa", "damage", "del_MPa"]].to_numpy(), want, rtol=1e-9)
    damaged = table["damage_reference"] > 1e-7          # (near the cut-off a few cycles more or less count)
    assert damaged.sum() >= 5
    np.testing.assert_allclose(table.loc[damaged, "damage"], table.loc[damaged, "damage_reference"], rtol=0.05)
    assert table["damage_per_year"].iloc[4] == pytest.approx(table["damage"].iloc[4] * 365.25 * 86400 / 1.0)
    assert "fatigue_figure" in res.files
    assert res.metrics["fatigue"]["outputs"][4]["channel"] == "strain:5"
    assert "1 s of record times 3.16e+07" in res.metrics["fatigue"]["per_year"]


def _measured(tmp_path, files):
    return measured_s17_files(tmp_path, files, {"fatigue": {"members": list(range(1, 35)), "detail_category": 36}})


def test_ten_files_count_exactly_as_one_and_a_resumed_run_as_well(tmp_path):
    one = estimate_job(Job.from_dict(_measured(tmp_path / "a", 1), "estimate"), str(tmp_path / "one"), plot=False)
    job = Job.from_dict(_measured(tmp_path / "b", 10), "estimate")
    ten = estimate_job(job, str(tmp_path / "ten"), plot=False)
    a, b = pd.read_csv(one.files["fatigue"]), pd.read_csv(ten.files["fatigue"])
    np.testing.assert_array_equal(a["cycles"], b["cycles"])
    np.testing.assert_array_equal(a["max_range_MPa"], b["max_range_MPa"])
    np.testing.assert_allclose(a[["damage", "del_MPa"]], b[["damage", "del_MPa"]], rtol=1e-12)
    assert not estimate_job(job, str(tmp_path / "r"), plot=False, stop_after=3).complete
    resumed = estimate_job(job, str(tmp_path / "r"), plot=False, resume=True)
    c = pd.read_csv(resumed.files["fatigue"])
    np.testing.assert_array_equal(c["cycles"], b["cycles"])
    np.testing.assert_allclose(c[["damage", "del_MPa"]], b[["damage", "del_MPa"]], rtol=1e-12)


BAD_FATIGUE = {
    "unknown detail category": ({"detail_category": 72}, "detail_category .* must be one of"),
    "no curve": ({"del_slope": 3.0}, "needs the S-N curve"),
    "two curves": ({"detail_category": 71, "sn_curve": [[1e4, 300], [1e8, 40]]}, "one of them"),
    "non-monotonic curve": ({"sn_curve": [[1e4, 300], [1e6, 400], [1e8, 40]]}, "not monotonic"),
    "acceleration outputs": ({"detail_category": 71, "outputs": ["acc:4:y"]}, "not .*an acceleration"),
    "outputs and members": ({"detail_category": 71, "outputs": ["strain:4"], "members": [4]}, "not both"),
    "unknown output": ({"detail_category": 71, "outputs": ["strain:99"]}, "99"),
    "gamma below 1": ({"detail_category": 71, "gamma_mf": 0.8}, "gamma_mf"),
    "E in GPa": ({"detail_category": 71, "youngs_modulus": 210}, r"youngs_modulus = 210 Pa .* e\.g\. 210e9"),
    "E in MPa": ({"detail_category": 71, "youngs_modulus": 210000}, r"youngs_modulus = 2\.1e\+05 Pa"),
}


@pytest.mark.parametrize("case", list(BAD_FATIGUE))
def test_bad_fatigue_input_is_named(case):
    section, message = BAD_FATIGUE[case]
    with pytest.raises((AKFInputError, ValueError), match=message):
        estimate_job(example("s17-case4", overrides={"output.fatigue": section, "simulation.duration": 0.1}))


def test_a_model_of_ones_own_without_e_or_strain_outputs_is_named():
    with pytest.raises(AKFInputError, match="no strain outputs"):
        stress_operator(from_matrices(np.diag([2e6, 1e6]), np.eye(2) * 100, [(1, "x"), (2, "x")],
                                      {1: [0.0, 1.0], 2: [0.0, 2.0]}), [0])
    structure = s17_truss()
    structure.meta.pop("E")
    with pytest.raises(AKFInputError, match="no Young's modulus.*youngs_modulus"):
        stress_operator(structure, [0])
    assert stress_operator(structure, [0], youngs_modulus=70e9)[0, 0] == 70e9
    with pytest.warns(UserWarning, match="youngs_modulus = 5e\\+08 Pa is outside"):
        check_youngs_modulus(5e8)
    with pytest.raises(AKFInputError, match="S-N points"):
        SNCurve.from_points([1e4, 300])
    with pytest.raises(AKFInputError, match="unknown detail category"):
        SNCurve.ec3(72)


def test_pieces_counted_apart_merge_into_the_one_piece_counts():
    """Each piece counted on its own from its first sample, then merged in order: the one-piece
    cycles exactly (rounded random walks: plateaus and ties at the joins)."""
    rng = np.random.default_rng(2)
    for _ in range(20):
        X = np.round(np.cumsum(rng.normal(size=(int(rng.integers(5, 3000)), 4)), axis=0), 1) * 1e6
        cuts = np.sort(rng.choice(np.arange(1, X.shape[0]), size=min(6, X.shape[0] - 1), replace=False))
        accs = []
        for part in np.split(X, cuts):
            accs.append(FatigueAccumulator(4, SNCurve.ec3(36)))
            accs[-1].update(part)
        for acc in accs[1:]:
            accs[0].merge(acc)
        np.testing.assert_array_equal(accs[0].summary().cycles, rainflow(X).total())
        np.testing.assert_array_equal(accs[0].summary().max_range, rainflow(X).max_range())
