"""Impact localisation with the augmented Kalman filter (IMP, Saleem & Jo 2019).

Installed sensors are split into SE (fed to the AKF) and AD (held back) roles in every
combination; for every candidate location the AKF with an assumed force there predicts the AD
sensors, and the location with the lowest mean (then spread) of the AD error is the impact
location.  A GA then tunes the covariance levels and the AKF reconstructs the force history.

>>> from impactloc import locate
>>> from akf.examples.impact import example_scenario              # the application layer's built-in cases
>>> sc = example_scenario("imp-truss-case1")                       # doctest: +SKIP
>>> res = locate(sc.structure, sc.sensors, sc.measurements, sc.dt, n_ad=4,
...              ad_kinds=("strain",), direction="y")              # doctest: +SKIP
>>> res.identified, res.scan.confidence, res.reconstruction.summary.peak   # doctest: +SKIP
"""
from .locate import LocateResult, locate
from .plots import plot_locate
from .reconstruct import ForceSummary, Reconstruction, force_summary, reconstruct
from .roles import RoleSplit, role_splits
from .scan import Covariances, ImpactModel, ScanResult, candidate_locations, default_covariances, scan
from .simulation import simulate_impact
from .tuning import TuningResult, tune_covariances, tune_covariances_ml

__all__ = ["LocateResult", "locate", "plot_locate", "ForceSummary", "Reconstruction",
           "force_summary", "reconstruct", "RoleSplit", "role_splits", "Covariances", "ImpactModel", "ScanResult",
           "candidate_locations", "default_covariances", "scan", "simulate_impact", "TuningResult", "tune_covariances",
           "tune_covariances_ml"]
