"""Every speed ratio in one run (by hand): ``python bench/run_all.py [--csv PATH] [--skip-jobs]``.

Needs the ``bench`` extra (``pip install ".[bench]"``: filterpy, simdkalman, pykalman and
dask[distributed]).  Prints one table and writes it as CSV (default ``bench/results.csv``):

1. One filter pass on the same inputs -- S17 truss, case-4 sensors (9 channels), 4 forces,
   70 augmented states, 8192 steps -- by the textbook loop (the reference), filterpy,
   simdkalman, pykalman and ``akf.run`` (time-varying and steady-state), with the largest
   state difference to the textbook loop.
2. 35 sensor sets at once (``estimate_batch``): the cost per filter against one alone.
3. Whole jobs through the command line (``akf locate --example imp-truss-case1 | imp-plate``,
   ``akf place --example th-case5``) on 1 and 2 joblib workers and on a 2-worker
   ``dask.distributed.LocalCluster``: the jobs' own stage totals ("work") and the process
   time including imports.

4. Placement on a 3-D frame of one's own (147 DOFs read from Matrix Market files, 161 members as
   extensometers, 200 Hz, 4 strain gauges, a 30 x 30 GA): the whole command, the filter's modes
   under the ``"auto"`` rule, and the found layout's fitness on the full model against the rule's.
5. The footbridge jobs (``akf place --example footbridge-place``, ``akf estimate --example
   footbridge-walk``): whole processes.
6. The 1e5-DOF plate: load and 100-mode reduction with static correction, in a fresh process
   (``bench/large_model_bench.py --sizes 183``): seconds and peak memory.

Each row carries its target and whether it is met; where a target is missed the row names
the stage that takes the time and the measured reason (operation counts and rates).  Times are
the best of a few repeats on a shared machine: read the ratios, they move less than the times.
"""
from __future__ import annotations

import argparse
import csv
import itertools
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def write_rows(path, rows):
    """Write ``rows`` (dicts with the same keys) as a CSV table at ``path``."""
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def best_of(fn, repeat=3):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def textbook_loop(A, G, Q, R, Y):
    """The plain Kalman filter, one step at a time with explicit inverses: the reference."""
    x = np.zeros(A.shape[0])
    P = Q.copy()
    out = np.empty((Y.shape[0], A.shape[0]))
    eye = np.eye(A.shape[0])
    for k in range(Y.shape[0]):
        K = P @ G.T @ np.linalg.inv(G @ P @ G.T + R)
        x = x + K @ (Y[k] - G @ x)
        P = (eye - K @ G) @ P
        out[k] = x
        x = A @ x
        P = A @ P @ A.T + Q
    return out


def textbook_steady_loop(A, G, Q, R, Y):
    """The plain steady-state filter: the gain from scipy's DARE solver, one step at a time."""
    import scipy.linalg
    P = scipy.linalg.solve_discrete_are(A.T, G.T, Q, R)
    K = P @ G.T @ np.linalg.inv(G @ P @ G.T + R)
    x = np.zeros(A.shape[0])
    out = np.empty((Y.shape[0], A.shape[0]))
    for k in range(Y.shape[0]):
        x = x + K @ (Y[k] - G @ x)
        out[k] = x
        x = A @ x
    return out


def filterpy_pass(A, G, Q, R, Y):
    from filterpy.kalman import KalmanFilter
    kf = KalmanFilter(dim_x=A.shape[0], dim_z=G.shape[0])
    kf.F, kf.H, kf.Q, kf.R, kf.P, kf.x = A, G, Q, R, Q.copy(), np.zeros(A.shape[0])
    out = np.empty((Y.shape[0], A.shape[0]))
    for k in range(Y.shape[0]):
        kf.update(Y[k])
        out[k] = kf.x
        kf.predict()
    return out


def simdkalman_pass(A, G, Q, R, Y):
    import simdkalman
    kf = simdkalman.KalmanFilter(state_transition=A, process_noise=Q, observation_model=G, observation_noise=R)
    res = kf.compute(Y[None], 0, initial_value=np.zeros(A.shape[0]), initial_covariance=Q, smoothed=False,
                     filtered=True, covariances=False, observations=False)
    return res.filtered.states.mean[0]


def pykalman_pass(A, G, Q, R, Y):
    from pykalman import KalmanFilter
    kf = KalmanFilter(transition_matrices=A, observation_matrices=G, transition_covariance=Q, observation_covariance=R,
                      initial_state_mean=np.zeros(A.shape[0]), initial_state_covariance=Q)
    return kf.filter(Y)[0]


#: what a peer's difference to the textbook filter comes from
PEER_NOTES = {"pykalman": "inverts the innovation covariance with scipy.linalg.pinv, whose cut-off (9 eps x the "
                          "largest singular value, 3.6e-12 here) drops the strain channels (innovation variances "
                          "~1e-13 against ~1e3 for the accelerations): a different filter on this mixed-unit problem"}


def gemm_rate(n, repeat=200):
    """Measured multiply-adds per second of one n x n matrix product (this machine's BLAS)."""
    X = np.random.default_rng(0).normal(size=(n, n))
    t, _ = best_of(lambda: X @ X, repeat)
    return n ** 3 / t


def filter_rows():
    from akf.examples import S17_FORCES, S17_MULTI, example_job
    from akf.job import Job
    from core_akf import filter as akf
    from core_akf.covariances import augmented_covariance
    from core_akf.filter.recursion import lti_response
    from core_akf.filter.riccati import steady_gain
    from core_akf.models import s17_truss
    from core_akf.simulate import simulate
    from core_akf.statespace import state_space

    n_steps, dt = 8192, 1 / 4096
    job = example_job("s17-case4")
    job["simulation"]["duration"] = n_steps * dt
    sim = Job.from_dict(job, "estimate").simulate()
    R = np.diag(sim.noise_std ** 2)
    Y = sim.measurements
    model = s17_truss().scaled(1.05)
    ss = state_space(model, S17_MULTI, S17_FORCES, dt)
    A, G = ss.A_a, ss.G_a
    Q = augmented_covariance(ss.n_states, ss.n_forces, 1e-16, 1e5)
    n, m = A.shape[0], G.shape[0]
    print(f"1. one filter pass: S17 case 4, {m} channels, {n} augmented states, {n_steps} steps")

    t_ref, ref = best_of(lambda: textbook_loop(A, G, Q, R, Y), 1)
    ref_steady = textbook_steady_loop(A, G, Q, R, Y)
    peers = [("filterpy KalmanFilter loop", filterpy_pass, 2), ("simdkalman", simdkalman_pass, 1),
             ("pykalman", pykalman_pass, 1)]
    times = {}
    rows = []
    for name, fn, rep in peers:
        try:
            t, out = best_of(lambda fn=fn: fn(A, G, Q, R, Y), rep)
        except ImportError as exc:
            print(f"  {name}: not installed ({exc.name}); pip install '.[bench]'")
            continue
        times[name] = t
        rows.append(dict(section="filter", case=name, seconds=t, diff=_rel(out, ref),
                         limit=PEER_NOTES.get(name, "")))
    t_tv, out_tv = best_of(lambda: akf.run(A, G, Q, R, Y), 5)
    t_ss, out_ss = best_of(lambda: akf.run(A, G, Q, R, Y, steady=True), 9)
    ref_fp = times.get("filterpy KalmanFilter loop", t_ref)

    # where the steady-state time goes: Riccati solve and the lifted recursion
    t_gain, (P, L) = best_of(lambda: steady_gain(A[None], G[None], Q[None], R[None]), 9)
    F = (np.eye(n) - L[0] @ G) @ A
    t_rec, _ = best_of(lambda: lti_response(F[None], L, Y[None], (L[0] @ Y[0])[None]), 9)
    rate = gemm_rate(n)
    inv_t, _ = best_of(lambda: np.linalg.inv(np.eye(n) + F @ F.T), 200)
    # where the time-varying time goes: covariance steps until the gain has converged
    k_switch = _switch_step(akf, A, G, Q, R, Y)
    tv_floor = k_switch * 2 * n ** 3 / rate
    rows += [
        dict(section="filter", case="akf.run time-varying", seconds=t_tv, diff=_rel(out_tv, ref),
             target_s=0.015, target_ratio=50,
             limit=(f"{k_switch} covariance steps before the gain converges (relative change < 1e-14), each "
                    f"A P A^T alone 2 n^3 = {2 * n ** 3 / 1e6:.2f} M multiply-adds at the measured BLAS rate "
                    f"{rate / 1e9:.1f} G/s: >= {1e3 * tv_floor:.0f} ms before any overhead; "
                    f"measured {1e6 * (t_tv - t_rec) / max(k_switch, 1):.0f} us per step")),
        dict(section="filter", case="akf.run steady-state", seconds=t_ss, diff=_rel(out_ss, ref_steady),
             target_s=0.007, target_ratio=100,
             limit=(f"Riccati (doubling) {1e3 * t_gain:.1f} ms: ~12 iterations, each a {n}x{n} inverse "
                    f"({1e6 * inv_t:.0f} us: LAPACK at {n ** 3 / inv_t / 1e9:.1f} G/s on this size) and 8 products; "
                    f"lifted recursion {1e3 * t_rec:.1f} ms (2 N n^2 = {2 * n_steps * n * n / 1e6:.0f} M "
                    f"multiply-adds in large products, {2 * n_steps * n * n / t_rec / 1e9:.1f} G/s)")),
    ]
    for r in rows:
        r["ratio_vs_filterpy"] = ref_fp / r["seconds"]
    rows.append(dict(section="filter", case="textbook loop (reference)", seconds=t_ref, diff=0.0,
                     ratio_vs_filterpy=ref_fp / t_ref))

    # 2. batches: 35 sensor sets, steady state
    accels = ["acc:4:y", "acc:6:y", "acc:8:y", "acc:12:y", "acc:6:x", "acc:10:y", "acc:14:y"]
    layouts = [S17_MULTI[5:] + list(c) for c in itertools.combinations(accels, 3)]
    truss = s17_truss()
    Ys = np.stack([simulate(truss, lay, S17_FORCES, sim.loads, dt, relative_noise=0.02, seed=1).measurements
                   for lay in layouts])
    noise = np.stack([np.diag(0.0004 * np.mean(y ** 2, axis=0)) for y in Ys])
    kw = dict(model_error_cov=1e-16, force_increment_cov=1e5, steady=True)
    t_one, _ = best_of(lambda: akf.estimate(model, layouts[0], S17_FORCES, Ys[0], dt, noise_cov=noise[0], **kw), 5)
    t_batch, _ = best_of(lambda: akf.estimate_batch(model, layouts, S17_FORCES, Ys, dt, noise_cov=noise, **kw), 2)
    rows.append(dict(section="batch", case="estimate, one sensor set", seconds=t_one))
    rows.append(dict(section="batch", case=f"estimate_batch, {len(layouts)} sets (per set)",
                     seconds=t_batch / len(layouts), ratio_vs_filterpy=None,
                     limit=f"per-set cost {t_batch / len(layouts) / t_one:.2f}x of one alone"))
    return rows


def _switch_step(akf, A, G, Q, R, Y):
    """Step at which the time-varying filter switches to its converged gain."""
    from core_akf.filter import kernels as mod
    calls = []
    original = mod.lti_response

    def spy(F, Bu, Ys, first, H=None):
        calls.append(Y.shape[0] - Ys.shape[1])
        return original(F, Bu, Ys, first, H)

    mod.lti_response = spy
    try:
        akf.run(A, G, Q, R, Y)
    finally:
        mod.lti_response = original
    return calls[0] if calls else Y.shape[0]


def _rel(a, ref):
    return float(np.max(np.abs(np.asarray(a) - ref)) / np.max(np.abs(ref)))


JOBS = [
    ("locate", "imp-truss-case1", dict(target_work=2.0, target_process=2.5, workers=1)),
    ("locate", "imp-plate", dict(target_work=3.0, workers=1)),
    ("place", "th-case5", dict(target_work=8.0, workers=2, seed=7)),
]


def run_job(args, cwd=None):
    """``python -m akf ARGS --json --no-plot --out TMP``; returns (process seconds, parsed JSON)."""
    with tempfile.TemporaryDirectory() as out:
        cmd = [sys.executable, "-m", "akf", *args, "--json", "--no-plot", "--out", out]
        env = dict(os.environ, PYTHONWARNINGS="ignore")
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env, check=False, cwd=cwd)
        wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{proc.stderr[-2000:]}")
    return wall, json.loads(proc.stdout)


def run_cli(command, example, n_jobs=None, scheduler=None, seed=None):
    """One built-in example through the command line (:func:`run_job`)."""
    args = [command, "--example", example]
    for flag, value in (("--seed", seed), ("--n-jobs", n_jobs), ("--scheduler", scheduler)):
        if value is not None:
            args += [flag, str(value)]
    return run_job(args)


def job_rows(repeat=2):
    print("3. whole jobs (command line, --json --no-plot)")
    rows = []
    for command, example, target in JOBS:
        for label, n_jobs, scheduler in (("1 worker", 1, None), ("2 workers", 2, None),
                                         ("2-worker LocalCluster", None, "local:2")):
            results = [run_cli(command, example, n_jobs, scheduler, target.get("seed")) for _ in range(repeat)]
            wall, data = min(results, key=lambda r: r[0])
            secs = data["seconds"]
            work = secs["total"] if isinstance(secs, dict) else float(secs)
            seed = f" --seed {target['seed']}" if "seed" in target else ""
            row = dict(section="job", case=f"akf {command} --example {example}{seed}", workers=label, seconds=work,
                       process_seconds=wall)
            if command == "locate":
                row["result"] = (f"node {data['identified']}, confidence {data['confidence']:.2f}, "
                                 f"peak {data['peak_force'] / 1e3:.3f} kN")
                row["stages"] = ", ".join(f"{k} {v:.2f} s" for k, v in secs.items() if k != "total")
            else:
                row["result"] = f"{' '.join(data['sensors'])}: {data['error']:.4f} µε, {data['evaluations']} evaluations"
                row["stages"] = f"{data['evaluations']} fitness evaluations, {work / max(data['evaluations'], 1) * 1e3:.0f} ms each"
            if (label == "1 worker" and target["workers"] == 1) or (label == "2 workers" and target["workers"] == 2):
                row["target_s"] = target["target_work"]
                if "target_process" in target:
                    row["target_process_s"] = target["target_process"]
            rows.append(row)
            print(f"  {row['case']:42s} {label:22s} work {work:7.2f} s, process {wall:7.2f} s  {row['result']}")
    return rows


FRAME_JOB = """name = "frame3d"
description = "a 3-D frame of one's own: 4 strain gauges on 161 members"
dt = 0.005
forces = ["27:z", "39:z"]

[structure]
model = "matrices"
K = "K.mtx"
M = "M.mtx"
dofs = "dofs.csv"
nodes = "nodes.csv"
fixed = {fixed}
damping = 0.01
extensometers = "members.csv"

[place]
kinds = ["strain"]
sensors = 4
window = 1.0
population = 30
generations = 30

[filter]
stiffness_factor = 1.02
model_error_cov = 1e-14
force_increment_cov = 1e3

[simulation]
duration = 10.0
relative_noise = 0.02
seed = 0

[[simulation.loads]]
components = [{{type = "constant", value = -700.0}}, {{type = "sine", frequency = 2.0, amplitude = 280.0}}]

[[simulation.loads]]
components = [{{type = "band_noise", rms = 150.0, f_low = 1.0, f_high = 6.0, seed = 7}}]
"""


def write_frame(folder):
    """A 3-D frame of one's own in ``folder`` (the footbridge's box truss with 12 panels: 147 free
    DOFs, 161 members) as an FE program leaves it: K.mtx, M.mtx, dofs.csv, nodes.csv, members.csv
    and the place job ``frame.toml``."""
    import scipy.io
    import scipy.sparse

    from core_akf.models.footbridge import footbridge_matrices

    m = footbridge_matrices(n_panels=12)
    scipy.io.mmwrite(os.path.join(folder, "K.mtx"), scipy.sparse.coo_matrix(m["K"]), symmetry="symmetric")
    scipy.io.mmwrite(os.path.join(folder, "M.mtx"), scipy.sparse.coo_matrix(m["M"]), symmetry="symmetric")
    with open(os.path.join(folder, "dofs.csv"), "w") as fh:
        fh.write("node,direction\n" + "".join(f"{n},{d}\n" for n, d in m["dofs"]))
    with open(os.path.join(folder, "nodes.csv"), "w") as fh:
        fh.write("node,x,y,z\n" + "".join(f"{i},{x!r},{y!r},{z!r}\n" for i, (x, y, z) in m["nodes"].items()))
    with open(os.path.join(folder, "members.csv"), "w") as fh:
        fh.write("a,b\n" + "".join(f"{a},{b}\n" for a, b in m["members"]))
    fixed = "[" + ", ".join(f'"{n}:{d}"' for n, d in m["fixed"]) + "]"
    path = os.path.join(folder, "frame.toml")
    with open(path, "w") as fh:
        fh.write(FRAME_JOB.format(fixed=fixed))
    return path


def frame_rows():
    """4. Placement on a 3-D frame of one's own (about 150 modes)."""
    from akf.job import load_job
    from akf.placement import problem_from_job
    from core_akf.defaults import auto_modes, band_modes

    print("4. placement on a 3-D frame of one's own")
    with tempfile.TemporaryDirectory() as folder:
        path = write_frame(folder)
        wall, data = run_job(["place", path, "--seed", "1", "--n-jobs", "1"], cwd=folder)
        problem, _ = problem_from_job(load_job(path, "place"))
        enc = problem.encoding()
        s = problem.structure
        k_band, k_auto = band_modes(s, problem.dt), auto_modes(s, problem.dt, accelerations=False)
        fits, per_layout = {}, {}
        for label, k in (("rule", "auto"), ("full", None)):
            problem.n_modes = k
            obj = problem.objective(enc)
            t, f = best_of(lambda obj=obj: obj.evaluate([data["sensors"]])[0], 2)
            fits[label], per_layout[label] = f, t
    diff = fits["rule"] / fits["full"] - 1
    row = dict(section="frame", case="akf place frame.toml (147 DOFs, 4 gauges, 30 x 30)", workers="1 worker",
               seconds=data["seconds"], process_seconds=wall, target_s=30.0, target_process_s=30.0,
               result=(f"{' '.join(data['sensors'])}: {data['error']:.4f} µε (whole record, {k_auto} modes); fitness "
                       f"{fits['rule']:.4f} ({k_band} modes) against {fits['full']:.4f} µε (all {s.n}): {100 * diff:+.1f} %"),
               stages=(f"{data['evaluations']} evaluations, {1e3 * per_layout['rule']:.0f} ms per layout on {k_band} "
                       f"modes against {1e3 * per_layout['full']:.0f} ms on all {s.n}"))
    print(f"  {row['case']}: work {row['seconds']:.2f} s, process {wall:.2f} s; {row['result']}; {row['stages']}")
    return [row]


def footbridge_rows():
    """5. The footbridge jobs, whole processes."""
    print("5. the footbridge jobs")
    rows = []
    for command, example in (("place", "footbridge-place"), ("estimate", "footbridge-walk")):
        wall, data = run_job([command, "--example", example] + (["--n-jobs", "1"] if command == "place" else []))
        if command == "place":
            result = f"{' '.join(data['sensors'])}: {data['error']:.4f} µε, {data['evaluations']} evaluations"
            work = float(data["seconds"])
        else:           # an estimate reports no stage times: the process is the measure
            forces = ", ".join(f"{v:.0f}" for v in data["rms_force"].values())
            result = f"force RMS errors {forces} N, average strain error {data['avg_strain_error_microstrain']:.3f} µε"
            work = wall
        rows.append(dict(section="footbridge", case=f"akf {command} --example {example}", workers="1 worker",
                         seconds=work, process_seconds=wall, target_s=30.0, target_process_s=30.0, result=result))
        print(f"  akf {command} --example {example}: work {work:.2f} s, process {wall:.2f} s  {result}")
    return rows


def large_rows():
    """6. The 1e5-DOF plate: load and 100-mode reduction with static correction, fresh process."""
    print("6. 1e5 DOFs: load and 100-mode reduction (bench/large_model_bench.py --sizes 183)")
    with tempfile.TemporaryDirectory() as out:
        csv_path = os.path.join(out, "large.csv")
        proc = subprocess.run([sys.executable, os.path.join(HERE, "large_model_bench.py"), "--sizes", "183",
                               "--csv", csv_path], capture_output=True, text=True, check=False)
        if proc.returncode != 0:
            raise RuntimeError(f"large_model_bench.py failed:\n{proc.stderr[-2000:]}")
        with open(csv_path, newline="", encoding="utf-8") as fh:
            r = next(csv.DictReader(fh))
    import scipy.sparse

    from core_akf.models.sparse import factorise
    method = factorise(scipy.sparse.csc_matrix(np.eye(2))).method
    model_s, peak = float(r["model_s"]), float(r["peak_rss_gib"])
    row = dict(section="large", case=f"{int(r['dofs'])} DOFs: load + 100 modes + static correction", workers="",
               seconds=model_s, target_s=15.0, memory_gib=peak, target_memory_gib=2.0,
               result=f"load {float(r['load_s']):.2f} s, reduction {float(r['reduce_s']):.2f} s, static correction "
                      f"{float(r['static_s']):.2f} s, peak {peak:.2f} GiB, factorisation {method}",
               limit=("the reduction is ~200 single-vector solves of the shift-invert Lanczos (ARPACK), each two "
                      "triangular solves with the Cholesky factor, bound by memory bandwidth (0.04 s each), plus ARPACK's "
                      "own reorthogonalisation (~5 s); PARDISO (MKL) factorises in 0.4 s but solves in 0.06 s; a block "
                      "Krylov of 240 vectors (20-vector solves at 0.015 s each) left the 100th frequency 1e-4 off"))
    print(f"  {row['case']}: {model_s:.2f} s, {peak:.2f} GiB  ({row['result']})")
    return [row]


def scan_reason(name):
    """Where the time of a location scan goes: the batched Riccati solves against the rest."""
    from akf.examples.impact import example_scenario
    from core_akf.filter.riccati import steady_gain
    from impactloc import candidate_locations, default_covariances, role_splits
    from impactloc.scan import ImpactModel, location_errors

    sc = example_scenario(name)
    splits = role_splits(sc.sensors, sc.n_ad, sc.ad_kinds)
    cov = default_covariances(sc.sensors, sc.measurements)
    cands = candidate_locations(sc.structure, sc.direction)
    model = ImpactModel(sc.structure, sc.sensors, sc.dt, "auto")
    loc = cands[0]
    A, G_all = model.system(loc)
    t_loc, _ = best_of(lambda: location_errors(model, loc, splits, sc.measurements, [cov]), 2)
    noise = model.noise(cov)
    G = G_all[np.array([s.se for s in splits])]
    R = np.stack([np.diag(noise[list(s.se)]) for s in splits])
    Q = np.broadcast_to(model.Q_a(cov, loc), (len(splits),) + A.shape)
    t_gain, _ = best_of(lambda: steady_gain(np.broadcast_to(A, Q.shape), G, Q, R), 2)
    n = A.shape[0]
    return (f"scan: {len(cands)} locations x {len(splits)} splits = {len(cands) * len(splits)} steady AKFs of "
            f"{n} states; per location {1e3 * t_loc:.0f} ms, of which the {len(splits)} Riccati solves "
            f"{1e3 * t_gain:.0f} ms ({1e3 * t_gain / len(splits):.1f} ms each: ~12 doubling iterations of "
            f"an {n}x{n} inverse (getrf + getri) and 8 products, each squaring the closed loop's spectral radius "
            f"~0.98); the tuning adds as many solves again. Not cut further: the layouts hold accelerometers, "
            f"which see the modes a reduced model drops (with them band_modes is auto_modes: {n} states here), "
            f"and a neighbouring location's solution is no warm start (on the truss its DARE residual is 0.2 "
            f"and Newton diverges from it)")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--csv", default=os.path.join(HERE, "results.csv"), help="where to write the table")
    ap.add_argument("--skip-jobs", action="store_true", help="only the filters and batches (about a minute)")
    args = ap.parse_args(argv)
    import numpy
    import scipy
    print(f"numpy {numpy.__version__}, scipy {scipy.__version__}, {os.cpu_count()} cores, python {sys.version.split()[0]}")
    rows = filter_rows()
    if not args.skip_jobs:
        rows += job_rows()
        rows += frame_rows() + footbridge_rows() + large_rows()
        for r in rows:
            if r["section"] == "job" and "target_s" in r and r["seconds"] > r["target_s"]:
                example = r["case"].split()[-1]
                r["limit"] = scan_reason(example) if example.startswith("imp") else r.get("stages", "")
    for r in rows:
        if "target_s" in r:
            met = r["seconds"] <= r["target_s"]
            if r.get("target_ratio") and r.get("ratio_vs_filterpy"):
                met = met or r["ratio_vs_filterpy"] >= r["target_ratio"]   # the ratio is what a shared machine keeps
            if r.get("target_process_s") and r.get("process_seconds"):
                met = met and r["process_seconds"] <= r["target_process_s"]
            if r.get("target_memory_gib") and r.get("memory_gib"):
                met = met and r["memory_gib"] <= r["target_memory_gib"]
            r["met"] = "yes" if met else "no"
    print(f"\n{'section':7s} {'case':46s} {'workers':22s} {'time (s)':>9s} {'vs filterpy':>11s} {'target':>14s} "
          f"{'met':>4s}  diff to textbook (steady: to the textbook steady-state loop)")
    for r in rows:
        ratio = f"{r['ratio_vs_filterpy']:10.1f}x" if r.get("ratio_vs_filterpy") else ""
        target = ""
        if "target_s" in r:
            target = f"<= {r['target_s']:g} s" + (f" / {r['target_ratio']}x" if r.get("target_ratio") else "")
        diff = f"{r['diff']:.1e}" if "diff" in r else ""
        print(f"{r['section']:7s} {r['case']:46s} {r.get('workers', ''):22s} {r['seconds']:9.4f} {ratio:>11s} "
              f"{target:>14s} {r.get('met', ''):>4s}  {diff}")
    missed = [r for r in rows if r.get("met") == "no"]
    if missed:
        print("\nwhere a target is missed, the stage and the measured reason:")
        for r in missed:
            print(f"- {r['case']} ({r.get('workers', '')}): {r.get('limit', r.get('stages', ''))}")
    keys = ["section", "case", "workers", "seconds", "process_seconds", "ratio_vs_filterpy", "diff", "target_s",
            "target_ratio", "target_process_s", "memory_gib", "target_memory_gib", "met", "result", "stages", "limit"]
    with open(args.csv, "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    print(f"\nwrote {args.csv}")


if __name__ == "__main__":
    main()
