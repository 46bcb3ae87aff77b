"""Operational modal analysis (SSI-cov): the poles equal pyOMA2's SSI-cov on the same record, the
identified modes of an ambient S17 record are the model's (frequency and MAC), and bad records
are named."""
import numpy as np
import pytest

from core_akf import AKFInputError
from core_akf.loads import band_limited_white_noise
from core_akf.models import s17_truss
from core_akf.oma import hankel, mac, pair_modes, ssi_cov
from core_akf.sensors import as_layout, selection_matrices
from core_akf.simulate import simulate

DT = 1.0 / 1024
ACC = [f"acc:{n}:y" for n in (2, 4, 6, 8, 10, 12, 14, 16)] + ["acc:6:x", "acc:12:x"]


@pytest.fixture(scope="module")
def ambient():
    """60 s of ten accelerometers on the S17 truss under three band-limited random loads (not
    white: their band edge at 300 Hz adds poles of its own)."""
    s = s17_truss()
    n = int(60 / DT)
    loads = np.column_stack([band_limited_white_noise(n, DT, 100.0, 0.0, 300.0, seed=k) for k in range(3)])
    sim = simulate(s, ACC, ["4:y", "8:y", "14:y"], loads, DT, relative_noise=0.02, seed=1)
    return s, sim.measurements


def test_poles_equal_pyoma2_ssi_cov(ambient):
    ssi = pytest.importorskip("pyoma2.functions.ssi")
    _, Y = ambient
    res = ssi_cov(Y, DT, channels=ACC, block_rows=30, max_order=60)
    Yc = (Y - Y.mean(axis=0)).T
    H, _ = ssi.build_hank(Yc, Yc, 30, "cov")
    assert np.allclose(hankel(Y - Y.mean(axis=0), 30), H, rtol=1e-12, atol=0)
    Obs, A, C, _ = ssi.SSI_fast(H, 30, 60, step=2)
    Fn, Xi = ssi.SSI_poles(Obs, A, C, 60, DT, step=2)[:2]
    for order in (10, 20, 40, 60):
        ours = res.poles[res.poles["order"] == order].sort_values("frequency_hz")
        col = Fn[:, order // 2]
        theirs = np.sort(col[np.isfinite(col)])
        assert ours["frequency_hz"].to_numpy() == pytest.approx(theirs, rel=1e-9)
        damp = Xi[:, order // 2]
        assert np.sort(ours["damping"].to_numpy()) == pytest.approx(np.sort(damp[np.isfinite(damp)]), rel=1e-7)


def test_ambient_modes_are_the_models(ambient):
    s, Y = ambient
    res = ssi_cov(Y, DT, channels=ACC, block_rows=30, max_order=60)
    k = 8
    shapes = (selection_matrices(s, as_layout(ACC))["acc"] @ s.modes(k)).T      # (k, channels)
    paired = pair_modes(res, s.frequencies(k), shapes, min_mac=0.9)
    found = paired.dropna(subset=["model_frequency_hz"])
    assert set(found["model_mode"]) >= {1, 2, 3, 4, 5}                          # the modes inside the load band
    assert np.all(np.abs(found["frequency_ratio"] - 1) < 0.003)                 # within 0.3 %
    assert np.all(np.abs(found["damping"] - 0.007) < 0.002)                     # the model's damping
    assert found["model_mode"].is_unique
    assert mac(shapes[0], shapes[0]) == pytest.approx(1.0) and mac(shapes[0], shapes[1]) < 0.5


@pytest.mark.parametrize("record, message", [
    (np.ones((5000, 1)), "at least 2 channels"),
    (np.where(np.arange(10000)[:, None] == 7, np.nan, np.ones((10000, 2))), "missing"),
    (np.random.default_rng(0).normal(size=(300, 3)), "too short"),
])
def test_bad_records_are_named(record, message):
    with pytest.raises(AKFInputError, match=message):
        ssi_cov(record, DT, block_rows=20, max_order=20)


@pytest.mark.parametrize("change, message", [
    (dict(block_rows=10.5), "block_rows must be a whole number >= 2, got 10.5"),
    (dict(block_rows=0), "block_rows must be a whole number >= 2, got 0"),
    (dict(max_order="20"), "max_order must be a whole number >= 2, got '20'"),
    (dict(dt="0.01"), "dt must be a positive number of seconds, got '0.01'"),
    (dict(channels="ab"), "channels must be a list of channel names, got str"),
    (dict(channels=2), "channels must be a list of channel names, got int"),
    (dict(constant=1), r"channel\(s\) \['ch2'\] are constant: they hold no vibration"),
    (dict(true_false=1), "must be numeric .*, not true/false values"),
    (dict(block_rows=10, max_order=20), r"max_order must be between 2 and \(block_rows - 1\) x channels = 18, got 20"),
])
def test_bad_arguments_are_named(change, message):
    """Each ended in numpy's TypeError or LinAlgError (a constant channel: "Singular matrix"; an order
    between (block_rows - 1) x channels and block_rows x channels, which the old bound let through:
    "Last 2 dimensions of the array must be square")."""
    dt = 0.01
    Y = _two_modes(20000, dt, 5.0, 12.0)
    if change.pop("constant", None):
        Y[:, 1] = 0.25
    if change.pop("true_false", None):
        Y = Y > 0
    kw = dict(block_rows=30, max_order=20) | change
    with pytest.raises(AKFInputError, match=message):
        ssi_cov(Y, kw.pop("dt", dt), **kw)
    assert len(ssi_cov(_two_modes(20000, dt, 5.0, 12.0), dt, block_rows=10, max_order=18).modes) == 2


def _two_modes(n, dt, f1, f2, seed=0):
    """Two lightly damped modes driven by white noise, seen by two channels."""
    import scipy.signal

    rng = np.random.default_rng(seed)

    def mode(f, zeta):
        w = 2 * np.pi * f
        b, a = scipy.signal.cont2discrete(([1.0], [1.0, 2 * zeta * w, w * w]), dt)[:2]
        return scipy.signal.lfilter(b.ravel(), a, rng.normal(size=n))

    q1, q2 = mode(f1, 0.02), mode(f2, 0.01)
    return np.column_stack([q1 + q2, q1 - 0.5 * q2]) + 1e-4 * rng.normal(size=(n, 2))


def test_a_record_shorter_than_twenty_periods_of_its_lowest_mode_is_refused():
    dt = 0.01
    ok = ssi_cov(_two_modes(20000, dt, 5.0, 12.0), dt, block_rows=30, max_order=20)
    assert ok.modes["frequency_hz"].to_numpy() == pytest.approx([5.0, 12.0], rel=0.005)
    with pytest.raises(AKFInputError, match="fewer than 20 periods of its lowest mode"):
        ssi_cov(_two_modes(1500, dt, 1.0, 12.0), dt, block_rows=30, max_order=20)     # 15 s: 15 periods at 1 Hz
