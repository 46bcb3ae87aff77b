"""Rank decisions do not depend on rounding (core_akf.rank).

Every verdict below must come out the same for the model as built, for random symmetric relative
perturbations of K and M of 1e-13 (far above the 1e-16 differences between BLAS kernels) and for
stiffness factors 1.00 ... 1.10.  The layouts include the structurally exact cases where rounding
decides a naive test: zero-force members, a self-equilibrated load group, outputs that vanish on a
clamped edge, and a symmetric plate whose mid-line gauges cannot see an antisymmetric load pair.
"""
import numpy as np
import pytest

from akf.examples import TH_FLEXIBLE_PLATE
from akf.job import build_structure
from core_akf.models import imp_plate, s17_truss, th_plate
from core_akf.rank import StaticGain, is_supported, zero_rows
from core_akf.statespace import detectability, static_gain

FORCES4 = ["4:y", "6:y", "8:y", "12:y"]
ACC_ONLY = [f"acc:{j}:y" for j in (2, 4, 5, 6, 7, 8, 9, 12, 14, 15)] + [f"acc:{j}:x" for j in (4, 5, 8, 9)]
CASE4 = ["acc:4:y", "acc:6:y", "acc:8:y", "acc:12:y", "acc:6:x", "strain:5", "strain:9", "strain:13", "strain:26"]
ZERO_FORCE_SET = ["acc:2:y", "acc:10:y", "acc:14:y", "acc:16:y", "acc:10:x",
                  "strain:5", "strain:19", "strain:26", "strain:30"]

# (structure, sensors, forces, expected verdict or None where only invariance is asserted)
LAYOUTS = [
    # S17 truss: members 9 and 30 are zero-force verticals unless their bottom joint is loaded
    ("s17", ["strain:9"], ["8:y"], False),
    ("s17", ["acc:4:y", "strain:9"], ["8:y"], False),
    ("s17", ["strain:30"], ["4:y"], False),
    ("s17", ["strain:30"], ["16:y"], True),
    ("s17", ["strain:9"], ["4:y"], True),
    ("s17", ["strain:9", "strain:30"], ["6:y"], False),
    ("s17", ["strain:13"], ["8:y"], True),
    ("s17", ["strain:9", "strain:30", "acc:6:y", "acc:6:x"], ["6:y"], False),
    ("s17", ZERO_FORCE_SET, FORCES4, False),                          # f4 - 2 f6 + f8 unseen
    ("s17", ZERO_FORCE_SET[:-1] + ["strain:14"], FORCES4, True),
    ("s17", CASE4, FORCES4, True),
    ("s17", ["strain:4", "strain:5", "strain:9", "strain:12", "strain:13", "strain:16", "strain:21",
             "strain:24", "strain:26"], FORCES4, True),
    ("s17", ACC_ONLY, FORCES4, False),
    ("s17", ACC_ONLY + ["strain:9"], FORCES4, False),
    ("s17", ["acc:4:y", "acc:6:y", "acc:8:y", "acc:12:y", "acc:6:x", "strain:9"], FORCES4, False),
    ("s17", ["disp:8:y", "disp:4:y", "disp:12:y", "disp:6:y"], FORCES4, True),
    ("s17", ["disp:8:y", "disp:10:y"], ["8:y", "10:y"], True),       # mirror-symmetric pair
    ("s17", ["disp:8:y", "disp:10:y"], ["4:y", "14:y"], True),
    ("s17", ["disp:8:y", "disp:10:y"], ["4:y", "14:y", "6:y"], False),
    ("s17", ["strain:1"], ["2:x"], None),
    ("s17", ["strain:34"], ["2:x"], None),
    ("s17", ["strain:5", "strain:9", "strain:13", "strain:26"], FORCES4, True),
    # thesis plate, clamped along y = 0 (nodes 1-11): e_x vanishes along the clamp
    ("th", ["strain:2:ex"], ["121:w"], False),
    ("th", ["strain:2:gxy"], ["121:w"], True),
    ("th", ["acc:12:w"], ["121:w"], False),
    ("th", ["strain:2:gxy", "strain:100:gxy"], ["121:w", "111:w"], True),
    ("th", ["strain:2:ey", "strain:58:ex", "strain:100:ey"], ["121:w", "111:w"], True),
    ("th", ["strain:2:ex", "strain:6:ex", "acc:12:w"], ["121:w", "111:w"], False),
    # mid-line x = lx/2 (nodes 6, 17, ..., 116): e_x there is blind to the antisymmetric pair f111 - f121
    ("th", ["strain:116:ex", "strain:61:ex"], ["121:w", "111:w"], False),
    ("th", ["strain:116:ex", "strain:61:gxy"], ["121:w", "111:w"], True),
    # the flexible thesis plate (condition ~4e10): the hardest case for a rounding bound
    ("flex", ["strain:2:gxy", "strain:100:gxy"], ["121:w", "111:w"], True),
    ("flex", ["strain:2:gxy", "acc:12:w"], ["121:w", "111:w"], False),
    ("flex", ["strain:6:ex"], ["121:w"], False),
    ("flex", ["strain:2:ey", "strain:58:ex", "strain:100:ey"], ["121:w", "111:w"], True),
    # IMP plate, clamped along x = lx (nodes 6, 12, ..., 36)
    ("imp", ["strain:12:ey"], ["21:w"], False),
    ("imp", ["strain:20:ex"], ["21:w"], True),
    ("imp", ["strain:20:ex", "strain:9:ey", "acc:14:w"], ["21:w", "15:w"], True),
]

_BUILDERS = {"s17": s17_truss, "th": th_plate, "imp": imp_plate, "flex": lambda: build_structure(TH_FLEXIBLE_PLATE)}
FACTORS = np.round(np.arange(1.00, 1.1001, 0.01), 2)


def _perturbed(structure, rng, size=1e-13):
    """K and M with a random symmetric relative perturbation of every entry."""
    def sym(n):
        E = rng.uniform(-1, 1, size=(n, n))
        return 0.5 * (E + E.T)
    n = structure.n
    return structure._replace(K=structure.K * (1 + size * sym(n)), M=structure.M * (1 + size * sym(n)))


@pytest.fixture(scope="module")
def variants():
    """Per structure: the model as built, then one perturbed copy per stiffness factor."""
    rng = np.random.default_rng(2026)
    out = {}
    for name, build in _BUILDERS.items():
        base = build()
        out[name] = [base] + [_perturbed(base.scaled(f), rng) for f in FACTORS]
    return out


def test_at_least_thirty_layouts():
    assert len(LAYOUTS) >= 30


@pytest.mark.parametrize("name,sensors,forces,expected", LAYOUTS,
                         ids=[f"{n}-{'+'.join(s)[:40]}-{'+'.join(f)}" for n, s, f, _ in LAYOUTS])
def test_verdict_is_stable_under_rounding_perturbations(variants, name, sensors, forces, expected):
    verdicts = [detectability(s, sensors, forces).detectable for s in variants[name]]
    assert len(set(verdicts)) == 1, f"verdict flips across perturbations/stiffness factors: {verdicts}"
    if expected is not None:
        assert verdicts[0] == expected


def test_zero_force_member_is_undetectable_for_every_stiffness_factor():
    """The issue's reproduction: member 9 sees rounding noise (~1e-23) from a load at joint 8."""
    for f in FACTORS:
        s = s17_truss().scaled(f)
        assert not detectability(s, ["strain:9"], ["8:y"]).detectable
        assert not detectability(s, ["acc:4:y", "strain:9"], ["8:y"]).detectable
        g = static_gain(s, ["strain:9", "strain:13"], ["8:y"])
        assert g.gain[0, 0] == 0.0 and g.gain[1, 0] != 0.0
        assert abs(g.gain[1, 0]) > 1e6 * g.bound[1, 0]          # a genuine response clears its bound by far


def test_static_gain_bound_is_a_bound():
    """The first-order rounding bound covers the actual error of the gain: against a solve in
    extended precision (numpy longdouble via iterative refinement) the error is below the bound."""
    s = th_plate()
    sensors = ["strain:2:gxy", "strain:58:ex", "strain:100:ey", "disp:121:w"]
    g = static_gain(s, sensors, ["121:w", "111:w"])
    from core_akf.sensors import selection_matrices
    from core_akf.statespace import force_selection
    S = selection_matrices(s, sensors)
    Sst, Sp = S["strain"] + S["disp"], force_selection(s, ["121:w", "111:w"])
    X = np.linalg.solve(s.K, Sp)
    for _ in range(3):                                  # refinement with residuals in long double
        r = (Sp.astype(np.longdouble) - s.K.astype(np.longdouble) @ X.astype(np.longdouble)).astype(float)
        X = X + np.linalg.solve(s.K, r)
    exact = Sst @ X
    nonzero = g.gain != 0
    assert np.all(np.abs(g.gain[nonzero] - exact[nonzero]) <= g.bound[nonzero])


def test_visibility_uses_weyl_bound():
    """A gain whose columns differ only by rounding counts as rank deficient; well separated
    columns count as full rank."""
    H = np.array([[1.0, 1.0 + 1e-15], [2.0, 2.0]])
    assert not StaticGain(H, np.full(H.shape, 1e-16)).sees_every_force
    assert StaticGain(np.array([[1.0, 0.5], [0.2, 1.0]]), np.full((2, 2), 1e-16)).sees_every_force
    assert not StaticGain(np.zeros((3, 1)), np.zeros((3, 1))).sees_every_force
    assert not StaticGain(np.ones((1, 2)), np.zeros((1, 2))).sees_every_force   # fewer sensors than forces


def test_zero_rows_and_supported_are_scale_free():
    s = th_plate()
    dead = zero_rows(s.strain_operator)
    labels = np.array(s.strain_labels)
    assert set(labels[dead]) == {f"strain:{i}:ex" for i in range(1, 12)}           # e_x along the clamped edge
    assert np.array_equal(zero_rows(1e-9 * s.strain_operator), dead)
    for f in (1e-6, 1.0, 1e6):
        assert is_supported(s17_truss(200e9 * f, 7800))
    import types
    free = types.SimpleNamespace(K=s17_truss().meta["K_full"], memo=lambda key, compute: compute())
    assert not is_supported(free)


def test_consumers_share_the_decision():
    """The location scan and the placement objective take the same verdicts as detectability()."""
    from impactloc.scan import ImpactModel
    s = s17_truss()
    layout = ["strain:9", "strain:13", "acc:4:y"]
    model = ImpactModel(s, layout, 1 / 1024)
    assert not model.detectable((8, "y"), [0])
    assert not model.detectable((8, "y"), [0, 2])
    assert model.detectable((8, "y"), [1])
    assert model.detectable((4, "y"), [0])
