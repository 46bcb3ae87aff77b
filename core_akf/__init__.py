"""core_akf: FE models, heterogeneous sensors, state space and the augmented Kalman filter."""
from .exceptions import AKFInputError, ModelError, UndetectableError
from .structure import Structure

__version__ = "0.1.0"
__all__ = ["Structure", "AKFInputError", "ModelError", "UndetectableError"]
