"""S17 (Khodabandeloo, Melvin, Jo, Sensors 2017) findings on the built-in cases.

The paper's Fig. 19 orders the RMS force errors (eq. 38): acceleration-only >> strain-only
> multi-metric.  S17 does not publish load amplitudes, so we assert the ordering and the
instability, not absolute values.
"""
import numpy as np
import pytest
from helpers import run_estimate

from akf.examples import example_job


@pytest.fixture(scope="module")
def s17_results():
    return {name: run_estimate(example_job(name), allow_undetectable=True)
            for name in ("s17-case1", "s17-case2", "s17-case3", "s17-case4")}


def _rms(result):
    return np.array(list(result.metrics["rms_force"].values()))


def test_s17_case4_multimetric_beats_strain_only(s17_results):
    """Fig. 19: multi-metric (case 4) has the lowest force error at every load location."""
    c3, c4 = _rms(s17_results["s17-case3"]), _rms(s17_results["s17-case4"])
    assert np.all(c4 < c3)
    assert c4.mean() < 0.7 * c3.mean()


def test_s17_case2_flagged_and_far_worse(s17_results):
    """Case 2 (accelerations only, 5 % model error, 2 % noise): undetectable; forced, it drifts."""
    c2, c3 = s17_results["s17-case2"], s17_results["s17-case3"]
    assert not c2.metrics["detectable"]
    assert np.all(_rms(c2) > 2.5 * _rms(c3))
    assert _rms(c2).mean() > 4 * _rms(s17_results["s17-case4"]).mean()


def test_s17_case2_error_grows_with_record_length():
    """The drift of the undetectable filter grows with time; the detectable one does not."""
    def err(name, duration):
        job = example_job(name)
        job["simulation"]["duration"] = duration
        job["filter"]["steady"] = False
        return _rms(run_estimate(job, allow_undetectable=True)).mean()

    assert err("s17-case2", 4.0) > 1.3 * err("s17-case2", 1.0)
    assert err("s17-case4", 4.0) < 1.3 * err("s17-case4", 1.0)


def test_s17_case1_fine_without_errors(s17_results):
    """Case 1: accelerations only are fine for zero-mean loads without model error and noise."""
    c1 = s17_results["s17-case1"]
    assert not c1.metrics["detectable"]
    load_rms = np.sqrt(np.mean(c1.simulation.loads ** 2, axis=0))
    assert np.all(_rms(c1) < 0.05 * load_rms)


def test_s17_steady_equals_time_varying_case4():
    job = example_job("s17-case4")
    tv = run_estimate(job, steady=False)
    ss = run_estimate(job, steady=True)
    assert np.allclose(_rms(tv), _rms(ss), rtol=0.01)   # they differ only in the transient (~1 % of 2 s)
