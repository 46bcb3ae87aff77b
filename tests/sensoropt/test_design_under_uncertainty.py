"""Design under uncertainty (issue 35): layouts scored over true structures unlike the filter's
model and over noise draws, after sensor losses, and under costs, budgets, forbidden regions and
a minimum spacing.  Each fitness is checked against an independent computation (a simulation of
the drawn truth and the steady filter run on it), not against itself."""
import json
import math

import numpy as np
import pytest

from akf.cli import main
from core_akf import AKFInputError
from core_akf.filter import FilterModel
from core_akf.filter.kernels import fixed_gain, fixed_gain_records, steady_outputs
from core_akf.filter.riccati import steady_gain
from core_akf.forcemodels import ForceModel
from core_akf.loads import band_limited_white_noise
from core_akf.models import s17_truss
from core_akf.simulate import simulate
from sensoropt import CandidateSet, Constraints, PlacementProblem, StrainErrorObjective, Uncertainty, combine, place
from sensoropt.robust import latin_hypercube

DT = 1e-3
FORCES = ["8:y", "12:y"]


def truss_loads(n=1500):
    ramp = np.linspace(0.0, 1.0, n)[:, None] * np.array([[400.0, -250.0]])
    return ramp + band_limited_white_noise(n, DT, 40.0, 0.0, 80.0, seed=3)[:, None] * np.array([[1.0, 0.6]])


SETTINGS = dict(window=0.3, stiffness_factor=1.05, relative_noise=0.02, model_error_cov=1e-12,
                force_increment_cov=1e2, n_modes=None, seed=4)


def encoding(n=3, **kw):
    return CandidateSet(s17_truss(), kinds=("strain", "acc"), n_sensors=n, **kw)


def test_fixed_gain_records_is_fixed_gain_per_record():
    rng = np.random.default_rng(0)
    B, S, N, n, m = 3, 4, 60, 6, 2
    A = 0.3 * rng.normal(size=(B, n, n))
    G = rng.normal(size=(B, m, n))
    L = 0.2 * rng.normal(size=(B, n, m))
    Y = rng.normal(size=(B, S, N, m))
    got = fixed_gain_records(A, G, L, Y)
    for s in range(S):
        want = fixed_gain(A, G, L, np.ascontiguousarray(Y[:, s]))
        assert np.allclose(got[:, s], want, rtol=1e-11, atol=1e-12)


def test_measures_and_latin_hypercube():
    e = np.array([3.0, 1.0, 4.0, 1.0, 5.0, 9.0, 2.0, 6.0, 5.0, 3.0])
    assert combine(e, "mean") == pytest.approx(3.9)
    assert combine(e, "p90") == pytest.approx(np.percentile(e, 90))
    assert combine(e, "worst") == 9.0
    assert combine(e, "cvar90") == 9.0                               # the worst 10 % of ten: one value
    assert combine(np.arange(20.0), "cvar90") == pytest.approx(18.5)  # the worst two of twenty
    assert np.isinf(combine(np.array([1.0, np.inf]), "mean"))
    with pytest.raises(AKFInputError, match="measure must be one of"):
        combine(e, "median")
    u = latin_hypercube(8, 2, np.random.default_rng(5))
    for d in range(2):                                               # one point per stratum
        assert sorted(np.floor(u[:, d] * 8).astype(int).tolist()) == list(range(8))
    a = Uncertainty.sample((0.95, 1.10), samples=8, seeds=3, seed=2)
    b = Uncertainty.sample((0.95, 1.10), samples=8, seeds=3, seed=2)
    assert a == b and a.n_scenarios == 24
    assert sorted(np.floor((np.array(a.stiffness_factors) - 0.95) / 0.15 * 8).astype(int).tolist()) == list(range(8))
    assert Uncertainty.sample([0.9, 1.0, 1.1], samples=8).stiffness_factors == (0.9, 1.0, 1.1)


@pytest.mark.parametrize("kwargs, message", [
    (dict(stiffness_factor=(1.10, 0.95)), "low < high"),
    (dict(stiffness_factor=(-1.0, 1.1)), "must be positive"),
    (dict(stiffness_factor=(0.9, 1.1), samples=0), "samples"),
    (dict(stiffness_factor=(0.9, 1.1), seeds=0), "seeds"),
    (dict(stiffness_factor=(0.9, 1.1), measure="p95"), "measure"),
])
def test_uncertainty_bad_input(kwargs, message):
    with pytest.raises(AKFInputError, match=message):
        Uncertainty.sample(**kwargs)


@pytest.fixture(scope="module")
def robust():
    s, loads = s17_truss(), truss_loads()
    u = Uncertainty.sample((0.95, 1.10), samples=3, seeds=2, measure="p90", seed=1)
    enc = encoding()
    return s, loads, u, enc, StrainErrorObjective(s, FORCES, loads, DT, enc, uncertainty=u, **SETTINGS)


def test_each_record_is_the_drawn_truth_read_by_the_one_filter(robust):
    """Independent of the objective's batching: simulate the truth of each model (stiffness
    divided by the factor), add the noise draw, run the steady filter of the nominal model."""
    s, loads, u, enc, obj = robust
    sensors = ["strain:6", "strain:21", "acc:2:y"]
    got = obj.scenario_errors(sensors)
    n = int(round(SETTINGS["window"] / DT))
    fm = FilterModel(s.scaled(1.05), FORCES, DT, None, force_model=ForceModel("random_walk", increment_cov=1e2))
    # every candidate channel is simulated with its own noise draw (a column of one draw per seed)
    sims = [simulate(s.scaled(1.05 / f), enc.labels, FORCES, loads[:n], DT, relative_noise=0.02, seed=4)
            for f in u.stiffness_factors]
    cols = [enc.labels.index(x) for x in sensors]
    R = np.diag(np.mean([sim.noise_std[cols] ** 2 for sim in sims], axis=0))   # the filter's R: over the truths
    want = []
    for sim in sims:
        for j in range(2):
            Y = sim.measurements if j == 0 else \
                sim.clean + np.random.default_rng(4 + j).normal(size=sim.clean.shape) * sim.noise_std
            Y = Y[:, cols]
            est = steady_outputs(fm.A_a, fm.observation(sensors)[None], fm.Q_a(1e-12), R[None], Y[None], fm.strain_rows())[0]
            want.append(np.sqrt(np.mean((est - sim.strains) ** 2, axis=0)).mean() * 1e6)
    assert np.allclose(got, want, rtol=1e-9)
    assert obj.evaluate([sensors])[0] == pytest.approx(np.quantile(want, 0.9), rel=1e-12)
    assert len(set(np.round(want, 6))) == 6                      # the models and draws differ


def test_one_model_at_the_filter_factor_is_the_nominal_fitness(robust):
    s, loads, _, enc, _ = robust
    nominal = StrainErrorObjective(s, FORCES, loads, DT, enc, **SETTINGS)
    same = StrainErrorObjective(s, FORCES, loads, DT, enc, uncertainty=Uncertainty((1.05, 1.05), seeds=1,
                                                                                     measure="mean"), **SETTINGS)
    layouts = [enc.sensors(enc.random_layout(np.random.default_rng(k))) for k in range(40)]
    a, b = np.array(nominal.evaluate(layouts)), np.array(same.evaluate(layouts))
    finite = np.isfinite(a)
    assert finite.sum() >= 4 and np.array_equal(finite, np.isfinite(b))
    assert np.allclose(a[finite], b[finite], rtol=1e-10)        # the records path equals the thesis' path


def test_survive_failures_scores_the_losses_and_refuses_fragile_layouts():
    s, loads = s17_truss(), truss_loads()
    enc = encoding()
    nominal = StrainErrorObjective(s, FORCES, loads, DT, enc, **SETTINGS)
    tolerant = StrainErrorObjective(s, FORCES, loads, DT, enc, survive_failures=1, **SETTINGS)
    layout = ["strain:1", "strain:15", "strain:21"]
    losses = [nominal.evaluate([[x for x in layout if x != lost]])[0] for lost in layout]
    assert tolerant.evaluate([layout])[0] == pytest.approx(max([nominal.evaluate([layout])[0]] + losses), rel=1e-12)
    assert [e for _, e in tolerant.failure_errors(layout)] == pytest.approx(losses, rel=1e-12)
    fragile = ["strain:6", "strain:21", "acc:2:y"]            # two forces: losing a gauge leaves one static sensor
    assert math.isfinite(nominal.evaluate([fragile])[0]) and math.isinf(tolerant.evaluate([fragile])[0])
    mean = StrainErrorObjective(s, FORCES, loads, DT, enc, survive_failures=1, failure_measure="mean", **SETTINGS)
    assert mean.evaluate([layout])[0] == pytest.approx(np.mean([nominal.evaluate([layout])[0]] + losses), rel=1e-12)
    res = place(tolerant, enc, seed=0, population=12, generations=4)
    assert all(math.isfinite(e) for _, e in tolerant.failure_errors(res.sensors))
    for bad, message in ((3, "below the number of sensors"), (-1, "whole number"), (1.5, "whole number")):
        with pytest.raises(AKFInputError, match=message):
            StrainErrorObjective(s, FORCES, loads, DT, enc, survive_failures=bad, **SETTINGS)


def problem(**kw):
    return PlacementProblem("truss", s17_truss(), FORCES, truss_loads(), DT, kinds=("strain", "acc"), n_sensors=3,
                            window=0.3, force_increment_cov=1e2, model_error_cov=1e-12, n_modes=None, **kw)


def test_forbidden_region_is_never_placed_or_evaluated():
    box = [0.0, -1.0, 2.5, 5.0]                                   # the truss' left part (x <= 2.5 m)
    p = problem(constraints=Constraints(forbidden=[box]))
    enc = p.encoding()
    seen = []
    obj = p.objective(enc)
    inner = obj.evaluate
    res = place(type("Spy", (), {"n_objectives": 1,
                                 "evaluate": lambda self, ls: (seen.extend(ls), inner(ls))[1]})(),
                enc, seed=0, population=12, generations=5)
    x = {lab: pos[0] for lab, pos in zip(enc.labels, enc.position)}
    assert seen and all(x[sens] > 2.5 for layout in seen for sens in layout)
    assert all(x[sens] > 2.5 for sens in res.sensors)
    nodes = problem(constraints=Constraints(forbidden_nodes=[8])).encoding()
    banned = [lab for lab, ok in zip(nodes.labels, nodes.allowed) if not ok]
    members = s17_truss().members
    assert "acc:8:x" in banned and "acc:8:y" in banned
    assert {f"strain:{m + 1}" for m in range(len(members)) if 8 in members[m]} <= set(banned)
    assert all(nodes.is_valid(nodes.random_layout(np.random.default_rng(k))) for k in range(50))


def test_min_spacing_and_budget_are_honoured_by_the_result():
    rules = Constraints(cost={"strain": 1.0, "acc": 4.0}, budget=6.0, min_spacing=1.5)
    p = problem(constraints=rules)
    enc = p.encoding()
    obj = p.objective(enc)
    res = place(obj, enc, seed=1, population=16, generations=6)
    layout = enc.from_sensors(res.sensors)
    assert rules.violation(enc, layout) is None and rules.cost_of(enc, layout) <= 6.0
    pos = enc.position[list(layout)]
    assert min(np.linalg.norm(pos[i] - pos[j]) for i in range(3) for j in range(i + 1, 3)) >= 1.5
    close = ["strain:1", "strain:2", "strain:13"]                 # members 1 and 2 share node 1
    assert math.isinf(obj.evaluate([close])[0])
    assert math.isinf(obj.evaluate([["strain:6", "acc:4:y", "acc:8:y"]])[0])     # costs 9
    assert "budget 6" in rules.violation(enc, enc.from_sensors(["strain:6", "acc:4:y", "acc:8:y"]))


@pytest.mark.parametrize("rules, message", [
    (Constraints(forbidden=[[-100.0, -100.0, 100.0, 100.0]]), "cover every candidate"),
    (Constraints(cost={"strain": 5.0, "acc": 5.0}, budget=4.0), "below the cheapest layout"),
    (Constraints(forbidden=[[0.0, 0.0, 1.0]]), "forbidden box"),
    (Constraints(forbidden_nodes=[99]), "not nodes of the model"),
    (Constraints(cost={"gauge": 1.0}, budget=5.0), "no sensor type or kind"),
])
def test_constraints_no_layout_can_meet_are_refused(rules, message):
    with pytest.raises(AKFInputError, match=message):
        problem(constraints=rules).encoding()


JOB = """
name = "truss-robust"
dt = 0.001
forces = ["8:y", "12:y"]
[structure]
model = "s17_truss"
[place]
kinds = ["strain", "acc"]
sensors = 3
window = 0.3
population = 10
generations = 2
n_modes = "full"
{extra}
[filter]
stiffness_factor = 1.05
model_error_cov = 1e-12
force_increment_cov = 100.0
[simulation]
duration = 1.0
relative_noise = 0.02
[[simulation.loads]]
components = [{{type = "ramp", start = 0.0, end = 1.0, peak = 400.0}}, {{type = "band_noise", rms = 40.0, f_high = 80.0, seed = 3}}]
[[simulation.loads]]
components = [{{type = "ramp", start = 0.0, end = 1.0, peak = -250.0}}]
"""


def test_akf_place_writes_the_layout_at_each_model_and_each_loss(tmp_path, capsys):
    extra = ("survive_failures = 1\n[place.uncertainty]\nstiffness_factor = [0.95, 1.10]\nsamples = 3\nseeds = 2\n"
             "[place.constraints]\ncost = {strain = 1.0, acc = 4.0}\nbudget = 7.0\n")
    job = tmp_path / "job.toml"
    job.write_text(JOB.format(extra=extra))
    assert main(["place", str(job), "--out", str(tmp_path / "out"), "--json", "--no-plot"]) == 0
    summary = json.loads(capsys.readouterr().out)
    import pandas as pd

    models = pd.read_csv(tmp_path / "out" / "uncertainty.csv")
    failures = pd.read_csv(tmp_path / "out" / "failures.csv")
    assert len(models) == 3 and models["stiffness_factor"].between(0.95, 1.10).all()
    assert summary["uncertainty"]["error_measure"] == pytest.approx(np.quantile(models["error"], 0.9))
    assert sorted(failures["lost"]) == sorted(summary["sensors"])
    assert np.isfinite(failures["error"]).all() and summary["constraints"]["honoured"]
    assert summary["constraints"]["cost"] <= 7.0


@pytest.mark.parametrize("extra, message", [
    ("[place.uncertainty]\nstiffness_factor = [1.10, 0.95]", "low < high"),
    ("[place.uncertainty]\nstiffness_factor = [0.0, 1.1]", "stiffness_factor"),
    ("[place.uncertainty]\nsamples = 0", "samples"),
    ("survive_failures = 3", "survive_failures"),
    ("[place.constraints]\nbudget = 0.5", "budget"),
    ("[place.constraints]\nforbidden = [[-100.0, -100.0, 100.0, 100.0]]", "every candidate"),
])
def test_akf_place_bad_robustness_keys(tmp_path, capsys, extra, message):
    job = tmp_path / "job.toml"
    job.write_text(JOB.format(extra=extra))
    assert main(["place", str(job), "--out", str(tmp_path / "out"), "--no-plot"]) == 2
    assert message in capsys.readouterr().err


def test_steady_gain_is_solved_once_per_layout(robust, monkeypatch):
    """The records of every model share one Riccati solve per layout (no loop over the models)."""
    import sensoropt.objective as objective

    _, _, u, enc, obj = robust
    calls = []

    def counting(A, G, Q, R):
        calls.append(G.shape[0])
        return steady_gain(A, G, Q, R)

    monkeypatch.setattr(objective, "steady_gain", counting)
    layouts = [enc.sensors(enc.random_layout(np.random.default_rng(k))) for k in range(6)]
    obj.evaluate(layouts)
    assert len(calls) == 1 and calls[0] <= 6 and u.n_scenarios == 6


@pytest.mark.parametrize("operators", ["set", "thesis"])
def test_plate_grid_forbidden_box_and_spacing_hold_under_both_operator_sets(operators):
    """TH case 5 (the thesis plate's grid encoding and its own operators): a box over the free
    corner is never used, and the returned layout keeps 0.1 m between its gauges."""
    from akf.placement import example_problem

    p = example_problem("th-case5")
    p.constraints = Constraints(forbidden=[[0.25, 0.15, 0.41, 0.31]], min_spacing=0.1)
    enc = p.encoding()
    obj = p.objective(enc)
    seen = []
    spy = type("Spy", (), {"n_objectives": 1, "evaluate": lambda self, ls: (seen.extend(ls), obj.evaluate(ls))[1]})()
    res = place(spy, enc, seed=2, population=12, generations=5, operators=operators)
    pos = {lab: xy for lab, xy in zip(enc.labels, enc.position)}
    inside = lambda s: 0.25 <= pos[s][0] <= 0.41 and 0.15 <= pos[s][1] <= 0.31     # noqa: E731
    assert not any(inside(s) for layout in seen for s in layout)
    assert sum(1 for layout in seen for s in layout) > 60
    assert p.constraints.violation(enc, enc.from_sensors(res.sensors)) is None
    xy = np.array([pos[s] for s in res.sensors])
    assert min(np.linalg.norm(xy[i] - xy[j]) for i in range(3) for j in range(i + 1, 3)) >= 0.1


def test_front_of_error_against_cost_on_the_footbridge(tmp_path, capsys):
    """``objectives = ["error", "cost"]``: NSGA-II over 1..8 sensors of any kind on the 3-D
    footbridge, with accelerometers four times a gauge's cost and a budget of 10."""
    from akf.examples import load_example

    text = (__import__("importlib.resources", fromlist=["files"]).files("akf.examples") / "jobs" /
            "footbridge-place.toml").read_text()
    assert load_example("footbridge-place", "place")["place"]["budget"] == {"strain": 4, "acc": 2}
    text = text.replace("budget = {strain = 4, acc = 2}", 'sensors = 8\nobjectives = ["error", "cost"]')
    text = text.replace("window = 4.0", "window = 2.0").replace("population = 30", "population = 16") \
        .replace("generations = 30", "generations = 6")
    text += "\n[place.constraints]\ncost = {strain = 1.0, acc = 4.0}\nbudget = 10.0\n"
    job = tmp_path / "front.toml"
    job.write_text(text)
    assert main(["place", str(job), "--out", str(tmp_path / "out"), "--json", "--no-plot"]) == 0
    summary = json.loads(capsys.readouterr().out)
    import pandas as pd

    front = pd.read_csv(tmp_path / "out" / "front.csv")
    assert len(front) >= 4 and len(summary["front"]) == len(front)
    assert front["cost"].is_monotonic_increasing and front["window_error"].is_monotonic_decreasing
    assert (front["cost"] <= 10.0).all() and np.isfinite(front["error"]).all()
    for r in front.itertuples():
        kinds = [s.split(":")[0] for s in r.sensors.split()]
        assert r.cost == pytest.approx(kinds.count("strain") + 4.0 * kinds.count("acc"))
        assert r.n_sensors == len(kinds)


def test_band_rule_with_accelerometers_ranks_layouts_as_the_full_model_on_a_3d_truss():
    """The fast default for accelerometer candidates (issue 35): a 147-DOF 3-D truss read from
    its matrices (the footbridge with 12 panels) at 512 Hz, 30 random layouts of 4 gauges and 2
    accelerometers.  The band rule keeps 118 modes (before: all 147); measured Spearman 0.96."""
    from scipy.stats import spearmanr

    from core_akf.models import footbridge

    s = footbridge(n_panels=12)
    dt = 1.0 / 512
    n = int(2.0 / dt)
    loads = np.column_stack([band_limited_white_noise(n, dt, 300.0, 1.0, 20.0, seed=1) - 700.0,
                             band_limited_white_noise(n, dt, 200.0, 2.0, 40.0, seed=2)])
    enc = CandidateSet(s, kinds=("strain", "acc:z", "acc:y"), budget={"strain": 4, "acc": 2})
    settings = dict(window=2.0, stiffness_factor=1.02, relative_noise=0.02, model_error_cov=1e-14,
                    force_increment_cov=1e3, seed=0)
    rng = np.random.default_rng(0)
    layouts = [enc.sensors(enc.random_layout(rng)) for _ in range(30)]
    band = StrainErrorObjective(s, ["21:z", "34:z"], loads, dt, enc, **settings)
    assert s.n == 147 and band.model.n_modes == 118
    full = StrainErrorObjective(s, ["21:z", "34:z"], loads, dt, enc, n_modes=None, **settings)
    a, b = np.array(full.evaluate(layouts)), np.array(band.evaluate(layouts))
    assert np.isfinite(a).all() and np.isfinite(b).all()
    assert spearmanr(a, b).correlation >= 0.95
    assert np.median(np.abs(b / a - 1)) < 0.06


def test_truths_carry_the_drawn_frequency_factors():
    s = s17_truss()
    u = Uncertainty.sample((0.95, 1.10), frequency=([1.02, 0.97], [0.01, 0.0]), samples=5, seeds=1, seed=3)
    assert u.frequency_factors.shape == (5, 2) and np.allclose(u.frequency_factors[:, 1], 0.97)
    z = np.log(u.frequency_factors[:, 0] / 1.02) / 0.01                       # stratified standard normal
    assert sorted(np.floor(__import__("scipy.stats", fromlist=["norm"]).norm.cdf(z) * 5).astype(int)) == list(range(5))
    for f, c, truth in zip(u.stiffness_factors, u.frequency_factors, u.truths(s, 1.05)):
        filt = s.scaled(1.05)
        ratio = truth.frequencies(3) / filt.frequencies(3)
        assert np.allclose(ratio, np.r_[c, 1.0] / np.sqrt(f), rtol=1e-9)   # the filter is f times as stiff


def test_akf_place_draws_frequencies_from_a_calibration(tmp_path, capsys):
    """akf calibrate (calibrate = ["frequencies"]) writes calibration.json with the standard
    errors beside calibrated.toml; [place.uncertainty] frequency_factors reads both, and the
    calibrated stiffness factor (the other modes' common factor) against the place job's."""
    from helpers import DAQ

    (tmp_path / "rec.csv").write_bytes((DAQ / "record-si.csv").read_bytes())
    head = (DAQ / "s17-tdms.toml").read_text().split("[measurements]")[0]
    head = head.replace("force_increment_cov = 1e5", 'force_increment_cov = 1e5\ncalibrate = ["frequencies"]\n'
                        'calibrate_modes = [1, 2]')
    (tmp_path / "cal.toml").write_text(head + '\n[measurements]\nfile = "rec.csv"\n')
    assert main(["calibrate", str(tmp_path / "cal.toml"), "--out", str(tmp_path / "cal"), "--json"]) == 0
    fit = json.loads(capsys.readouterr().out)["calibration"]
    saved = json.loads((tmp_path / "cal" / "calibration.json").read_text())
    assert saved["std_errors"] == fit["std_errors"] and len(fit["frequency_factors"]) >= 2
    job = tmp_path / "place.toml"
    job.write_text(JOB.format(extra='[place.uncertainty]\nfrequency_factors = "cal/calibrated.toml"\nsamples = 4\n'
                              'seeds = 1'))
    assert main(["place", str(job), "--out", str(tmp_path / "out"), "--json", "--no-plot"]) == 0
    import pandas as pd

    models = pd.read_csv(tmp_path / "out" / "uncertainty.csv")
    # the truth is the calibrated model: its stiffness factor (the other modes' common factor) against the place job's
    import tomllib

    calibrated = tomllib.loads((tmp_path / "cal" / "calibrated.toml").read_text())["filter"]["stiffness_factor"]
    placed = tomllib.loads(job.read_text()).get("filter", {}).get("stiffness_factor", 1.0)
    assert calibrated == pytest.approx(fit["stiffness_factor"]) and abs(calibrated - 1.0) < 0.01
    assert len(models) == 4 and np.allclose(models["stiffness_factor"], placed / calibrated, rtol=1e-9)
    for k in (1, 2):
        name = f"frequencies:{k}"
        c, se = fit["frequency_factors"][k - 1], max(fit["std_errors"][name], fit["robust_std_errors"][name])
        z = np.log(models[f"frequency_factor_{k}"] / c) / se
        assert np.all(np.abs(z) < 3) and z.std() > 0.3                     # drawn around the fit, spread by its error
    job.write_text(JOB.format(extra='[place.uncertainty]\nfrequency_factors = "nowhere/calibrated.toml"'))
    assert main(["place", str(job), "--out", str(tmp_path / "out2"), "--no-plot"]) == 2
    assert "cannot read" in capsys.readouterr().err


def test_a_checkpoint_resumes_only_under_the_same_robustness(tmp_path):
    s, loads = s17_truss(), truss_loads()
    enc = encoding()
    ck = str(tmp_path / "ga.json")
    tolerant = StrainErrorObjective(s, FORCES, loads, DT, enc, survive_failures=1, **SETTINGS)
    first = place(tolerant, enc, seed=0, population=8, generations=3, checkpoint=ck, checkpoint_every=1)
    again = place(tolerant, enc, seed=0, population=8, generations=3, checkpoint=ck, resume=True)
    assert again.sensors == first.sensors
    with pytest.raises(AKFInputError, match="other settings"):
        place(StrainErrorObjective(s, FORCES, loads, DT, enc, survive_failures=1, failure_measure="mean", **SETTINGS),
              enc, seed=0, population=8, generations=3, checkpoint=ck, resume=True)
    with pytest.raises(AKFInputError, match="other settings"):
        place(StrainErrorObjective(s, FORCES, loads, DT, enc, **SETTINGS), enc, seed=0, population=8, generations=3,
              checkpoint=ck, resume=True)


def test_fatigue_objective_under_uncertainty_and_failures():
    """The DEL objective scores each record against its own truth's stresses."""
    from sensoropt import FatigueErrorObjective

    s, loads = s17_truss(), truss_loads()
    enc = encoding()
    layouts = [["strain:1", "strain:15", "strain:21"], ["strain:6", "strain:21", "acc:2:y"]]
    nominal = FatigueErrorObjective(s, FORCES, loads, DT, enc, **SETTINGS)
    same = FatigueErrorObjective(s, FORCES, loads, DT, enc, uncertainty=Uncertainty((1.05, 1.05), measure="mean"),
                                 **SETTINGS)
    assert same.evaluate(layouts) == pytest.approx(nominal.evaluate(layouts), rel=1e-10)
    robust = FatigueErrorObjective(s, FORCES, loads, DT, enc, survive_failures=1,
                                   uncertainty=Uncertainty.sample((0.95, 1.10), samples=3, seeds=2, seed=1), **SETTINGS)
    per_record = robust.scenario_errors(layouts[0])
    assert per_record.shape == (6,) and np.ptp(per_record) > 0
    fit = robust.evaluate(layouts)
    assert fit[0] >= combine(per_record, "p90") - 1e-12 and math.isinf(fit[1])     # a lost gauge leaves one static sensor


@pytest.mark.parametrize("samples, seeds", [(2, 10**6), (10**5, 1)])
def test_draws_that_cannot_fit_in_memory_are_refused_before_any_simulation(samples, seeds, monkeypatch):
    """seeds = 10^6 in [place.uncertainty] grew the process to 24 GB before the kernel killed it."""
    from core_akf import checks
    from sensoropt import objective

    monkeypatch.setattr(checks, "available_memory", lambda: 16 * 2 ** 30)       # whatever machine runs it
    simulated = []
    monkeypatch.setattr(objective, "simulate", lambda *a, **k: simulated.append(1))
    u = Uncertainty.sample((0.95, 1.10), samples=samples, seeds=seeds, seed=1)
    with pytest.raises(AKFInputError, match=rf"\[place.uncertainty\]: {samples} models x {seeds} noise draws of a "
                                            r"300-step window: .* records need about .* GiB, but this machine has"):
        StrainErrorObjective(s17_truss(), FORCES, truss_loads(), DT, encoding(), uncertainty=u, **SETTINGS)
    assert simulated == []
    objective.check_scenarios(s17_truss(), Uncertainty.sample((0.95, 1.10), samples=8, seeds=3, seed=1), 300, 80)
