"""What several test modules share: the estimate pipeline on a job dict, a simulated record as a file."""
from akf.estimate import estimate_job
from akf.job import Job


def run_estimate(job, out=None, *, steady=None, allow_undetectable=None, **run_options):
    """:func:`akf.estimate.estimate_job` of a job dict (as read from TOML) into ``out`` (None: in
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


def measured_s17_files(tmp_path, files, output):
    """S17 case 4 (the true model, 1 s) as a measured record in ``files`` CSV files under
    ``tmp_path/rec``: the job dict reading them (``*.csv`` for several files), with ``[output]``
    as given."""
    import numpy as np
    import pandas as pd

    from akf.examples import example_job
    from akf.job import Job

    data = example_job("s17-case4")
    data["simulation"]["duration"] = 1.0
    data["filter"]["stiffness_factor"] = 1.0
    sim = Job.from_dict(data, "estimate").simulate()
    frame = pd.DataFrame(sim.measurements, columns=data["sensors"])
    frame.insert(0, "time", np.arange(len(frame)) * data["dt"])
    folder = tmp_path / "rec"
    folder.mkdir(parents=True, exist_ok=True)
    for i, part in enumerate(np.array_split(np.arange(len(frame)), files)):
        frame.iloc[part].to_csv(folder / f"part{i:02d}.csv", index=False, float_format="%.17g")
    measured = {k: v for k, v in data.items() if k != "simulation"}
    measured["filter"]["noise_cov"] = [float(v) ** 2 for v in sim.noise_std]
    measured["measurements"] = {"file": str(folder / ("*.csv" if files > 1 else "part00.csv")), "chunk": 0.1}
    measured["output"] = output
    return measured


def read_record(path, sensors, dt, **channel_map):
    """A measured record's data (N x m, SI) through :class:`core_akf.io.Record`, its sampling
    interval checked against ``dt``."""
    from core_akf.io import Record

    record = Record(path, sensors, **channel_map)
    record.check_dt(dt)
    return record.read()[1]
