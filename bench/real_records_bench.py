"""Real records, measured: missing samples, mixed rates and sensor faults on the S17 case-4 filter.

Run by hand (``python bench/real_records_bench.py``); prints its tables, then draws
``docs/figures/real-records-gap.png`` (the smoothed forces with their bands across a gap).

1. Throughput of the steady filter (``core_akf.filter.kernels.steady``) on 60 s at 4096 Hz:
   complete; 5 % of the samples missing in random channel blocks (1-50 steps); 5 % of the steps
   missing on every channel (dropouts).  The ratio is the complete record's time over each.
2. Accuracy on the 2 s case-4 record with the holes of the tests: the force RMS error of the
   complete record, the exact (time-varying) filter and the steady filter with cached gains.
3. Mixed rates: accelerometers at 4096 Hz and gauges at 256 Hz, 60 s in two files: read from
   Parquet and streamed through ``core_akf.filter.Estimator``, and from CSV through ``akf estimate``
   (reading, filtering, checking, writing): times real time.
4. Faults injected into case 4 (a stuck accelerometer, spikes, clipping at 80 %, a drifting
   gauge): found samples and false alarms per kind, and the force error with "flag" and "drop".
"""
import os
import sys
import tempfile
import time

import numpy as np
import pandas as pd

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))

from helpers import run_estimate  # noqa: E402

from akf.examples import example_job  # noqa: E402
from akf.job import Job  # noqa: E402
from core_akf.filter import Estimator, kernels  # noqa: E402
from core_akf.filter.model import Filter  # noqa: E402
from core_akf.io import open_record  # noqa: E402
from core_akf.sensors import as_layout, parse_force_locations  # noqa: E402

DATA = example_job("s17-case4")
LABELS, FORCES, DT = DATA["sensors"], DATA["forces"], DATA["dt"]


def holes(Y, fraction, seed, longest=50, dead=None):
    """Random blocks of missing samples, one channel each (and a dead channel ``(j, a, b)``)."""
    rng, Y = np.random.default_rng(seed), Y.copy()
    if dead is not None:
        Y[dead[1]:dead[2], dead[0]] = np.nan
    while np.isnan(Y).mean() < fraction:
        j, a = rng.integers(Y.shape[1]), rng.integers(0, Y.shape[0] - longest)
        Y[a:a + rng.integers(1, longest), j] = np.nan
    return Y


def best(fn, repeat=3):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def throughput():
    s = Job.from_dict(DATA, "estimate").structure.scaled(1.05)
    f = Filter(s, [as_layout(LABELS)], parse_force_locations(s, FORCES), DT, model_error_cov=1e-16,
               force_increment_cov=1e5, noise_cov={"acc": 0.2, "strain": 4e-14})
    N = int(60 / DT)
    Y = np.random.default_rng(0).normal(size=(N, len(LABELS))) * np.r_[np.full(5, 0.3), np.full(4, 2e-7)]
    blocks = holes(Y, 0.05, 1)
    drop = Y.copy()
    drop[np.random.default_rng(2).random(N) < 0.05] = np.nan
    base = best(lambda: kernels.steady(f, Y[None]))
    rows = [("complete", base)]
    for name, rec in (("5 % in channel blocks", blocks), ("5 % of the steps, every channel", drop)):
        rows.append((name, best(lambda rec=rec: kernels.steady(f, rec[None]))))
    print(f"\n1. steady filter, 60 s at 4096 Hz ({N} steps, 9 channels, 70 states)")
    print(f"{'record':34s} {'time (s)':>9s} {'throughput vs complete':>23s}")
    for name, t in rows:
        print(f"{name:34s} {t:9.3f} {base / t:23.2f}")


def accuracy():
    job = Job.from_dict(DATA, "estimate")
    sim = job.simulate()
    loads = job.loads(sim.measurements.shape[0])
    N = sim.measurements.shape[0]
    s = job.structure.scaled(1.05)
    f = Filter(s, [as_layout(LABELS)], parse_force_locations(s, FORCES), DT, model_error_cov=1e-16,
               force_increment_cov=1e5, noise_cov=np.diag(sim.noise_std ** 2))
    cases = {"5 % blocks + strain:9 dead 10 %": holes(sim.measurements, 0.05 + 0.1 / 9, 1,
                                                      dead=(LABELS.index("strain:9"), int(0.6 * N), int(0.7 * N))),
             "5 % in blocks of 1-50 steps": holes(sim.measurements, 0.05, 1),
             "5 % in blocks of 1-5 steps": holes(sim.measurements, 0.05, 1, longest=5),
             "strain:9 dead 10 %": holes(sim.measurements, 0.0, 1, dead=(LABELS.index("strain:9"), int(0.6 * N),
                                                                          int(0.7 * N))),
             "gauges at 256 Hz (every 16th step)": sim.measurements.copy()}
    cases["gauges at 256 Hz (every 16th step)"][np.arange(N) % 16 != 0, 5:] = np.nan

    def err(run):
        F = run.states[0, :, f.nx:] @ f.H.T
        return float(np.sqrt(np.mean((F - loads) ** 2)))
    complete = err(kernels.steady(f, sim.measurements[None]))
    print("\n2. force RMS error on the 2 s case-4 record (N), and against the complete record")
    print(f"{'holes':34s} {'exact':>8s} {'steady':>8s} {'exact/complete':>15s} {'steady/complete':>16s}")
    print(f"{'none':34s} {complete:8.1f} {complete:8.1f}")
    for name, Y in cases.items():
        exact, steady = err(kernels.time_varying(f, Y[None])), err(kernels.steady(f, Y[None]))
        print(f"{name:34s} {exact:8.1f} {steady:8.1f} {exact / complete:15.3f} {steady / complete:16.3f}")


def accuracy_redundant(extra="strain:17"):
    """The holes of case 4 on its layout with one gauge more than forces: a hole in one gauge no
    longer leaves the static response unseen."""
    data = dict(DATA, sensors=LABELS + [extra])
    job = Job.from_dict(data, "estimate")
    sim = job.simulate()
    loads = job.loads(sim.measurements.shape[0])
    N, labels = sim.measurements.shape[0], data["sensors"]
    s = job.structure.scaled(1.05)
    f = Filter(s, [as_layout(labels)], parse_force_locations(s, FORCES), DT, model_error_cov=1e-16,
               force_increment_cov=1e5, noise_cov=np.diag(sim.noise_std ** 2))

    def err(run):
        F = run.states[0, :, f.nx:] @ f.H.T
        return float(np.sqrt(np.mean((F - loads) ** 2)))
    complete = err(kernels.steady(f, sim.measurements[None]))
    Y = holes(sim.measurements, 0.05 + 0.1 / len(labels), 1, dead=(labels.index("strain:9"), int(0.6 * N), int(0.7 * N)))
    exact, steady = err(kernels.time_varying(f, Y[None])), err(kernels.steady(f, Y[None]))
    print(f"\n2b. the same with {extra} added (5 gauges, 4 forces): complete {complete:.1f} N; 5 % blocks + strain:9 "
          f"dead 10 %: exact {exact:.1f} N ({exact / complete:.3f}x), steady {steady:.1f} N ({steady / complete:.3f}x)")


def mixed_rates(tmp):
    job = Job.from_dict(dict(DATA, simulation=dict(DATA["simulation"], duration=60.0)), "estimate")
    sim = job.simulate()
    t = np.arange(sim.measurements.shape[0]) * DT
    frame = pd.DataFrame(sim.measurements, columns=LABELS)
    frame.insert(0, "time", t)
    for kind in ("csv", "parquet"):
        folder = os.path.join(tmp, f"mixed-{kind}")
        os.makedirs(folder)
        acc, gauges = frame[["time"] + LABELS[:5]], frame[["time"] + LABELS[5:]].iloc[::16]
        if kind == "csv":
            acc.to_csv(os.path.join(folder, "acc.csv"), index=False, float_format="%.17g")
            gauges.to_csv(os.path.join(folder, "gauges.csv"), index=False, float_format="%.17g")
        else:
            acc.to_parquet(os.path.join(folder, "acc.parquet"), index=False)
            gauges.to_parquet(os.path.join(folder, "gauges.parquet"), index=False)
    noise = [float(v) ** 2 for v in sim.noise_std]
    print("\n3. mixed rates (accelerometers 4096 Hz, gauges 256 Hz), 60 s")

    def streamed():
        record = open_record(os.path.join(tmp, "mixed-parquet"), LABELS)
        s = Job.from_dict(DATA, "estimate").structure.scaled(1.05)
        est = Estimator(s, LABELS, FORCES, DT, model_error_cov=1e-16, force_increment_cov=1e5, noise_cov=noise,
                        steady=True)
        for _, Y in record.chunks(65536):
            est.update(Y)
    took = best(streamed)
    print(f"   read from Parquet and streamed through core_akf.filter.Estimator: {took:.2f} s, "
          f"{60.0 / took:.0f}x real time")
    measured = {k: v for k, v in DATA.items() if k != "simulation"}
    measured["filter"] = dict(DATA["filter"], noise_cov=noise)
    measured["measurements"] = {"file": os.path.join(tmp, "mixed-csv")}
    measured["output"] = {"strains": ["strain:13"]}
    start = time.perf_counter()
    run_estimate(measured, os.path.join(tmp, "mixed-out"), plot=False)
    took = time.perf_counter() - start
    print(f"   through akf estimate, CSV in and out (four forces and one strain written): {took:.2f} s, "
          f"{60.0 / took:.0f}x real time")


def faults(tmp, extra=None):
    """The injected faults on case 4 (``extra``: one more gauge, a layout with static redundancy)."""
    data = DATA if extra is None else dict(DATA, sensors=LABELS + [extra])
    labels = data["sensors"]
    job = Job.from_dict(data, "estimate")
    sim = job.simulate()
    loads = job.loads(sim.measurements.shape[0])
    Y, rng, N = sim.measurements.copy(), np.random.default_rng(0), sim.measurements.shape[0]
    truth = {}
    j = labels.index("acc:6:y")
    Y[int(0.3 * N):int(0.35 * N), j] = Y[int(0.3 * N), j]
    truth["stuck acc:6:y"] = (j, np.arange(int(0.3 * N), int(0.35 * N)))
    j = labels.index("acc:12:y")
    idx = rng.choice(N, 12, replace=False)
    Y[idx, j] += 10 * np.std(Y[:, j]) * rng.choice([-1, 1], 12)
    truth["spikes acc:12:y"] = (j, idx)
    j = labels.index("acc:8:y")
    rail = 0.8 * np.abs(Y[:, j]).max()
    truth["clipped acc:8:y"] = (j, np.flatnonzero(np.abs(Y[:, j]) > rail))
    Y[:, j] = np.clip(Y[:, j], -rail, rail)
    j = labels.index("strain:26")
    Y[N // 2:, j] += np.linspace(0, 1, N - N // 2) * np.std(Y[:, j])
    truth["drift strain:26"] = (j, np.arange(N // 2, N))
    faulty = np.zeros(Y.shape, bool)
    for j, idx in truth.values():
        faulty[idx, j] = True

    def run(name, record, mode):
        frame = pd.DataFrame(record, columns=labels)
        frame.insert(0, "time", np.arange(N) * DT)
        frame.to_csv(os.path.join(tmp, f"{name}{extra or ''}.csv"), index=False, float_format="%.17g")
        measured = {k: v for k, v in data.items() if k != "simulation"}
        measured["filter"] = dict(data["filter"], noise_cov=[float(v) ** 2 for v in sim.noise_std])
        measured["measurements"] = {"file": os.path.join(tmp, f"{name}{extra or ''}.csv"), "chunk": 0.25, "faults": mode}
        out = os.path.join(tmp, f"{name}{extra or ''}-{mode}")
        run_estimate(measured, out, plot=False)
        ts = pd.read_csv(os.path.join(out, "timeseries.csv"))
        f = ts[ts.quantity == "force"]
        F = np.column_stack([f[f.channel == c].estimated.to_numpy() for c in FORCES])
        flagged = np.zeros(Y.shape, bool)
        if mode != "off":
            for _, r in pd.read_csv(os.path.join(out, "data_quality.csv")).iterrows():
                a = int(round(r.start_s / DT))
                flagged[a:a + int(r.samples), labels.index(r.channel)] = True
        return float(np.sqrt(np.mean((F - loads) ** 2))), flagged
    clean_error, clean_flags = run("clean", sim.measurements, "flag")
    print("\n4. faults injected into S17 case 4 (2 s, 8192 steps)" + ("" if extra is None else f", {extra} added"))
    print(f"false alarms on the clean record: {clean_flags.mean():.4%} of the samples")
    for mode in ("flag", "drop"):
        error, flagged = run("faulty", Y, mode)
        print(f"faults = {mode!r}: force RMS error {error / clean_error:.3f}x the clean record's; false alarms "
              f"{flagged[~faulty].mean():.3%} of the clean samples")
        for name, (j, idx) in truth.items():
            print(f"   {name:18s} {len(idx):5d} faulty samples, {flagged[idx, j].mean():7.1%} flagged")


def figure():
    """The smoothed forces with their bands across a 25 ms gap of every channel (printed first, then drawn)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from core_akf.filter import estimate

    job = Job.from_dict(DATA, "estimate")
    sim = job.simulate()
    loads = job.loads(sim.measurements.shape[0])
    Y = sim.measurements.copy()
    a, b = int(0.9 / DT), int(0.925 / DT)
    Y[a:b] = np.nan
    est = estimate(job.structure.scaled(1.05), LABELS, FORCES, Y, DT, model_error_cov=1e-16, force_increment_cov=1e5,
                   noise_cov=np.diag(sim.noise_std ** 2), smooth=True)
    k = 2                                                  # force 3, 8:y
    inside, outside = est.force_std[a:b, k].mean(), est.force_std[:a, k].mean()
    print(f"\nfigure: force {FORCES[k]} band (1 sigma) {outside:.1f} N outside the gap, {inside:.1f} N inside it")
    t = est.time
    w = slice(int(0.85 / DT), int(0.975 / DT))
    fig, ax = plt.subplots(figsize=(7, 3.2))
    ax.axvspan(t[a], t[b - 1], color="0.9", zorder=0, label="every channel missing")     # behind the band
    ax.fill_between(t[w], est.forces[w, k] - 2 * est.force_std[w, k], est.forces[w, k] + 2 * est.force_std[w, k],
                    color="C0", alpha=0.3, lw=0, label="smoothed ± 2σ")
    ax.plot(t[w], loads[w, k], "k", lw=1, label="true load")
    ax.plot(t[w], est.forces[w, k], "C0", lw=1, label="smoothed estimate")
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"force {FORCES[k]} (N)")
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    path = os.path.join(ROOT, "docs", "figures", "real-records-gap.png")
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as tmp:
        throughput()
        accuracy()
        accuracy_redundant()
        mixed_rates(tmp)
        faults(tmp)
        faults(tmp, "strain:17")
    figure()
