"""akf estimate on the S17 case-4 record as a CSV file with holes: about 5 % of the samples missing
in random channel blocks and one gauge dead for a tenth of the record."""
import numpy as np
import pandas as pd
import pytest
from helpers import run_estimate

from akf.examples import example_job
from akf.job import Job

FORCES = ["4:y", "6:y", "8:y", "12:y"]


@pytest.fixture(scope="module")
def case4(tmp_path_factory):
    """The record, complete and with holes, as CSV files; the true loads."""
    data = example_job("s17-case4")
    job = Job.from_dict(data, "estimate")
    sim = job.simulate()
    loads = job.loads(sim.measurements.shape[0])
    N = sim.measurements.shape[0]
    holes, rng = sim.measurements.copy(), np.random.default_rng(1)
    holes[int(0.6 * N):int(0.7 * N), data["sensors"].index("strain:9")] = np.nan       # dead for 0.2 s
    while np.isnan(holes).mean() < 0.05 + 0.1 / 9:
        j, a = rng.integers(holes.shape[1]), rng.integers(0, N - 50)
        holes[a:a + rng.integers(1, 50), j] = np.nan
    folder = tmp_path_factory.mktemp("case4")
    jobs = {}
    for name, Y in (("complete", sim.measurements), ("holes", holes)):
        frame = pd.DataFrame(Y, columns=data["sensors"])
        frame.insert(0, "time", np.arange(N) * data["dt"])
        frame.to_csv(folder / f"{name}.csv", index=False, float_format="%.17g", na_rep="")
        measured = {k: v for k, v in data.items() if k != "simulation"}
        measured["filter"] = dict(data["filter"], noise_cov=[float(v) ** 2 for v in sim.noise_std])
        measured["measurements"] = {"file": str(folder / f"{name}.csv"), "chunk": 0.25}
        jobs[name] = measured
    return jobs, loads, holes, folder


def _forces(out):
    ts = pd.read_csv(out / "timeseries.csv")
    f = ts[ts.quantity == "force"]
    return np.column_stack([f[f.channel == c].estimated.to_numpy() for c in FORCES])


@pytest.mark.parametrize("steady", [None, False])
def test_a_record_with_holes_completes_and_names_what_it_could_not_see(case4, steady):
    jobs, loads, holes, folder = case4
    errors = {}
    for name in ("complete", "holes"):
        job = dict(jobs[name], filter=dict(jobs[name]["filter"]) | ({} if steady is None else {"steady": steady}))
        res = run_estimate(job, str(folder / f"{name}-{steady}"), plot=False)
        assert res.complete
        F = _forces(folder / f"{name}-{steady}")
        assert F.shape == loads.shape and np.isfinite(F).all()        # every force at every step
        errors[name] = float(np.sqrt(np.mean((F - loads) ** 2)))
    sensors = {d["channel"]: d for d in res.metrics["sensors"]}
    for j, label in enumerate(jobs["holes"]["sensors"]):
        assert sensors[label]["missing_fraction"] == pytest.approx(np.isnan(holes[:, j]).mean())
    assert sensors["strain:9"]["longest_missing_s"] >= 0.2
    summary = pd.read_csv(folder / f"holes-{steady}" / "summary.csv")
    assert summary[summary.quantity == "sensor"].missing_spans.min() >= 1
    warned = [w for w in res.metrics["warnings"] if "strain:9 missing; the remaining set is not detectable" in w]
    assert len(warned) == 1 and "t = 1.19" in warned[0]
    # Every gauge is needed to see the static response of the four forces: a hole in any gauge leaves
    # the set undetectable, and the forces drift on their random-walk prior there.  Measured: 1.94x the
    # complete record's RMS error with the steady filter, 1.59x with the exact one (the 1.10x
    # is not reached; see docs/guide/real-records.md).
    ratio = errors["holes"] / errors["complete"]
    assert 1.0 < ratio < (2.1 if steady is None else 1.75)


def test_a_channel_never_observed_is_dropped_or_the_job_refused(case4, tmp_path):
    from core_akf.checks import AKFInputError

    jobs, _, _, folder = case4
    frame = pd.read_csv(folder / "complete.csv")
    frame["acc:6:x"] = np.nan                                      # one accelerometer of five: dropped
    frame.to_csv(tmp_path / "dead.csv", index=False, float_format="%.17g", na_rep="")
    job = dict(jobs["complete"], measurements={"file": str(tmp_path / "dead.csv"), "chunk": 0.25})
    res = run_estimate(job, str(tmp_path / "out"), plot=False)
    assert res.complete and [d["channel"] for d in res.metrics["sensors"]] == [
        s for s in jobs["complete"]["sensors"] if s != "acc:6:x"]
    assert any(w.startswith("channel acc:6:x has no observed sample") and "dropped" in w for w in res.metrics["warnings"])
    for gauge in ("strain:5", "strain:9", "strain:13", "strain:26"):              # every gauge: refused
        frame[gauge] = np.nan
    frame.to_csv(tmp_path / "no-gauges.csv", index=False, float_format="%.17g", na_rep="")
    job = dict(jobs["complete"], measurements={"file": str(tmp_path / "no-gauges.csv")})
    with pytest.raises(AKFInputError, match="every sample of strain:5, strain:9, strain:13, strain:26 is missing"):
        run_estimate(job, str(tmp_path / "out2"), plot=False)
