"""Learning from the data, timed by hand: ``python bench/learn_bench.py [--csv PATH]``.

Needs statsmodels (a test extra).  On the S17 case-4 record (9 channels, 4 forces, 70 augmented
states, 8192 steps) it prints and writes (default ``bench/learn_results.csv``):

1. The log-likelihood of one parameter set: ours (the steady filter straight to the innovations,
   :func:`core_akf.filter.kernels.steady_logliks`; and the time-varying :func:`core_akf.filter.run`
   path, which holds the gain once the covariance has converged, as statsmodels does) against
   statsmodels' ``KalmanFilter.loglike`` on the same matrices, with the relative difference.
2. Calibration time per parameter set (``core_akf.calibration.calibrate``): the stiffness factor
   alone; stiffness, R per kind and S from levels 100 x off; with the fitted values, the force
   error against the truth.
   Also the frequencies of modes 1-4 from a model whose modes 2 and 3 are off, and R per channel
   with one gauge's variance 100 x off.
3. Smoother throughput (steps/s): ``core_akf.smooth`` (steady and time-varying, with the
   variances) against statsmodels' ``KalmanSmoother.smooth`` on the same matrices; the
   fixed-lag smoother of the record streamed in chunks of 1024 steps against the filter alone.

Times are the best of a few repeats on a shared machine: read the ratios.
"""
from __future__ import annotations

import argparse
import csv
import os

import numpy as np
from run_all import best_of  # noqa: E402  (bench/ is the script's folder)

HERE = os.path.dirname(os.path.abspath(__file__))


def _problem():
    from akf.examples import example
    from core_akf.filter import Filter

    job = example("s17-case4")
    sim = job.simulate()
    R = job.noise_cov(sim)
    setup = Filter(job.filter_model(), [job.sensors], job.forces, job.dt, model_error_cov=job.model_error_cov,
                   force_increment_cov=job.force_increment_cov, noise_cov=R)
    return job, sim, R, setup


def _statsmodels(kind, A, G, Q, R, Y, P0):
    from statsmodels.tsa.statespace.kalman_filter import KalmanFilter
    from statsmodels.tsa.statespace.kalman_smoother import KalmanSmoother

    n, m = A.shape[0], G.shape[0]
    cls = KalmanFilter if kind == "filter" else KalmanSmoother
    model = cls(k_endog=m, k_states=n, initialization="known", initial_state=np.zeros(n), initial_state_cov=P0)
    model.bind(np.asarray(Y))
    model["design"], model["transition"], model["selection"], model["state_cov"], model["obs_cov"] = G, A, np.eye(n), Q, R
    return model


def main(argv=None):
    from core_akf.calibration import calibrate
    from core_akf.filter import estimate, filter_states
    from core_akf.filter.kernels import steady_logliks
    from core_akf.filter.smoother import smooth
    from core_akf.metrics import rms_error

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--csv", default=os.path.join(HERE, "learn_results.csv"))
    args = parser.parse_args(argv)
    job, sim, R, setup = _problem()
    A, G, Q, Rm, Y = setup.A_a, setup.G_a[0], setup.Q_a, setup.R[0], sim.measurements
    N = Y.shape[0]
    rows = []

    # 1. the log-likelihood of one parameter set
    P_ss = filter_states(A, G, Q, Rm, Y, steady=True).P_prior
    t_ours, ll = best_of(lambda: steady_logliks(A[None], G[None], Q[None], Rm[None], Y)[0])
    sm = _statsmodels("filter", A, G, Q, Rm, Y, P_ss)
    t_sm, ll_sm = best_of(lambda: sm.loglike())
    rows.append({"what": "loglik, steady (one parameter set)", "ours_s": t_ours, "statsmodels_s": t_sm,
                 "ratio": t_sm / t_ours, "difference": abs(ll - ll_sm) / abs(ll_sm)})
    t_tv, res = best_of(lambda: filter_states(A, G, Q, Rm, Y, loglik=True).loglik_terms.sum(), repeat=1)
    sm = _statsmodels("filter", A, G, Q, Rm, Y, Q)
    t_sm, ll_sm = best_of(lambda: sm.loglike(), repeat=1)
    rows.append({"what": "loglik, time-varying (P0 = Q_a)", "ours_s": t_tv, "statsmodels_s": t_sm,
                 "ratio": t_sm / t_tv, "difference": abs(res - ll_sm) / abs(ll_sm)})

    # 2. calibration per parameter set
    def fit(parameters, noise, start):
        return calibrate(start, job.sensors, job.forces, Y, job.dt, parameters=parameters,
                         model_error_cov=job.model_error_cov, force_increment_cov=job.force_increment_cov, noise_cov=noise)
    kinds = np.array([s.kind for s in job.sensors])
    off = np.diag(np.where(kinds == "acc", 100.0, 0.01) * np.diag(R))
    one_off = np.diag(np.diag(R) * np.where(np.arange(len(kinds)) == 7, 0.01, 1.0))      # strain:13 100 x too small
    modes_off = job.structure.with_frequency_factors([1.0, 1.04, 0.97])                # modes 2, 3 off by +4 %, -3 %
    for parameters, noise, start, label in (
            (["stiffness_factor"], R, job.filter_model(), "stiffness factor"),
            (["stiffness_factor", "noise_cov", "force_increment_cov"], off, job.filter_model(),
             "stiffness, R per kind, S (from R 100 x off)"),
            (["frequencies"], R, modes_off, "frequencies of modes 1-4 (modes 2, 3 off by +4 %, -3 %)"),
            (["noise_cov:channels"], one_off, job.structure, "R per channel (one gauge 100 x off), true model")):
        t_fit, result = best_of(lambda p=parameters, r=noise, m=start: fit(p, r, m), repeat=1)
        model, Qf, Sf, Rf = result.apply(start, job.sensors, job.model_error_cov, job.force_increment_cov, noise)
        est = estimate(model, job.sensors, job.forces, Y, job.dt, model_error_cov=Qf, force_increment_cov=Sf, noise_cov=Rf)
        row = {"what": f"calibrate: {label}", "ours_s": t_fit, "evaluations": result.evaluations,
               "force_error_N": float(rms_error(est.forces, sim.loads).mean())}
        if "stiffness_factor" in result.multipliers:
            row["stiffness_factor"] = job.stiffness_factor * result.multipliers["stiffness_factor"]
        if "frequency_factors" in result.values:
            row["frequency_factors"] = " ".join(f"{v:.4f}" for v in np.array(result.values["frequency_factors"])
                                                * [1.0, 1.04, 0.97, 1.0])
        rows.append(row)

    # 3. smoother throughput
    for steady in (True, False):
        t_ours, _ = best_of(lambda s=steady: smooth(A, G, Q, Rm, Y, steady=s, covariances="diagonal"), repeat=1)
        sm = _statsmodels("smoother", A, G, Q, Rm, Y, P_ss if steady else Q)
        t_sm, _ = best_of(lambda m=sm: m.smooth(), repeat=1)
        rows.append({"what": f"smoother ({'steady' if steady else 'time-varying'}, variances)", "ours_s": t_ours,
                     "statsmodels_s": t_sm, "ratio": t_sm / t_ours, "ours_steps_per_s": N / t_ours,
                     "statsmodels_steps_per_s": N / t_sm})
    # the fixed-lag smoother of a streamed record (chunks of 1024 steps, the automatic lag), with the
    # standard deviations of the forces and every strain output
    from core_akf.filter import Estimator

    def streamed(lag):
        est = Estimator(job.structure, job.sensors, job.forces, job.dt, model_error_cov=job.model_error_cov,
                        force_increment_cov=job.force_increment_cov, noise_cov=R, smooth_lag=lag)
        parts = [est.update(Y[i:i + 1024]) for i in range(0, N, 1024)] + [est.finish()]
        return est, np.vstack([p.forces for p in parts])
    t_filter, _ = best_of(lambda: streamed(None))
    t_lag, (est, forces) = best_of(lambda: streamed("auto"))
    rows.append({"what": f"fixed-lag smoother, streamed (lag {est.lagged.lag} steps, forces and strain std)",
                 "ours_s": t_lag, "ours_steps_per_s": N / t_lag, "filter_alone_s": t_filter,
                 "force_error_N": float(rms_error(forces, sim.loads).mean())})

    keys = sorted({k for r in rows for k in r}, key=lambda k: (k != "what", k))
    with open(args.csv, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=keys)
        writer.writeheader()
        writer.writerows(rows)
    for r in rows:
        print(" | ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in r.items()))
    print(f"wrote {args.csv}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
