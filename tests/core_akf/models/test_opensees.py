"""A live OpenSeesPy model (core_akf.models.opensees.from_opensees): the S17 truss built in OpenSees
(consistent-mass truss elements) is the built-in s17_truss -- frequencies to 1e-8, member strains,
estimated forces -- and the same model exported as Matrix Market files agrees with it."""
import numpy as np
import pytest

from core_akf import estimate, simulate
from core_akf.models import s17_truss
from core_akf.models.truss import S17_MEMBERS, s17_areas, s17_joint_coordinates


def _opensees():
    try:
        import openseespy.opensees as ops
    except Exception as exc:  # noqa: BLE001 -- a missing system BLAS is an OSError-like ImportError
        pytest.skip(f"openseespy is not usable here: {exc}; OpenSeesPy loads the system's BLAS and LAPACK "
                    "(libblas.so.3, liblapack.so.3): on Debian/Ubuntu `apt-get install libblas3 liblapack3`, "
                    "on Fedora/RHEL `dnf install blas lapack`")
    return ops


def _build_s17(ops, E=200e9, rho=7800.0, offset=100, rayleigh=0):
    ops.wipe()
    ops.model("basic", "-ndm", 2, "-ndf", 2)
    for i, (x, y) in enumerate(s17_joint_coordinates(), start=1):
        ops.node(i + offset, float(x), float(y))
    ops.fix(1 + offset, 1, 1)
    ops.fix(18 + offset, 0, 1)
    ops.uniaxialMaterial("Elastic", 1, E)
    for k, ((a, b), area) in enumerate(zip(S17_MEMBERS, s17_areas()), start=1):
        ops.element("Truss", k, a + offset, b + offset, float(area), 1, "-rho", float(rho * area), "-cMass", 1,
                    "-doRayleigh", rayleigh)


def test_s17_built_in_opensees_is_the_builtin_truss():
    ops = _opensees()
    from core_akf.models.opensees import from_opensees

    ref = s17_truss()
    _build_s17(ops)
    m = from_opensees(damping=ref.damping, name="S17 from OpenSees")
    ops.wipe()
    np.testing.assert_allclose(m.frequencies(), ref.frequencies(), rtol=1e-8)
    assert m.n_strain == 34 and list(m.user_node_ids) == list(range(101, 119))
    # the same displacement field gives the same member strains
    u = np.random.default_rng(0).standard_normal(ref.n)
    order = [m.dof_index(j + 100, d) for j, d in [(int(n), d) for n, d in _ref_dofs(ref)]]
    u_m = np.zeros(m.n)
    u_m[order] = u
    np.testing.assert_allclose(m.strain_matrix @ u_m, ref.strain_matrix @ u, rtol=1e-12, atol=1e-15)
    sensors = ["acc:4:y", "acc:8:y", "strain:5", "strain:13"]
    dt = 1 / 1024
    loads = 300 * np.sin(2 * np.pi * 4 * np.arange(1024) * dt)[:, None]
    sim = simulate(ref, sensors, ["8:y"], loads, dt, relative_noise=0.02, seed=1)
    kw = dict(model_error_cov=1e-16, force_increment_cov=1e4, noise_cov=np.diag(sim.noise_std ** 2))
    a = estimate(ref, sensors, ["8:y"], sim.measurements, dt, **kw)
    b = estimate(m, ["acc:104:y", "acc:108:y", "strain:5", "strain:13"], ["108:y"], sim.measurements, dt, **kw)
    np.testing.assert_allclose(b.forces, a.forces, rtol=0, atol=1e-6 * np.max(np.abs(a.forces)))


def _ref_dofs(structure):
    """(node, direction) of each free DOF of a built-in structure."""
    nd = len(structure.dof_names)
    return [(int(f) // nd + 1, structure.dof_names[int(f) % nd]) for f in structure.free_dofs]


def test_opensees_rayleigh_damping_and_a_missing_model():
    ops = _opensees()
    from core_akf.checks import AKFInputError
    from core_akf.models.opensees import from_opensees

    ops.wipe()
    with pytest.raises(AKFInputError, match="has no nodes"):
        from_opensees()
    _build_s17(ops, rayleigh=1)                  # OpenSees' Truss takes Rayleigh damping only when asked
    ops.rayleigh(0.1, 2e-5, 0.0, 0.0)
    m = from_opensees()
    ops.wipe()
    ref = s17_truss()
    K, M = ref.K, ref.M
    # C = 0.1 M + 2e-5 K (Rayleigh on the current stiffness)
    perm = [m.dof_index(j + 100, d) for j, d in _ref_dofs(ref)]
    C = np.zeros_like(m.C)
    C[np.ix_(perm, perm)] = 0.1 * M + 2e-5 * K
    np.testing.assert_allclose(m.C, C, rtol=0, atol=1e-9 * np.max(np.abs(C)))


@pytest.mark.parametrize("failure", ["native", "absent"])
def test_openseespy_that_cannot_load_is_named_not_a_traceback(monkeypatch, failure):
    """openseespy wraps a native library that fails to load in RuntimeError("Failed to import
    openseespy on Linux."): that was a raw traceback; a package that is absent names its extra."""
    import builtins
    import sys

    from core_akf.checks import AKFInputError
    from core_akf.models import opensees

    real = builtins.__import__

    def fake(name, *args, **kw):
        if name.startswith("openseespy"):
            if failure == "absent":
                raise ImportError("No module named 'openseespy'")
            try:
                raise ImportError("libblas.so.3: cannot open shared object file: No such file or directory")
            except ImportError:
                raise RuntimeError("Failed to import openseespy on Linux.")  # noqa: B904 -- as openseespy does
        return real(name, *args, **kw)

    monkeypatch.delitem(sys.modules, "openseespy.opensees", raising=False)
    monkeypatch.delitem(sys.modules, "openseespy", raising=False)
    monkeypatch.setattr(builtins, "__import__", fake)
    with pytest.raises(AKFInputError) as info:
        opensees._ops()
    if failure == "native":
        assert "openseespy is installed but cannot load (Failed to import openseespy on Linux.: libblas.so.3" in str(
            info.value) and "apt-get install libblas3 liblapack3" in str(info.value)
    else:
        assert "needs the package 'openseespy': python -m pip install" in str(info.value)
