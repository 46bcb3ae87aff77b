"""Models brought as matrices (core_akf.models.from_matrices): the S17 truss exported as K, M, a
DOF map and coordinates -- with node ids of its own -- is the built-in truss; files and job keys;
clear errors for matrices that cannot be a structural model."""
import json
import re

import numpy as np
import pytest
import scipy.io
import scipy.sparse

from akf.cli import main
from core_akf import estimate, simulate
from core_akf.checks import AKFInputError
from core_akf.models import from_files, from_matrices, load_matrix, s17_truss
from core_akf.models.matrices import ModelWarning

OFFSET = 100        # the exported model numbers its nodes 101..118


@pytest.fixture(scope="module")
def s17():
    return s17_truss()


def _export(s):
    """The S17 truss as an FE program would export it: full K and M, the DOF map, coordinates."""
    ids = np.arange(1, s.n_nodes + 1) + OFFSET
    dofs = [(int(i), d) for i in ids for d in "xy"]
    nodes = {int(i): tuple(s.nodes[i - OFFSET - 1]) for i in ids}
    fixed = [(j + OFFSET, d) for j, ds in s.meta["supports"].items() for d in ds]
    return s.meta["K_full"], s.meta["M_full"], dofs, nodes, fixed


def test_s17_from_matrices_is_the_builtin_truss(s17):
    K, M, dofs, nodes, fixed = _export(s17)
    m = from_matrices(scipy.sparse.csr_matrix(K), M, dofs, nodes, fixed=fixed, damping=s17.damping,
                      extensometers=s17.members + OFFSET)
    np.testing.assert_allclose(m.frequencies(), s17.frequencies(), rtol=1e-12)
    np.testing.assert_allclose(m.strain_matrix, s17.strain_matrix, rtol=0, atol=1e-15)
    sensors = ["acc:4:y", "acc:8:y", "strain:5", "strain:13"]
    shifted = ["acc:104:y", "acc:108:y", "strain:5", "strain:13"]       # extensometer k = member k
    dt = 1 / 2048
    loads = 300 * np.sin(2 * np.pi * 4 * np.arange(2048) * dt)[:, None]
    sim = simulate(s17, sensors, ["8:y"], loads, dt, relative_noise=0.02, seed=1)
    kw = dict(model_error_cov=1e-16, force_increment_cov=1e4, noise_cov=np.diag(sim.noise_std ** 2))
    a = estimate(s17, sensors, ["8:y"], sim.measurements, dt, **kw)
    b = estimate(m, shifted, ["108:y"], sim.measurements, dt, **kw)
    np.testing.assert_allclose(b.forces, a.forces, rtol=0, atol=1e-9 * np.max(np.abs(a.forces)))
    np.testing.assert_allclose(b.strains, a.strains, rtol=0, atol=1e-9 * np.max(np.abs(a.strains)))
    with pytest.raises(AKFInputError, match="unknown node 4: this structure's node ids run from 101 to 118"):
        estimate(m, ["acc:4:y"], ["108:y"], sim.measurements[:, :1], dt, **kw)


def test_a_job_reads_the_model_from_matrix_market_files(tmp_path, capsys, s17):
    """akf estimate on K.mtx, M.mtx, dofs.csv, nodes.csv gives the RMS errors of the built-in truss."""
    K, M, dofs, nodes, fixed = _export(s17)
    scipy.io.mmwrite(tmp_path / "K.mtx", scipy.sparse.coo_matrix(K), symmetry="symmetric")
    scipy.io.mmwrite(tmp_path / "M.mtx", scipy.sparse.coo_matrix(M), symmetry="symmetric")
    (tmp_path / "dofs.csv").write_text("node,direction\n" + "".join(f"{n},{d}\n" for n, d in dofs))
    (tmp_path / "nodes.csv").write_text("node,x,y\n" + "".join(f"{n},{float(x)!r},{float(y)!r}\n" for n, (x, y) in nodes.items()))
    members = ", ".join(f"[{a + OFFSET}, {b + OFFSET}]" for a, b in s17.members)
    common = '''dt = 0.0009765625
forces = ["{f}"]
sensors = ["strain:13", "strain:21", "acc:{a}:y"]
[filter]
model_error_cov = 1e-16
force_increment_cov = 1e4
[simulation]
duration = 1.0
relative_noise = 0.02
[[simulation.loads]]
components = [{{type = "sine", frequency = 4.0, amplitude = 500.0}}]
'''
    (tmp_path / "built.toml").write_text(common.format(f="8:y", a=8) + '[structure]\nmodel = "s17_truss"\n')
    (tmp_path / "files.toml").write_text(common.format(f="108:y", a=108) + f'''[structure]
model = "matrices"
K = "K.mtx"
M = "M.mtx"
dofs = "dofs.csv"
nodes = "nodes.csv"
fixed = [{", ".join(f'"{n}:{d}"' for n, d in fixed)}]
damping = {s17.damping}
extensometers = [{members}]
''')
    out = {}
    for name in ("built", "files"):
        assert main(["estimate", str(tmp_path / f"{name}.toml"), "--json", "--no-plot", "--out", str(tmp_path / name)]) == 0
        out[name] = json.loads(capsys.readouterr().out)
    assert list(out["files"]["rms_force"].values()) == pytest.approx(list(out["built"]["rms_force"].values()), rel=1e-8)
    assert out["files"]["avg_strain_error"] == pytest.approx(out["built"]["avg_strain_error"], rel=1e-8)


def test_load_matrix_formats(tmp_path):
    A = np.array([[4.0, -1.0], [-1.0, 3.0]])
    scipy.io.mmwrite(tmp_path / "a.mtx", scipy.sparse.coo_matrix(A))
    scipy.sparse.save_npz(tmp_path / "a.npz", scipy.sparse.csr_matrix(A))
    np.savez(tmp_path / "b.npz", K=A)
    np.save(tmp_path / "c.npy", A)
    for name in ("a.mtx", "a.npz", "b.npz", "c.npy"):
        B = load_matrix(tmp_path / name)
        np.testing.assert_array_equal(B.toarray() if scipy.sparse.issparse(B) else B, A)
    np.savez(tmp_path / "two.npz", K=A, M=A)
    with pytest.raises(AKFInputError, match="holds one matrix"):
        load_matrix(tmp_path / "two.npz")
    with pytest.raises(AKFInputError, match="not found"):
        load_matrix(tmp_path / "none.mtx")


def test_three_dimensional_tripod_extensometers():
    """A 3-D tripod: three bars from the ground to an apex (3 translational DOFs).  A unit apex
    displacement along a bar stretches it by 1/L (the extensometer along it reads 1/L); the
    stiffness is sum(EA/L e e^T), so the frequencies are those of K/m."""
    base = {1: (1.0, 0.0, 0.0), 2: (-0.5, 0.8660254037844386, 0.0), 3: (-0.5, -0.8660254037844386, 0.0)}
    apex = np.array([0.0, 0.0, 2.0])
    EA, mass = 2e8, 50.0
    K = np.zeros((3, 3))
    for p in base.values():
        d = apex - np.array(p)
        L = np.linalg.norm(d)
        K += EA / L * np.outer(d / L, d / L)
    s = from_matrices(K, mass * np.eye(3), [(4, "x"), (4, "y"), (4, "z")], base | {4: tuple(apex)},
                      extensometers=[(1, 4), (2, 4), (3, 4)])
    np.testing.assert_allclose(s.frequencies(), np.sqrt(np.linalg.eigvalsh(K) / mass) / (2 * np.pi), rtol=1e-12)
    d = apex - np.array(base[2])
    L = np.linalg.norm(d)
    u = d / L * 1e-3                                 # 1 mm along bar 2
    np.testing.assert_allclose(s.strain_matrix @ u, [u @ (apex - base[k]) / np.linalg.norm(apex - base[k]) ** 2
                                                      for k in (1, 2, 3)], rtol=1e-12)
    assert s.strain_matrix @ u == pytest.approx([s.strain_matrix[0] @ u, 1e-3 / L, s.strain_matrix[2] @ u])
    assert s.nodes.shape == (4, 3) and s.dof_names == ("x", "y", "z")


def two_dof():
    K = np.array([[2.0, -1.0], [-1.0, 1.0]]) * 1e6
    return K, np.eye(2) * 10.0, [(1, "x"), (2, "x")], {1: (1.0, 0.0), 2: (2.0, 0.0)}


@pytest.mark.parametrize("change, message", [
    (lambda K, M, d, n: (K + np.triu(np.ones((2, 2)), 1) * 1e3, M, d, n), "K is not symmetric: entries \\(1, 2\\)"),
    (lambda K, M, d, n: (K, np.eye(3), d, n), "K is 2x2 but M is 3x3"),
    (lambda K, M, d, n: (K, M, d[:1], n), "the DOF map has 1 rows for matrices of 2 rows"),
    (lambda K, M, d, n: (K, M, [(1, "x"), (1, "x")], n), "DOF 1:x appears twice"),
    (lambda K, M, d, n: (K, M, [(1, "x"), (2, "w")], n), "unknown direction 'w'"),
    (lambda K, M, d, n: (K, M, d, {1: (0.0, 0.0)}), "node\\(s\\) \\[2\\] that have no coordinates"),
    (lambda K, M, d, n: (K * np.nan, M, d, n), "K has NaN"),
    (lambda K, M, d, n: (np.array([[1.0, -1.0], [-1.0, 1.0]]), M, d, n), "rigid-body mode"),
    (lambda K, M, d, n: (K, -M, d, n), "positive definite"),
    (lambda K, M, d, n: (K, K, d, n), "K and M are the same matrix"),
])
def test_matrices_that_cannot_be_a_model_are_refused(change, message):
    with pytest.raises(AKFInputError, match=message):
        from_matrices(*change(*two_dof()))


def test_absurd_frequencies_warn_about_units():
    K, M, dofs, nodes = two_dof()
    with pytest.warns(ModelWarning, match=r"first natural frequencies 3\.111e\+05, 8\.143e\+05 Hz lie outside"):
        from_matrices(K * 1e8, M, dofs, nodes)        # a mass 1e8 times too small
    with pytest.raises(AKFInputError, match="extensometer 1 \\(1-2\\) needs DOF 1:y"):
        from_matrices(K, M, dofs, {1: (0.0, 0.0), 2: (1.0, 1.0)}, extensometers=[(1, 2)])


def test_impact_located_on_the_exported_model(s17):
    """Localisation takes a model's own node ids: the IMP truss impact at joint 14 is found at
    node 114 of the exported truss, as at 14 of the built-in one."""
    from akf.examples.impact import example_scenario
    from impactloc.locate import locate

    sc = example_scenario("imp-truss-case1")
    K, M, dofs, nodes, fixed = _export(s17)
    m = from_matrices(K, M, dofs, nodes, fixed=fixed, damping=s17.damping, extensometers=s17.members + OFFSET)
    sensors = [s if s.startswith("strain") else f"acc:{int(s.split(':')[1]) + OFFSET}:y" for s in sc.sensors]
    kw = dict(n_ad=sc.n_ad, ad_kinds=sc.ad_kinds, direction="y", tune=False, max_splits=6, seed=0)
    built = locate(sc.structure, sc.sensors, sc.measurements, sc.dt, **kw)
    exported = locate(m, sensors, sc.measurements, sc.dt, **kw)
    assert built.identified == (14, "y") and exported.identified == (114, "y")
    np.testing.assert_allclose(exported.scan.summary["mean"], built.scan.summary["mean"], rtol=1e-8)


def test_strain_rows_of_ones_own_come_before_the_extensometers(s17):
    """A strain operator from the FE program (here the S17 member strains over the full DOFs):
    strain:1..34 are its rows, strain:35 the extensometer after them."""
    K, M, dofs, nodes, fixed = _export(s17)
    S_full = np.zeros((s17.n_strain, K.shape[0]))
    S_full[:, s17.free_dofs] = s17.strain_matrix
    m = from_matrices(K, M, dofs, nodes, fixed=fixed, damping=s17.damping, strain_rows=scipy.sparse.csr_matrix(S_full),
                      extensometers=[(101, 118)])
    assert m.n_strain == 35 and m.members is None
    np.testing.assert_array_equal(m.strain_matrix[:34], s17.strain_matrix)
    u = np.linalg.solve(m.K, m.dof_rows([(108, "y")])[0] * 1e4)           # 10 kN down at joint 8
    ends = m.dof_rows([(118, "x")])[0] @ u - 0.0                          # joint 1 is pinned, 18 rolls in x
    assert m.strain_matrix[34] @ u == pytest.approx(ends / np.linalg.norm(s17.nodes[17] - s17.nodes[0]), rel=1e-12)
    with pytest.raises(AKFInputError, match="one column per matrix row \\(36\\)"):
        from_matrices(K, M, dofs, nodes, fixed=fixed, strain_rows=np.zeros((2, 5)))


def _own_files(folder):
    """A two-DOF model as files: K.mtx, M.mtx, dofs.csv, nodes.csv, members.csv."""
    K, M, dofs, nodes = two_dof()
    scipy.io.mmwrite(folder / "K.mtx", scipy.sparse.coo_matrix(K), symmetry="symmetric")
    scipy.io.mmwrite(folder / "M.mtx", scipy.sparse.coo_matrix(M), symmetry="symmetric")
    (folder / "dofs.csv").write_text("node,direction\n1,x\n2,x\n")
    (folder / "nodes.csv").write_text("node,x,y\n1,1.0,0.0\n2,2.0,0.0\n3,0.0,0.0\n")
    (folder / "members.csv").write_text("a,b\n3,1\n1,2\n")
    return {k: str(folder / f) for k, f in (("K", "K.mtx"), ("M", "M.mtx"), ("dofs", "dofs.csv"), ("nodes", "nodes.csv"),
                                            ("extensometers", "members.csv"))}


def _edit(path, old, new):
    path.write_text(path.read_text().replace(old, new))


@pytest.mark.parametrize("damage, message", [
    # a size line that cannot be true: refused from the header, before anything is allocated
    (lambda d: _edit(d / "K.mtx", "2 2 3", "2 2 1000000000000"), "declares 1000000000000 entries for a 2 x 2 matrix, "
     "which has 3 places"),
    (lambda d: _edit(d / "K.mtx", "2 2 3", "2 2 4"), "declares a 2 x 2 matrix of 4 entries, but the file's \\d+ bytes "
     "hold at most 3|declares 4 entries"),
    (lambda d: [_edit(d / f, f"2 2 {k}", f"1000000000 1000000000 {k}") for f, k in (("K.mtx", 3), ("M.mtx", 2))],
     "the DOF map has 2 rows for matrices of "
     "1000000000 rows"),
    (lambda d: _edit(d / "K.mtx", "2 2 3", "1000000000 1000000000000 3"), "K must be a square matrix, got shape "
     "\\(1000000000, 1000000000000\\)"),
    # cells described, never quoted (np.float64(nan) was quoted)
    (lambda d: _edit(d / "nodes.csv", "3,0.0,0.0", "3,0.0,\n,,"), "nodes.csv: y in data row 3 is an empty cell, not a "
     "finite number"),
    (lambda d: _edit(d / "dofs.csv", "2,x", "2 m,x"), "dofs.csv: node in data row 2 is a number followed by text"),
    (lambda d: _edit(d / "members.csv", "1,2", "1,inf"), "members.csv: node b in data row 2 is an infinite number"),
    # a header that is no table's is not quoted
    (lambda d: (d / "nodes.csv").write_text("root:x:0:0:root:/root:/bin/bash\n1\n"), "nodes.csv: missing column\\(s\\) "
     "\\['node', 'x', 'y'\\]; found 1 column\\(s\\) whose header does not look like column names"),
    (lambda d: (d / "nodes.csv").write_text("1,1.0,0.0\n2,2.0,0.0\n3,0.0,0.0\n"), "found numbers in the first row: "
     "the table has no header row"),
    (lambda d: (d / "dofs.csv").write_text("1,x\n2,x\n"), "found 2 column\\(s\\), 1 of them named by a number: is "
     "the header row missing\\?"),
    # a member twice (in either order) would be one strain output twice
    (lambda d: _edit(d / "members.csv", "1,2\n", "1,2\n2,1\n"), "extensometers 2 and 3 both join nodes 1 and 2"),
])
def test_model_files_that_cannot_be_true_are_named(tmp_path, damage, message):
    files = _own_files(tmp_path)
    damage(tmp_path)
    with pytest.raises(AKFInputError, match=message):
        from_files(**files)


def test_model_files_of_excel_and_pickles(tmp_path):
    """Trailing rows of empty cells (an Excel export) are no rows; a pickled .npy is refused
    without advice to load it unsafely."""
    files = _own_files(tmp_path)
    _edit(tmp_path / "nodes.csv", "3,0.0,0.0\n", "3,0.0,0.0\n,,\n,,\n")
    _edit(tmp_path / "members.csv", "1,2\n", "1,2\n,\n")
    m = from_files(**files)
    assert m.strain_matrix.shape[0] == 2
    np.save(tmp_path / "K.npy", np.array([[object()]], dtype=object), allow_pickle=True)
    with pytest.raises(AKFInputError, match="holds Python objects \\(pickled\\), which are never loaded"):
        load_matrix(tmp_path / "K.npy")


@pytest.mark.parametrize("key, value, message", [
    ("units", "'mm'", "model = 'matrices' has no key 'units'; its keys are K, M, dofs, nodes, fixed"),
    ("K", "3", "\\[structure\\] K must be a file's path \\(text, relative to the job file\\); got 3 \\(int\\)"),
    ("M", "'K.mtx'", "K and M name the same file \\(K.mtx\\)"),
    ("fixed", "'all'", "fixed must be a list of DOFs"),
])
def test_structure_keys_of_a_model_from_files(tmp_path, capsys, key, value, message):
    """Each was a TypeError from inside (an unexpected keyword, a path that is a number, 'all'
    read as the node ids 'a', 'l', 'l') or, for K given as M, a silent run on a model whose modes
    all have one frequency."""
    _own_files(tmp_path)
    entries = {"K": "'K.mtx'", "M": "'M.mtx'", "dofs": "'dofs.csv'", "nodes": "'nodes.csv'", "fixed": "[]"} | {key: value}
    (tmp_path / "job.toml").write_text('''dt = 0.001
forces = ["2:x"]
sensors = ["acc:2:x"]
[structure]
model = "matrices"
''' + "".join(f"{k} = {v}\n" for k, v in entries.items()) + '''[filter]
force_model = "matern32"
force_std = 1.0
force_timescale = 0.1
[simulation]
duration = 0.1
[[simulation.loads]]
components = [{type = "sine", frequency = 4.0, amplitude = 5.0}]
''')
    assert main(["estimate", str(tmp_path / "job.toml"), "--no-plot", "--out", str(tmp_path / "out")]) == 2
    assert re.search(message, capsys.readouterr().err)


def test_a_model_error_is_named_by_the_model():
    """The name was overwritten by the shape check's loop: "M: the model has a rigid-body mode"."""
    K, M, dofs, nodes = two_dof()
    with pytest.raises(AKFInputError, match="^frame: the model has a rigid-body mode"):
        from_matrices(np.array([[1.0, -1.0], [-1.0, 1.0]]), M, dofs, nodes, name="frame")


def test_a_damping_matrix_of_ones_own_is_kept_under_a_stiffness_factor():
    """Every job with C and a [filter] stiffness_factor (or a frequency calibration) ended in
    "cannot rescale a structure with an explicit C": the given C is now kept as given."""
    K, M, dofs, nodes = two_dof()
    C = 0.5 * M + 1e-4 * K
    s = from_matrices(K, M, dofs, nodes, C=C)
    stiff = s.scaled(1.05)
    np.testing.assert_array_equal(stiff.C, s.C)
    np.testing.assert_allclose(stiff.K, 1.05 * s.K, rtol=1e-15)
    np.testing.assert_allclose(stiff.frequencies(), np.sqrt(1.05) * s.frequencies(), rtol=1e-12)
    shifted = s.with_frequency_factors([0.9])
    np.testing.assert_array_equal(shifted.C, s.C)
    np.testing.assert_allclose(shifted.frequencies(), s.frequencies() * [0.9, 1.0], rtol=1e-10)
