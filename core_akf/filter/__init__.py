"""The augmented Kalman filter (AKF), one package (Lourens et al. 2012; S17 eq. 14-26, IMP eq. 12-25),
with a random-walk or a Matérn Gaussian-process force model and dummy measurements
(:mod:`core_akf.forcemodels`).

- :mod:`~core_akf.filter.model` -- :class:`FilterModel` (the layout-free augmented model, full or
  reduced) and :class:`Filter` (a model with layouts, covariances and prior, built and checked once);
- :mod:`~core_akf.filter.kernels` -- the pure steady and time-varying kernels, the one fixed-gain
  step, innovations and their covariance, and the filter through missing samples;
- :mod:`~core_akf.filter.matrices` -- :func:`run` / :func:`filter_states` on matrices of one's own;
- :mod:`~core_akf.filter.results` -- :class:`Estimate`, which carries its own summary;
- :mod:`~core_akf.filter.estimate` -- :func:`estimate` and :func:`estimate_batch`;
- :mod:`~core_akf.filter.streaming` -- :class:`Estimator`, a record in chunks;
- :mod:`~core_akf.filter.parallel` -- the time-parallel filter over a record's pieces;
- :mod:`~core_akf.filter.smoother` -- the RTS and fixed-lag smoothers;
- :mod:`~core_akf.filter.transfer` -- :func:`force_transfer`, what a layout sees of each force per
  frequency;
- :mod:`~core_akf.filter.riccati`, :mod:`~core_akf.filter.recursion` (with the threads for stacks)
  and :mod:`~core_akf.filter.likelihood` -- the numerics beneath.
"""
from .estimate import estimate, estimate_batch, run_filter
from .kernels import FilterRun
from .matrices import filter_states, run
from .model import Filter, FilterModel
from .parallel import TimeParallel, estimate_in_parallel, zero_state_end
from .results import Estimate
from .smoother import FixedLagSmoother, SmoothResult, smooth
from .streaming import CheckpointError, Estimator
from .transfer import force_transfer, recovered_band

__all__ = ["Filter", "FilterModel", "FilterRun", "Estimate", "estimate", "estimate_batch", "run_filter", "run",
           "filter_states", "smooth", "SmoothResult", "FixedLagSmoother", "Estimator", "CheckpointError",
           "TimeParallel", "estimate_in_parallel", "zero_state_end", "force_transfer", "recovered_band"]
