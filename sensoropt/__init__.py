"""Sensor placement on plates with a mixed-integer GA on DEAP (TH §4).

>>> from sensoropt import PlateGrid, StrainErrorObjective, place     # doctest: +SKIP
>>> enc = PlateGrid(plate, kinds=("ex", "ey", "gxy"), n_sensors=3)                # doctest: +SKIP
>>> obj = StrainErrorObjective(plate, forces, loads, dt, enc, window=0.1)         # doctest: +SKIP
>>> res = place(obj, enc, seed=0, n_jobs=2)                                       # doctest: +SKIP
>>> res.layout, res.best_error                                                    # doctest: +SKIP
"""
from .encoding import KINDS, STRAIN_KINDS, CandidateSet, Encoding, PlateGrid, make_encoding
from .ga import THESIS, PlacementResult, independent_runs, place
from .objective import FatigueErrorObjective, FunctionObjective, Objective, StrainErrorObjective
from .pareto import ParetoResult, pareto
from .plots import plot_convergence, plot_layout, plot_pareto
from .problem import PlacementProblem

__all__ = ["KINDS", "STRAIN_KINDS", "CandidateSet", "PlateGrid", "Encoding", "make_encoding", "THESIS",
           "PlacementResult", "independent_runs", "place", "Objective", "FunctionObjective", "StrainErrorObjective",
           "FatigueErrorObjective",
           "ParetoResult", "pareto", "plot_convergence", "plot_layout", "plot_pareto", "PlacementProblem"]
