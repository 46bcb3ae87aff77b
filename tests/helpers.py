"""What several test modules share: the estimate pipeline on a job dict."""
from akf.estimating import estimate_job
from akf.job import Job


def run_estimate(job, out=None, *, steady=None, allow_undetectable=None, **run_options):
    """:func:`akf.estimating.estimate_job` of a job dict (as read from TOML) into ``out`` (None: in
    memory), with ``[filter] steady`` / ``allow_undetectable`` overridden when given and the
    other options (``resume``, ``stop_after``, ``plot``, ...) passed on."""
    overrides = {f"filter.{k}": v for k, v in {"steady": steady, "allow_undetectable": allow_undetectable}.items()
                 if v is not None}
    return estimate_job(Job.from_dict(job, "estimate", overrides=overrides), out, **run_options)
