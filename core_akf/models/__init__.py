"""Finite-element models: planar truss and Mindlin plate, the papers' presets, a 3-D truss
footbridge, and any linear model brought as matrices (:func:`from_matrices`; large sparse ones
reduced with a static correction, :mod:`core_akf.models.sparse`)."""
from .footbridge import footbridge, footbridge_matrices
from .matrices import from_files, from_matrices, load_matrix
from .plate import imp_plate, plate, plate_matrices, th_plate, uniform_pressure_load
from .truss import planar_truss, s17_truss

__all__ = ["s17_truss", "planar_truss", "plate", "th_plate", "imp_plate", "uniform_pressure_load", "plate_matrices", "from_matrices",
           "from_files", "load_matrix", "footbridge", "footbridge_matrices"]
