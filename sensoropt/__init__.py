"""Sensor placement on any structure: a genetic algorithm over the sensor layouts of a candidate
set (every strain output, accelerometers at free DOFs, any subset of one's own) that minimises
the augmented Kalman filter's whole-response error, or an objective of one's own.

- :class:`CandidateSet` -- the admissible sensors of any model (a truss, a 3-D frame, a model from
  its matrices); :class:`PlateGrid` -- the thesis' mixed-integer plate encoding (TH §4);
- :class:`StrainErrorObjective` (the average strain error of the steady AKF, batched over the
  layouts of a generation), :class:`FatigueErrorObjective`, :class:`FunctionObjective` (yours);
- :func:`place` -- the GA (core_akf's one engine: seeded, cached, parallel, checkpointed);
  :func:`pareto` -- NSGA-II fronts; :class:`PlacementProblem` -- a placement study of a job;
- :class:`Uncertainty` -- layouts scored over true structures unlike the filter's model;
  :class:`Constraints` -- costs, a budget, forbidden regions, a minimum spacing.

>>> import numpy as np
>>> from core_akf.models import s17_truss
>>> from sensoropt import CandidateSet, StrainErrorObjective, place
>>> truss, loads = s17_truss(), np.random.default_rng(0).normal(0, 100, (400, 1)).cumsum(axis=0)
>>> enc = CandidateSet(truss, kinds=("strain",), n_sensors=2)
>>> obj = StrainErrorObjective(truss, ["8:y"], loads, 1e-3, enc, window=0.2)
>>> res = place(obj, enc, seed=0, generations=2, population=8)
>>> len(res.sensors)
2
"""
from .constraints import Constrained, Constraints
from .encoding import KINDS, STRAIN_KINDS, CandidateSet, PlateGrid, make_encoding
from .ga import THESIS, PlacementResult, independent_runs, place
from .objective import FatigueErrorObjective, FunctionObjective, Objective, StrainErrorObjective
from .pareto import ParetoResult, pareto
from .plots import plot_convergence, plot_layout, plot_pareto
from .problem import PlacementProblem
from .robust import MEASURES, Uncertainty, combine

__all__ = ["KINDS", "STRAIN_KINDS", "CandidateSet", "PlateGrid", "make_encoding", "THESIS",
           "PlacementResult", "independent_runs", "place", "Objective", "FunctionObjective", "StrainErrorObjective",
           "FatigueErrorObjective",
           "ParetoResult", "pareto", "plot_convergence", "plot_layout", "plot_pareto", "PlacementProblem",
           "Constrained", "Constraints", "MEASURES", "Uncertainty", "combine"]
