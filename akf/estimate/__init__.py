"""``akf estimate``: one job through the filter to its result, files and figures.

- :mod:`~akf.estimate.pipeline` -- :func:`estimate_job` and the sequential run, chunk by chunk;
- :mod:`~akf.estimate.files` -- the time series, the checkpoint and the figures in the output folder;
- :mod:`~akf.estimate.metrics` -- the metrics, the summary table and :class:`EstimateResult`;
- :mod:`~akf.estimate.pieces` -- a record of many files filtered time-parallel.
"""
from .metrics import METRIC_UNITS, EstimateResult, summary_frame
from .pipeline import estimate_job

__all__ = ["estimate_job", "EstimateResult", "summary_frame", "METRIC_UNITS"]
