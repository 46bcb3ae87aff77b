"""Streamed estimation of long measured records: throughput and memory (run by hand).

    python bench/stream_bench.py                 # 1 h and 24 h
    python bench/stream_bench.py --hours 1       # 1 h only (about a minute)
    python bench/stream_bench.py --hours --plate # the thesis plate only
    python bench/stream_bench.py --hours 1 24 --fatigue   # with fatigue of all 34 members as well

The S17 case-4 sensor set (5 accelerometers, 4 strain gauges; 4 unknown forces) sampled at 1 kHz
is simulated file by file -- TDMS files of 10 minutes each, written by npTDMS with DAQ channel
names and units (microstrain, g), as a monitoring system would leave them -- and then estimated by
``akf.estimate.estimate_job``, the code behind ``akf estimate``: the files read in time order,
converted to SI through the channel map, filtered chunk by chunk (65536 steps) and written to
``timeseries.parquet`` (the four forces and one strain history per step).  A thread samples the
process's resident memory (RSS) every 0.2 s.  Printed: the time to estimate, samples per second
(steps x channels), the ratio to real time, and the RSS over the run: flat means the same at a
quarter, half and the end of the run.  Results go to ``bench/stream_results.csv``.

``--fatigue``: each record again with ``[output.fatigue]`` on all 34 members (rainflow, Miner
damage and DEL of the estimated stresses, EN 1993-1-9 category 36), against the target of 100x
real time.

``--plate``: the case that held the whole record in memory before (about 21 kB per step, 2.6 GB
for 60 s at 2 kHz): the thesis plate (full model, 330 DOFs) with 6 gauges and 2 accelerometers,
60 s at 2 kHz in one Parquet file, all 363 strain outputs' RMS accumulated, 3 strain histories
written.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import threading
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DT = 1e-3
FILE_SECONDS = 600
SENSORS = ["acc:4:y", "acc:6:y", "acc:8:y", "acc:12:y", "acc:6:x", "strain:5", "strain:9", "strain:13", "strain:26"]
FORCES = ["4:y", "6:y", "8:y", "12:y"]
TARGET_REAL_TIME = 50.0


def _name(sensor):
    p = sensor.split(":")
    return f"SG{p[1]}" if p[0] == "strain" else f"ACC_{p[1]}{p[2].upper()}"


def _rss():
    """Resident memory of this process (bytes)."""
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def write_record(folder, hours, seed=0):
    """The simulated record as TDMS files of FILE_SECONDS each; returns the number of steps."""
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    from core_akf import simulate
    from core_akf.models import s17_truss
    from core_akf.sensors import parse_force_locations
    from core_akf.statespace import continuous, zoh

    truss = s17_truss()
    A, B = zoh(*continuous(truss, parse_force_locations(truss, FORCES)), DT)
    rng = np.random.default_rng(seed)
    freqs, amps = rng.uniform(0.5, 40, size=(4, 6)), rng.uniform(50, 300, size=(4, 6))
    phases = rng.uniform(0, 2 * np.pi, size=(4, 6))
    n_file = int(FILE_SECONDS / DT)
    x = None
    n_files = int(round(hours * 3600 / FILE_SECONDS))
    for i in range(n_files):
        t = (i * n_file + np.arange(n_file)) * DT
        loads = np.stack([(amps[j] * np.sin(2 * np.pi * freqs[j] * t[:, None] + phases[j])).sum(axis=1)
                          for j in range(4)], axis=1) + 100 * rng.normal(size=(n_file, 4))
        sim = simulate(truss, SENSORS, FORCES, loads, DT, absolute_noise={"strain": 1e-6, "acc": 9.80665e-3},
                       seed=rng, x0=x)
        x = A @ sim.states[-1] + B @ loads[-1]
        raw = [sim.measurements[:, j] * (1e6 if s.startswith("strain") else 1 / 9.80665) for j, s in enumerate(SENSORS)]
        with TdmsWriter(os.path.join(folder, f"rec-{i:04d}.tdms")) as w:
            w.write_segment([GroupObject("DAQ")] + [
                ChannelObject("DAQ", _name(s), v, properties={"unit_string": "microstrain" if s.startswith("strain") else "g",
                                                            "wf_increment": DT, "wf_start_offset": float(t[0])})
                for s, v in zip(SENSORS, raw)])
        print(f"\r  writing the record: file {i + 1}/{n_files}", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    return n_files * n_file


def job(folder, fatigue=False):
    out = {"name": "stream-bench", "dt": DT, "sensors": SENSORS, "forces": FORCES,
            "structure": {"model": "s17_truss"},
            "filter": {"stiffness_factor": 1.05, "model_error_cov": 1e-16, "force_increment_cov": 1e5,
                       "noise_cov": {"acc": 1e-4, "strain": 1e-12}},
            "measurements": {"file": os.path.join(folder, "*.tdms"), "channels": {_name(s): s for s in SENSORS}},
            "output": {"format": "parquet", "strains": ["strain:13"]}}
    if fatigue:
        out["output"]["fatigue"] = {"detail_category": 36}
    return out


def run(hours, base, fatigue=False):
    from akf.estimate import estimate_job
    from akf.job import Job

    folder = os.path.join(base, f"record-{hours:g}h")
    out = os.path.join(base, f"out-{hours:g}h")
    os.makedirs(folder, exist_ok=True)
    t0 = time.perf_counter()
    n = write_record(folder, hours)
    t_write = time.perf_counter() - t0
    samples, stop = [], threading.Event()

    def sample():
        start = time.perf_counter()
        while not stop.is_set():
            samples.append((time.perf_counter() - start, _rss()))
            stop.wait(0.2)
    rss_before = _rss()
    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    t0 = time.perf_counter()
    res = estimate_job(Job.from_dict(job(folder, fatigue), "estimate"), out, plot=False)
    elapsed = time.perf_counter() - t0
    stop.set()
    sampler.join()
    ts, rss = np.array(samples).T
    at = {q: float(rss[np.searchsorted(ts, q * ts[-1]).clip(0, len(rss) - 1)]) for q in (0.25, 0.5, 0.75, 1.0)}
    size = sum(os.path.getsize(os.path.join(folder, f)) for f in os.listdir(folder))
    out_size = sum(os.path.getsize(os.path.join(out, "timeseries.parquet", f))
                   for f in os.listdir(os.path.join(out, "timeseries.parquet")))
    row = {"hours": hours, "steps": n, "channels": len(SENSORS), "files": len(os.listdir(folder)),
           "record_GB": size / 1e9, "output_GB": out_size / 1e9, "write_record_s": t_write, "estimate_s": elapsed,
           "samples_per_s": n * len(SENSORS) / elapsed, "steps_per_s": n / elapsed,
           "x_real_time": n * DT / elapsed, "rss_before_MB": rss_before / 1e6,
           **{f"rss_at_{int(q * 100)}pct_MB": v / 1e6 for q, v in at.items()}, "rss_peak_MB": float(rss.max()) / 1e6,
           "rss_growth_25_to_100pct_MB": (at[1.0] - at[0.25]) / 1e6, "peak_force_4y_N": res.metrics["forces"][0]["peak"]}
    if fatigue:
        damage = [o["damage"] for o in res.metrics["fatigue"]["outputs"]]
        row |= {"fatigue_outputs": len(damage), "max_damage": max(damage)}
    shutil.rmtree(folder)
    shutil.rmtree(out)
    return row


def run_plate(base, seconds=60.0, dt=5e-4):
    """The thesis plate, ``seconds`` at 1/dt Hz, streamed from one Parquet file."""
    import pandas as pd

    from akf.estimate import estimate_job
    from akf.job import Job
    from core_akf import simulate
    from core_akf.models import th_plate

    plate = th_plate()
    sensors = ["strain:58:ex", "strain:62:ey", "strain:80:gxy", "strain:100:ex", "strain:104:ey", "strain:120:ex",
               "acc:60:w", "acc:110:w"]
    forces = ["99:w"]
    n = int(round(seconds / dt))
    t = np.arange(n) * dt
    loads = (200 * np.sin(2 * np.pi * 7 * t) + 50 * np.random.default_rng(0).normal(size=n))[:, None]
    t0 = time.perf_counter()
    sim = simulate(plate, sensors, forces, loads, dt, relative_noise=0.02, seed=0)
    path = os.path.join(base, "plate.parquet")
    pd.DataFrame({"time": t} | {s: sim.measurements[:, j] for j, s in enumerate(sensors)}).to_parquet(path)
    t_write = time.perf_counter() - t0
    del sim
    job = {"name": "plate", "dt": dt, "sensors": sensors, "forces": forces, "structure": {"model": "th_plate"},
           "filter": {"model_error_cov": 1e-16, "force_increment_cov": 1e2,
                      "noise_cov": {"strain": 1e-14, "acc": 1e-2}},
           "measurements": {"file": path}, "output": {"format": "parquet", "strains": sensors[:3]}}
    out = os.path.join(base, "out-plate")
    samples, stop = [], threading.Event()

    def sample():
        while not stop.is_set():
            samples.append(_rss())
            stop.wait(0.2)
    rss_before = _rss()
    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    t0 = time.perf_counter()
    estimate_job(Job.from_dict(job, "estimate"), out, plot=False)
    elapsed = time.perf_counter() - t0
    stop.set()
    sampler.join()
    shutil.rmtree(out)
    os.remove(path)
    return {"case": "th_plate 60 s at 2 kHz", "steps": n, "channels": len(sensors), "write_record_s": t_write,
            "estimate_s": elapsed, "x_real_time": n * dt / elapsed, "rss_before_MB": rss_before / 1e6,
            "rss_peak_MB": max(samples) / 1e6}


def main(argv=None):
    import pandas as pd

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, nargs="*", default=[1.0, 24.0], help="record lengths (none: skip)")
    parser.add_argument("--plate", action="store_true", help="also the thesis plate, 60 s at 2 kHz")
    parser.add_argument("--fatigue", action="store_true", help="also with fatigue on all 34 members")
    parser.add_argument("--no-baseline", action="store_true", help="with --fatigue: only the runs with fatigue")
    parser.add_argument("--data", help="folder for the simulated record (default a temporary one; 24 h take ~7 GB)")
    args = parser.parse_args(argv)
    base = args.data or tempfile.mkdtemp(prefix="akf-stream-")
    os.makedirs(base, exist_ok=True)
    rows = []
    kinds = ((True,) if args.no_baseline else (False, True)) if args.fatigue else (False,)
    for hours, fatigue in [(h, f) for h in args.hours for f in kinds]:
        row = run(hours, base, fatigue)
        rows.append({"case": f"S17 case-4 set, {hours:g} h at 1 kHz" + (", fatigue of 34 members" if fatigue else "")}
                    | row)
        target = 100.0 if fatigue else TARGET_REAL_TIME
        print(f"{hours:g} h at 1 kHz ({row['steps']:,} steps x {row['channels']} channels, {row['files']} TDMS files, "
              f"{row['record_GB']:.2f} GB): estimated in {row['estimate_s']:.1f} s = {row['samples_per_s'] / 1e6:.2f} M "
              f"samples/s, {row['x_real_time']:.0f}x real time (target >= {target:g}x: "
              f"{'met' if row['x_real_time'] >= target else 'NOT met'})" + (" with fatigue of all 34 members" if fatigue
                                                                           else ""))
        print(f"  RSS before {row['rss_before_MB']:.0f} MB; at 25/50/75/100 % of the run "
              + " / ".join(f"{row[f'rss_at_{p}pct_MB']:.0f}" for p in (25, 50, 75, 100))
              + f" MB; peak {row['rss_peak_MB']:.0f} MB; growth from 25 % to the end {row['rss_growth_25_to_100pct_MB']:+.1f} MB")
    if args.plate:
        row = run_plate(base)
        rows.append(row)
        print(f"{row['case']} ({row['steps']:,} steps, full model of 330 DOFs): estimated in {row['estimate_s']:.1f} s, "
              f"{row['x_real_time']:.1f}x real time; RSS before {row['rss_before_MB']:.0f} MB, peak "
              f"{row['rss_peak_MB']:.0f} MB (the whole record in memory took about 2.6 GB)")
    path = os.path.join(HERE, "stream_results.csv")
    table = pd.DataFrame(rows)
    if os.path.exists(path):           # keep the other cases of an earlier run
        old = pd.read_csv(path)
        table = pd.concat([old[~old["case"].isin(table["case"])], table], ignore_index=True)
    table.to_csv(path, index=False)
    print(f"wrote {path}")
    if not args.data:
        shutil.rmtree(base, ignore_errors=True)


if __name__ == "__main__":
    main()
