"""Type aliases of the public API (for annotations; nothing here runs or checks shapes).

A sensor is a string in the sensor grammar (``"strain:13"``, ``"strain:70:ex"``, ``"acc:8:y"``)
or a :class:`~core_akf.sensors.Sensor`; a force location is ``"8:y"`` or ``(8, "y")``; a
covariance is one level, a vector of variances, a matrix, or (for measurement noise) a table of
variances per sensor kind.  SI units throughout.

The array aliases carry their shape and unit as :data:`typing.Annotated` metadata, as dynamax's
``types.py`` does with jaxtyping: ``Measurements`` is an array of shape (N, m) -- N time steps,
m sensors -- in the sensors' SI units.  Letters: N time steps, m sensors, n generalised
coordinates (2n structural states), n_p unknown forces, n_a = 2n + n_p augmented states,
B a batch of problems.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Annotated, Protocol, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray


class SensorLike(Protocol):
    """What a :class:`core_akf.sensors.Sensor` is to an annotation: an object with a ``kind`` and a
    ``label`` (structural, so that this module imports none of the modules that use it)."""

    kind: str

    @property
    def label(self) -> str:
        """The sensor's string, e.g. ``"acc:8:y"``."""


#: a sensor: its string (``"strain:13"``) or a :class:`core_akf.sensors.Sensor`
SensorSpec = Union[str, SensorLike]
Layout = Sequence[SensorSpec]
ForceSpec = Union[str, tuple[int, str]]
Forces = Sequence[ForceSpec]
#: a force location as the library returns it: 1-based node id and direction
ForceLocation = tuple[int, str]
Covariance = Union[float, ArrayLike]
NoiseCovariance = Union[float, ArrayLike, Mapping[str, float]]
#: damping of a model: a modal ratio (one, or one per mode), ``("rayleigh", alpha, beta)`` or None
Damping = Union[float, Sequence[float], tuple, None]
#: a random stream: a seed or a numpy Generator
Seed = Union[int, np.random.Generator, None]

FloatArray = NDArray[np.float64]
#: measurements: one row per time step, one column per sensor, SI (m/m, m/s^2, m/s, m)
Measurements = Annotated[ArrayLike, "(N, m) SI"]
#: a batch of measurement sets, one per layout
BatchMeasurements = Annotated[ArrayLike, "(B, N, m) SI"]
#: force histories, one column per force location
ForceHistories = Annotated[ArrayLike, "(N, n_p) N"]
#: one signal over time
Signal = Annotated[FloatArray, "(N,)"]
#: a time grid
Time = Annotated[FloatArray, "(N,) s"]
#: a square matrix (K, M, C, a covariance), or a stack of them
Matrix = Annotated[ArrayLike, "(..., n, n)"]
#: a layout as the placement GA holds it: sorted candidate indices (0-based)
CandidateLayout = tuple[int, ...]

__all__ = ["ArrayLike", "SensorLike", "SensorSpec", "Layout", "ForceSpec", "Forces", "ForceLocation", "Covariance",
           "NoiseCovariance", "Damping", "Seed", "FloatArray", "Measurements", "BatchMeasurements", "ForceHistories", "Signal",
           "Time", "Matrix", "CandidateLayout"]
