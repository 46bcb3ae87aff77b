"""Placement with accelerometer candidates on a ~150-DOF 3-D truss of one's own (run by hand:
python bench/acc_candidates_bench.py [--quick]).

The footbridge with 12 panels (147 free DOFs, read through ``from_matrices``), 4 strain gauges on
its 149 members and 2 accelerometers (z or y) on its free joints, 512 Hz, a 2 s fitness window,
two band-limited loads that are not drawn from the filter's prior.  A 30 x 30 GA (seed 0) with
the default modes (the band rule: 118 of 147 modes with the dropped modes' noise in R) against
the same GA on the full model (296 states; about 15 minutes, skipped by --quick), and the
ranking of 30 random layouts.  Targets (issue 35): the default GA <= 60 s, its layout's
full-model fitness within 5 % of the full-model GA's, Spearman >= 0.95.
"""
import sys
import time

import numpy as np
from scipy.stats import spearmanr

from core_akf.loads import band_limited_white_noise
from core_akf.models import footbridge
from sensoropt import CandidateSet, StrainErrorObjective, place

DT = 1.0 / 512
FORCES = ["21:z", "34:z"]
SETTINGS = dict(window=2.0, stiffness_factor=1.02, relative_noise=0.02, model_error_cov=1e-14, force_increment_cov=1e3,
                seed=0)


def main(quick=False):
    s = footbridge(n_panels=12)
    n = int(SETTINGS["window"] / DT)
    loads = np.column_stack([band_limited_white_noise(n, DT, 300.0, 1.0, 20.0, seed=1) - 700.0,
                             band_limited_white_noise(n, DT, 200.0, 2.0, 40.0, seed=2)])
    enc = CandidateSet(s, kinds=("strain", "acc:z", "acc:y"), budget={"strain": 4, "acc": 2})
    print(f"3-D truss: {s.n} DOFs, {len(enc.candidates)} candidates, 512 Hz, 4 gauges + 2 accelerometers")
    full = StrainErrorObjective(s, FORCES, loads, DT, enc, n_modes=None, **SETTINGS)
    rows = {}
    for name, n_modes in (("default (band rule)", "auto"), ("full model", None)):
        if quick and n_modes is None:
            continue
        t0 = time.perf_counter()
        obj = StrainErrorObjective(s, FORCES, loads, DT, enc, n_modes=n_modes, **SETTINGS)
        res = place(obj, enc, seed=0, population=30, generations=30)
        wall = time.perf_counter() - t0
        rows[name] = (wall, full.evaluate([res.sensors])[0])
        print(f"  {name:20s} {obj.model.n_a:4d} states  GA {wall:7.1f} s  {res.evaluations:4d} evaluations  "
              f"full-model fitness {rows[name][1]:.4f} µε  {' '.join(res.sensors)}", flush=True)
    if "full model" in rows:
        print(f"default / full-model GA: time {rows['default (band rule)'][0] / rows['full model'][0]:.3f}, "
              f"fitness {rows['default (band rule)'][1] / rows['full model'][1]:.4f} (target <= 1.05)")
    rng = np.random.default_rng(0)
    layouts = [enc.sensors(enc.random_layout(rng)) for _ in range(30)]
    a = np.array(full.evaluate(layouts))
    b = np.array(StrainErrorObjective(s, FORCES, loads, DT, enc, **SETTINGS).evaluate(layouts))
    print(f"30 random layouts: Spearman {spearmanr(a, b).correlation:.3f} (target >= 0.95), median difference "
          f"{np.median(np.abs(b / a - 1)):.1%}")


if __name__ == "__main__":
    main(quick="--quick" in sys.argv)
