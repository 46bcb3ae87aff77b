"""The filter pass side by side in two trees (run by hand: ``python bench/filter_speed_bench.py [REV ...]``).

``core_akf.filter.run`` -- the time-varying and the steady-state AKF -- on the S17 truss, case-4
sensors (9 channels, 4 forces, 70 augmented states), 8192 steps, timed in this tree and in each
given git revision (default 9193c32, the last tree before the log-likelihood terms), each in a
process of its own, the trees alternating, best of ``ROUNDS`` rounds.  The inputs are made once, in
this tree, and handed to every tree in one ``.npz`` file, so every tree filters the same numbers;
the states each tree returns are compared too.  Also times this tree's run with the
log-likelihood asked for (``filter_states(..., loglik=True)``) against without.
"""
import os
import pathlib
import subprocess
import sys
import sysconfig
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
N_STEPS = 8192
DT = 1 / 4096
ROUNDS = 5

#: what each tree runs: times and the states of both passes, written to argv[2]
CHILD = r"""
import sys, time
sys.path.insert(0, sys.argv[5])                     # the tree given (run with -S: no editable install's hook)
sys.path.append(sys.argv[6])
import numpy as np
try:
    from core_akf.filter import run, filter_states
except ImportError:                                 # the trees before the filter module had it as core_akf.akf
    from core_akf.akf import run, filter_states
import core_akf; assert core_akf.__file__.startswith(sys.argv[5]), core_akf.__file__
d = np.load(sys.argv[1])
args = (d["A"], d["G"], d["Q"], d["R"], d["Y"])
out = {}
for steady in (False, True):
    run(*args, steady=steady)                       # warm
    best = np.inf
    for _ in range(int(sys.argv[3])):
        t = time.perf_counter(); X = run(*args, steady=steady); best = min(best, time.perf_counter() - t)
    key = "steady" if steady else "time_varying"
    out[key] = np.array(best)
    out[key + "_states"] = X
import inspect
if sys.argv[4] == "loglik" and "loglik" in inspect.signature(filter_states).parameters:
    for steady in (False, True):
        best = np.inf
        for _ in range(int(sys.argv[3])):
            t = time.perf_counter(); r = filter_states(*args, steady=steady, loglik=True); r.loglik
            best = min(best, time.perf_counter() - t)
        out[("steady" if steady else "time_varying") + "_loglik"] = np.array(best)
np.savez(sys.argv[2], **out)
"""


def inputs(path):
    from akf.examples import S17_FORCES, S17_MULTI
    from core_akf.covariances import augmented_covariance
    from core_akf.models import s17_truss
    from core_akf.simulate import simulate
    from core_akf.statespace import state_space

    truss = s17_truss()
    rng = np.random.default_rng(0)
    loads = np.cumsum(rng.normal(0.0, 20.0, (N_STEPS, len(S17_FORCES))), axis=0)
    sim = simulate(truss, S17_MULTI, S17_FORCES, loads, DT, relative_noise=0.02, seed=1)
    ss = state_space(truss.scaled(1.05), S17_MULTI, S17_FORCES, DT)
    Q = augmented_covariance(ss.n_states, ss.n_forces, 1e-16, 1e5)
    np.savez(path, A=ss.A_a, G=ss.G_a, Q=Q, R=np.diag(sim.noise_std ** 2), Y=sim.measurements)


def tree(rev, tmp):
    """A checkout of ``rev`` (a git worktree in ``tmp``)."""
    where = pathlib.Path(tmp) / rev
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-f", str(where), rev], check=True,
                   capture_output=True)
    return where


def timed(where, data, out, loglik):
    site = sysconfig.get_paths()["purelib"]
    subprocess.run([sys.executable, "-S", "-c", CHILD, data, out, "3", "loglik" if loglik else "-", str(where), site],
                   check=True, cwd=tempfile.gettempdir())
    return dict(np.load(out))


def main(revs):
    with tempfile.TemporaryDirectory() as tmp:
        data = os.path.join(tmp, "inputs.npz")
        inputs(data)
        trees = {"this tree": (ROOT, True)} | {rev: (tree(rev, tmp), False) for rev in revs}
        best = {name: {} for name in trees}
        states = {}
        try:
            for _ in range(ROUNDS):                               # alternate the trees
                for name, (where, own) in trees.items():
                    r = timed(where, data, os.path.join(tmp, "out.npz"), own)
                    for key, v in r.items():
                        if key.endswith("_states"):
                            states[(name, key)] = v
                        else:
                            best[name][key] = min(best[name].get(key, np.inf), float(v))
        finally:
            for rev in revs:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(pathlib.Path(tmp) / rev)],
                               capture_output=True)
    print(f"core_akf.filter.run on S17 case 4 ({N_STEPS} steps, 70 states, 9 channels), best of {ROUNDS} rounds x 3")
    print(f"{'tree':12s} {'time-varying (ms)':>18s} {'steady (ms)':>12s}")
    for name in trees:
        print(f"{name:12s} {1e3 * best[name]['time_varying']:18.1f} {1e3 * best[name]['steady']:12.1f}")
    own = best["this tree"]
    for rev in revs:
        print(f"this tree / {rev}: time-varying {own['time_varying'] / best[rev]['time_varying']:.3f}, "
              f"steady {own['steady'] / best[rev]['steady']:.3f}  (below 1: faster)")
        for key in ("time_varying_states", "steady_states"):
            a, b = states[("this tree", key)], states[(rev, key)]
            print(f"  {key}: max relative difference {np.max(np.abs(a - b)) / np.max(np.abs(b)):.1e}")
    if "time_varying_loglik" in own:
        for key in ("time_varying", "steady"):
            print(f"with the log-likelihood asked for, {key}: {1e3 * own[key + '_loglik']:.1f} ms "
                  f"(+{100 * (own[key + '_loglik'] / own[key] - 1):.1f} %)")


if __name__ == "__main__":
    main(sys.argv[1:] or ["9193c32"])
