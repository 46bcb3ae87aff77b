"""Type aliases of the public API (for annotations; nothing here runs).

A sensor is a string in the sensor grammar (``"strain:13"``, ``"strain:70:ex"``, ``"acc:8:y"``)
or a :class:`~core_akf.sensors.Sensor`; a force location is ``"8:y"`` or ``(8, "y")``; a
covariance is one level, a vector of variances, a matrix, or (for measurement noise) a table of
variances per sensor kind.  SI units throughout.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Union

from numpy.typing import ArrayLike

if TYPE_CHECKING:
    from .sensors import Sensor

SensorSpec = Union[str, "Sensor"]
Layout = Sequence[SensorSpec]
ForceSpec = Union[str, tuple[int, str]]
Forces = Sequence[ForceSpec]
Covariance = Union[float, ArrayLike]
NoiseCovariance = Union[float, ArrayLike, Mapping[str, float]]

__all__ = ["ArrayLike", "SensorSpec", "Layout", "ForceSpec", "Forces", "Covariance", "NoiseCovariance"]
