"""Finite-element models: planar truss and Mindlin plate, plus the papers' presets."""
from .plate import imp_plate, plate, th_plate, uniform_pressure_load
from .truss import planar_truss, s17_truss

__all__ = ["s17_truss", "planar_truss", "plate", "th_plate", "imp_plate", "uniform_pressure_load"]
