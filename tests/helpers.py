"""What several test modules share: the estimate pipeline on a job dict, a simulated record as a file."""
from akf.estimating import estimate_job
from akf.job import Job


def run_estimate(job, out=None, *, steady=None, allow_undetectable=None, **run_options):
    """:func:`akf.estimating.estimate_job` of a job dict (as read from TOML) into ``out`` (None: in
    memory), with ``[filter] steady`` / ``allow_undetectable`` overridden when given and the
    other options (``resume``, ``stop_after``, ``plot``, ...) passed on."""
    overrides = {f"filter.{k}": v for k, v in {"steady": steady, "allow_undetectable": allow_undetectable}.items()
                 if v is not None}
    return estimate_job(Job.from_dict(job, "estimate", overrides=overrides), out, **run_options)


def write_record(simulation, sensors, dt, path):
    """A simulated record as a measured one: a CSV file of a time column and one column per sensor
    (full precision).  Returns ``path``."""
    import numpy as np
    import pandas as pd

    frame = pd.DataFrame(simulation.measurements, columns=list(sensors))
    frame.insert(0, "time", np.arange(len(frame)) * dt)
    frame.to_csv(path, index=False, float_format="%.17g")
    return path
