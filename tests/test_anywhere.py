"""Placement and localisation on any structure: the candidate set (sensoropt.encoding.CandidateSet)
on the S17 truss -- gauges on members, accelerometers on joints -- its operators, the GA against an
exhaustive search, `akf place` and `akf locate` on job files of the truss, and the 3-D footbridge
(core_akf.models.footbridge) with its layout figure."""
import itertools
import json

import numpy as np
import pytest

from akf.cli import main
from core_akf.checks import AKFInputError
from core_akf.models import footbridge, footbridge_matrices, from_files, s17_truss
from sensoropt import PlacementProblem, place
from sensoropt.encoding import CandidateSet, make_encoding


@pytest.fixture(scope="module")
def s17():
    return s17_truss()


def test_candidate_set_on_a_truss_places_gauges_on_members_and_accelerometers_on_joints(s17):
    enc = make_encoding(s17, kinds=("strain", "acc"), budget={"strain": 3, "acc": 2})
    assert isinstance(enc, CandidateSet)
    # 34 members, 2 x 18 joint DOFs less the 3 supported ones
    assert enc.counts(range(len(enc.candidates))) == {"strain": 34, "acc": 33}
    assert set(enc.kinds) == {"strain", "acc:x", "acc:y"}
    m5 = enc.index["strain:5"]                        # member 5 joins joints 2 and 3: its middle
    np.testing.assert_allclose(enc.position[m5], 0.5 * (s17.nodes[1] + s17.nodes[2]))
    a = enc.index["acc:8:y"]
    assert all(enc.kind[g] == "acc:y" for g in enc.neighbours[a])           # moves keep the kind
    d = [np.linalg.norm(enc.position[g] - enc.position[a]) for g in enc.neighbours[a]]
    assert d == sorted(d) and d[0] == pytest.approx(1.0)                    # nearest first: 1 m panels
    rng = np.random.default_rng(0)
    pop = [enc.random_layout(rng) for _ in range(20)]
    for x, y in zip(pop[::2], pop[1::2]):
        for child in (*enc.crossover_set(x, y, rng), *enc.crossover_intermediate(x, y, rng),
                      enc.mutate(x, rng, indpb=1.0), enc.mutate_adaptive(x, rng, 2.0)):
            assert enc.is_valid(child) and enc.counts(child) == {"strain": 3, "acc": 2}
    flip = enc._flip(a, set(), rng)                                   # kind flip: y -> x at joint 8
    assert enc.labels[flip] == "acc:8:x"
    assert enc.distance(pop[0], pop[0]) == 0 and enc.distance(pop[0], pop[1]) > 0
    with pytest.raises(AKFInputError, match="unknown sensor kind"):
        make_encoding(s17, kinds=("ex",), n_sensors=2)
    with pytest.raises(AKFInputError, match="no direction 'z'"):
        make_encoding(s17, kinds=("acc:z",), n_sensors=2)
    with pytest.raises(AKFInputError, match="unknown node"):
        make_encoding(s17, candidates=["strain:5", "acc:99:y"], n_sensors=1)
    with pytest.raises(AKFInputError, match="duplicate sensor strain:5"):
        make_encoding(s17, candidates=["strain:5", "strain:5"], n_sensors=1)


def test_ga_on_the_truss_finds_the_exhaustive_optimum(s17):
    """Two gauges among 12 candidate members, targets the bottom chord: the GA's best is the best
    of all 66 pairs."""
    dt = 1 / 512
    t = np.arange(512) * dt
    loads = np.column_stack([300 * np.sin(2 * np.pi * 3 * t) + 200, 150 * np.sin(2 * np.pi * 5 * t)])
    cands = [f"strain:{m}" for m in (1, 4, 5, 9, 10, 13, 14, 18, 21, 22, 25, 26)]
    targets = [f"strain:{m}" for m in (1, 6, 10, 14, 18, 23, 27, 31, 34)]
    p = PlacementProblem("truss", s17, ["8:y", "12:y"], loads, dt, candidates=cands, n_sensors=2, targets=targets,
                         window=0.5, n_modes=None)
    enc = p.encoding()
    obj = p.objective(enc)
    pairs = list(itertools.combinations(range(len(enc.candidates)), 2))
    values = np.array(obj.evaluate([enc.sensors(x) for x in pairs]))
    best = pairs[int(np.argmin(values))]
    res = place(obj, enc, seed=0, population=12, generations=12)
    assert res.best == best and res.best_error == pytest.approx(values.min())
    assert p.full_record_error(res.sensors) > 0


TRUSS_PLACE = """name = "truss-place"
dt = 0.001953125
forces = ["8:y", "12:y"]
[structure]
model = "s17_truss"
[place]
kinds = ["strain", "acc"]
budget = {strain = 3, acc = 2}
window = 0.25
population = 8
generations = 3
[filter]
model_error_cov = 1e-16
force_increment_cov = 1e4
[simulation]
duration = 1.0
relative_noise = 0.02
[[simulation.loads]]
components = [{type = "sine", frequency = 3.0, amplitude = 300.0}]
[[simulation.loads]]
components = [{type = "band_noise", rms = 100.0, f_high = 20.0, seed = 3}]
"""


def test_akf_place_on_the_truss_job(tmp_path, capsys):
    job = tmp_path / "truss.toml"
    job.write_text(TRUSS_PLACE)
    assert main(["place", str(job), "--json", "--out", str(tmp_path / "o")]) == 0
    d = json.loads(capsys.readouterr().out)
    kinds = [r["kind"] for r in d["layout"]]
    assert sum(k == "strain" for k in kinds) == 3 and sum(k.startswith("acc:") for k in kinds) == 2
    assert all(s.startswith(("strain:", "acc:")) for s in d["sensors"]) and d["error"] > 0
    assert (tmp_path / "o" / "layout.png").stat().st_size > 0


def test_footbridge_model_and_its_exported_files(tmp_path):
    """The footbridge as .mtx files and CSV tables read back through a job's keys is the built-in
    model; its first mode is vertical; the layout figure is drawn in 3-D."""
    import scipy.io

    b = footbridge()
    assert b.free_dofs.size == 1011 and b.n_strain == 1097 and b.nodes.shape == (340, 3)
    parts = footbridge_matrices()
    scipy.io.mmwrite(tmp_path / "K.mtx", parts["K"], symmetry="symmetric")
    scipy.io.mmwrite(tmp_path / "M.mtx", parts["M"], symmetry="symmetric")
    (tmp_path / "dofs.csv").write_text("node,direction\n" + "".join(f"{n},{d}\n" for n, d in parts["dofs"]))
    (tmp_path / "nodes.csv").write_text("node,x,y,z\n" + "".join(f"{n},{x!r},{y!r},{z!r}\n"
                                                                for n, (x, y, z) in parts["nodes"].items()))
    (tmp_path / "members.csv").write_text("a,b\n" + "".join(f"{a},{c}\n" for a, c in parts["members"]))
    m = from_files(tmp_path / "K.mtx", tmp_path / "M.mtx", tmp_path / "dofs.csv", tmp_path / "nodes.csv",
                   fixed=[f"{n}:{d}" for n, d in parts["fixed"]], damping=0.005, extensometers=str(tmp_path / "members.csv"))
    np.testing.assert_allclose(m.frequencies(20), b.frequencies(20), rtol=1e-10)
    np.testing.assert_allclose(m.strain_matrix, b.strain_matrix, rtol=0, atol=1e-14)
    phi = b.modes(1)[:, 0]
    z = [i for i, (_, d) in enumerate(b.meta["dof_map"]) if d == "z"]
    assert np.sum(phi[z] ** 2) > 0.9 * np.sum(phi ** 2)
    from core_akf.figures import plot_structure
    fig = plot_structure(b, tmp_path / "layout.png", sensors=["strain:337", "acc:129:z", "acc:85:y"],
                         forces=[(113, "z")])
    assert fig.axes[0].name == "3d" and (tmp_path / "layout.png").stat().st_size > 0
