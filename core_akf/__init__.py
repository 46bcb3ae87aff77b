"""core_akf: FE models, heterogeneous sensors, state space and the augmented Kalman filter.

The most used names are importable from here::

    from core_akf import models, estimate, simulate, detectability, rms_error
"""
from . import loads, models
from .checks import AKFInputError, ModelError, UndetectableError
from .filter import Estimate, Filter, FilterModel, SmoothResult, estimate, estimate_batch, run, smooth
from .forcemodels import DummyMeasurements, ForceModel
from .metrics import average_strain_error, rms_error
from .sensors import Sensor
from .simulate import Simulation, simulate
from .statespace import detectability, state_space
from .structure import Structure

__version__ = "0.1.0"
__all__ = [
    "models", "loads", "Structure", "Sensor", "Filter", "FilterModel",
    "estimate", "estimate_batch", "run", "smooth", "SmoothResult", "Estimate",
    "simulate", "Simulation", "detectability", "state_space", "rms_error", "average_strain_error",
    "AKFInputError", "ModelError", "UndetectableError", "ForceModel", "DummyMeasurements",
]
