"""AKF benchmark: S17 truss, case-4 sensors, 8192 steps (run by hand: python bench/akf_bench.py).

Times one AKF pass in the time-varying, steady-state and batched (35 sensor sets) forms,
against a plain per-step Python loop (textbook Kalman filter with explicit inverses), and
the Riccati solution by doubling against scipy.linalg.solve_discrete_are.
"""
import itertools

import numpy as np
import scipy.linalg
from run_all import best_of, textbook_loop  # bench/ is on the path when run as a script

from akf.estimate import estimate_job
from akf.examples import S17_FORCES, S17_MULTI, example_job
from akf.job import Job
from core_akf import filter as akf
from core_akf.covariances import augmented_covariance
from core_akf.filter.riccati import solve_filter_dare
from core_akf.models import s17_truss
from core_akf.simulate import simulate
from core_akf.statespace import state_space

N_STEPS = 8192
DT = 1 / 4096
KW = dict(model_error_cov=1e-16, force_increment_cov=1e5)


def main():
    truss = s17_truss()
    model = truss.scaled(1.05)
    job = example_job("s17-case4")
    job["simulation"]["duration"] = N_STEPS * DT
    res = estimate_job(Job.from_dict(job, "estimate"))
    sim = res.simulation
    R = np.diag(sim.noise_std ** 2)
    Y = sim.measurements
    print(f"S17 truss, case 4: {len(S17_MULTI)} sensors, {len(S17_FORCES)} forces, {N_STEPS} steps, "
          f"{2 * truss.n + len(S17_FORCES)} augmented states")

    t_tv, est_tv = best_of(lambda: akf.estimate(model, S17_MULTI, S17_FORCES, Y, DT, noise_cov=R, steady=False, **KW), 1)
    t_ss, est_ss = best_of(lambda: akf.estimate(model, S17_MULTI, S17_FORCES, Y, DT, noise_cov=R, steady=True, **KW))

    ss = state_space(model, S17_MULTI, S17_FORCES, DT)
    Q_a = augmented_covariance(ss.n_states, ss.n_forces, KW["model_error_cov"], KW["force_increment_cov"])
    t_loop, states_loop = best_of(lambda: textbook_loop(ss.A_a, ss.G_a, Q_a, R, Y), 1)
    t_run, states_run = best_of(lambda: akf.run(ss.A_a, ss.G_a, Q_a, R, Y), 1)
    diff = np.max(np.abs(states_run - states_loop)) / np.max(np.abs(states_loop))

    # 35 sensor sets: the four case-4 strain gauges plus 3 of 7 candidate accelerometers
    accels = ["acc:4:y", "acc:6:y", "acc:8:y", "acc:12:y", "acc:6:x", "acc:10:y", "acc:14:y"]
    layouts = [S17_MULTI[5:] + list(c) for c in itertools.combinations(accels, 3)]
    Ys = np.stack([simulate(truss, l, S17_FORCES, sim.loads, DT, relative_noise=0.02, seed=1).measurements
                   for l in layouts])
    Rb = 0.0004 * np.mean(Ys ** 2, axis=1)  # 2 % noise variances per channel
    noise = np.stack([np.diag(r) for r in Rb])

    def one_by_one():
        return [akf.estimate(model, l, S17_FORCES, y, DT, noise_cov=n, steady=True, **KW)
                for l, y, n in zip(layouts, Ys, noise)]

    def batched():
        return akf.estimate_batch(model, layouts, S17_FORCES, Ys, DT, noise_cov=noise, steady=True, **KW)

    t_one, ests_one = best_of(one_by_one, 1)
    t_batch, ests_batch = best_of(batched, 1)
    bdiff = max(np.max(np.abs(a.forces - b.forces)) for a, b in zip(ests_one, ests_batch))

    Pq = Q_a
    t_sda, _ = best_of(lambda: solve_filter_dare(ss.A_a, ss.G_a, Pq, R))
    t_scipy, _ = best_of(lambda: scipy.linalg.solve_discrete_are(ss.A_a.T, ss.G_a.T, Pq, R))

    rows = [
        ("plain per-step Python loop (textbook)", t_loop, t_loop),
        ("akf.run, time-varying (batched kernel)", t_run, t_loop),
        ("akf.estimate, time-varying", t_tv, t_loop),
        ("akf.estimate, steady-state", t_ss, t_loop),
    ]
    print(f"\n{'one AKF pass':45s} {'time (s)':>10s} {'speed-up vs loop':>18s}")
    for name, t, ref in rows:
        print(f"{name:45s} {t:10.3f} {ref / t:17.1f}x")
    print(f"(akf.run vs textbook loop: max relative state difference {diff:.1e})")
    print(f"\n{'35 sensor sets, steady-state':45s} {'time (s)':>10s} {'per set (ms)':>14s}")
    print(f"{'one estimate() call per set':45s} {t_one:10.3f} {1e3 * t_one / 35:14.1f}")
    print(f"{'estimate_batch() (one batched call)':45s} {t_batch:10.3f} {1e3 * t_batch / 35:14.1f}")
    print(f"batched vs one-by-one: {t_one / t_batch:.1f}x (max force difference {bdiff:.1e} N); "
          f"vs 35 time-varying passes: {35 * t_tv / t_batch:.0f}x")
    print(f"\nRiccati ({ss.n_aug} states): doubling {1e3 * t_sda:.1f} ms, scipy solve_discrete_are "
          f"{1e3 * t_scipy:.1f} ms ({t_scipy / t_sda:.1f}x)")

    # the thesis plate: full model (330 DOFs, 662 augmented states) and modal reductions
    job = example_job("th-case3")
    th = estimate_job(Job.from_dict(job, "estimate"))
    sim = th.simulation
    plate = th.estimate.structure
    noise = np.diag(sim.noise_std ** 2)
    print(f"\nTH plate, case 3 layout, {sim.loads.shape[0]} steps, steady-state AKF:")
    print(f"{'filter model':28s} {'time (s)':>9s} {'avg strain error (µε)':>22s}")
    for modes in (None, 80, 40):
        model = plate if modes is None else plate.reduce(modes)
        t, est = best_of(lambda model=model: akf.estimate(model, job["sensors"], job["forces"], sim.measurements, job["dt"],
                                              model_error_cov=1e-16, force_increment_cov=1e-2,
                                              noise_cov=noise, steady=True), 1)
        from core_akf.metrics import average_strain_error
        label = f"full ({2 * plate.n + 2} states)" if modes is None else f"{modes} modes ({2 * modes + 2} states)"
        print(f"{label:28s} {t:9.2f} {1e6 * average_strain_error(est.strains, sim.strains):22.3f}")
    n_tv = 2000
    t, _ = best_of(lambda: akf.estimate(plate, job["sensors"], job["forces"], sim.measurements[:n_tv], job["dt"],
                                        model_error_cov=1e-16, force_increment_cov=1e-2,
                                        noise_cov=noise, steady=False), 1)
    print(f"time-varying AKF, full model, first {n_tv} steps: {t:.2f} s ({1e3 * t / n_tv:.1f} ms per step; "
          "covariance update O(n^2) in modal coordinates)")


if __name__ == "__main__":
    main()
