"""The steady filter's force transfer function (issue 34, item 7) against the filter itself run on
sinusoidal loads, and what it says of accelerometers and gauges."""
import numpy as np
import pytest

from core_akf import simulate
from core_akf.checks import AKFInputError
from core_akf.filter import Filter, force_transfer, recovered_band, run_filter
from core_akf.forcemodels import ForceModel
from core_akf.models import s17_truss

DT = 1 / 1024
FORCES = ["6:y", "12:y"]


def _filter(sensors, force_model, hold="zero"):
    fm = ForceModel(force_model[0], hold=hold, **force_model[1])
    return Filter(s17_truss(), [sensors], FORCES, DT, model_error_cov=1e-16, force_model=fm,
                  noise_cov={"strain": 1e-14, "acc": 1e-4})


def _measured_response(f, freq, force, hold):
    """The complex amplitude of each force estimate from a unit cosine of ``force`` at ``freq``
    (the filter run on the noise-free record, its transient dropped, fitted by least squares)."""
    n = 6144
    t = np.arange(n) * DT
    P = np.zeros((n, len(FORCES)))
    P[:, force] = np.cos(2 * np.pi * freq * t)
    Y = simulate(s17_truss(), f.layouts[0], FORCES, P, DT, load_hold=hold).clean
    est = run_filter(f, Y[None])[0].forces[n // 2:]
    basis = np.column_stack([np.cos(2 * np.pi * freq * t[n // 2:]), -np.sin(2 * np.pi * freq * t[n // 2:])])
    coef = np.linalg.lstsq(basis, est, rcond=None)[0]            # (2, n_p): real and imaginary parts
    return coef[0] + 1j * coef[1]


@pytest.mark.parametrize("sensors, model, hold", [
    (["strain:13", "strain:5", "acc:8:y", "acc:4:y"], ("random_walk", dict(increment_cov=1e4)), "zero"),
    (["acc:8:y", "acc:6:y", "acc:4:y", "acc:12:y", "acc:9:y"], ("matern32", dict(std=300.0, timescale=5e-3)), "zero"),
    (["strain:13", "strain:5", "acc:8:y", "acc:4:y"], ("random_walk", dict(increment_cov=1e4)), "linear"),
])
def test_the_transfer_function_is_what_the_filter_does_to_a_sinusoid(sensors, model, hold):
    f = _filter(sensors, model, hold)
    freqs = [3.0, 41.0, 160.0]
    T = force_transfer(f, freqs)[0]
    for i, freq in enumerate(freqs):
        for force in range(len(FORCES)):
            got = _measured_response(f, freq, force, hold)
            np.testing.assert_allclose(got, T[i, :, force], rtol=0, atol=2e-6 * max(1.0, np.abs(T[i]).max()))


def test_accelerometers_miss_the_static_part_and_gauges_see_it():
    """An accelerometer-only layout under a Matérn prior recovers nothing of a static force, and
    the band it recovers narrows as its noise grows (measured: 1-512 Hz at 0.01 m/s^2 noise,
    4.5-357 Hz at 1 m/s^2, none at 10 m/s^2); a layout with gauges under the random walk
    recovers a force from 0 Hz."""
    freqs = np.linspace(0.0, 0.5 / DT, 1025)
    bands = []
    for noise in (1e-4, 1.0, 100.0):
        acc = Filter(s17_truss(), [["acc:8:y", "acc:6:y", "acc:4:y", "acc:12:y", "acc:9:y"]], FORCES, DT,
                     model_error_cov=1e-16, force_model=ForceModel("matern32", std=300.0, timescale=5e-3),
                     noise_cov={"acc": noise})
        T_acc = np.abs(np.diagonal(force_transfer(acc, freqs)[0], axis1=1, axis2=2))
        assert np.all(T_acc[0] < 1e-6)                          # a static load: nothing
        bands.append(recovered_band(freqs, T_acc[:, 0]))
    assert bands[0][0] > 0.0 and bands[1][0] > 3 * bands[0][0] and bands[1][1] < bands[0][1] and bands[2] is None
    gauges = _filter(["strain:13", "strain:5", "acc:8:y", "acc:4:y"], ("random_walk", dict(increment_cov=1e4)))
    T_gauge = np.abs(np.diagonal(force_transfer(gauges, freqs)[0], axis1=1, axis2=2))
    assert np.all(np.abs(T_gauge[0] - 1.0) < 1e-6)              # seen exactly
    assert recovered_band(freqs, T_gauge[:, 0])[0] == 0.0


def test_bad_input_is_named():
    f = _filter(["strain:13", "strain:5", "acc:8:y"], ("random_walk", dict(increment_cov=1e4)))
    with pytest.raises(AKFInputError, match="Nyquist"):
        force_transfer(f, [600.0])
    with pytest.raises(AKFInputError, match="Nyquist"):
        force_transfer(f, [-1.0])
    und = Filter(s17_truss(), [["acc:8:y", "acc:4:y"]], FORCES, DT, model_error_cov=1e-16, force_increment_cov=1e4,
                 noise_cov={"acc": 1e-4}, allow_undetectable=True, steady=False)
    with pytest.raises(AKFInputError, match="undetectable"):
        force_transfer(und, [1.0])
    assert recovered_band([1.0, 2.0], [0.0, 0.1]) is None


def test_akf_show_transfer_of_a_job(tmp_path, capsys):
    """``akf show JOB --transfer``: accelerometers only see nothing of a static force and recover
    from a few Hz (s17-acc: 3.9-1571 Hz); gauges see every force from 0 Hz (s17-case4); the
    figure is written."""
    import json
    from pathlib import Path

    import akf
    from akf.cli import main

    seen = {}
    for name in ("s17-acc", "s17-case4"):
        path = Path(akf.__file__).parent / "examples" / "jobs" / f"{name}.toml"
        assert main(["show", str(path), "--transfer", "--json", "--out", str(tmp_path)]) == 0
        info = json.loads(capsys.readouterr().out)
        seen[name] = {r["force"]: r for r in info["forces"]}
        assert (tmp_path / f"{name}-transfer.png").stat().st_size > 0
    for r in seen["s17-acc"].values():
        assert r["static_gain"] < 1e-9 and 2.0 < r["recovered_band_hz"][0] < 6.0 and r["max_cross_talk"] < 0.1
    for r in seen["s17-case4"].values():
        assert abs(r["static_gain"] - 1.0) < 1e-6 and r["recovered_band_hz"][0] == 0.0
    assert main(["show", "s17_truss", "--transfer"]) == 2
    assert "needs a job file of akf estimate" in capsys.readouterr().err
