"""What several test modules share: the repository root, job snippets, the estimate pipeline on a job dict, a
simulated record as a file."""
import pathlib

from akf.estimate import estimate_job
from akf.job import Job

#: the repository's root folder
ROOT = pathlib.Path(__file__).resolve().parents[1]
#: node ids of the 3-D frame of one's own are the S17 truss' plus this
OFFSET = 100

SIMULATION = """[filter]
model_error_cov = 1e-16
force_increment_cov = 1e4
[simulation]
duration = 1.0
relative_noise = 0.02
[[simulation.loads]]
components = [{type = "sine", frequency = 3.0, amplitude = 300.0}]
"""

PLACE_3D = """[place]
candidates = ["strain:5", "strain:13", "strain:35", "strain:36", "acc:108:y", "acc:106:y"]
budget = {strain = 2, acc = 1}
window = 0.25
population = 6
generations = 2
"""


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


#: the sample data-acquisition files
DAQ = ROOT / "examples" / "daq"


def measured_job(tmp_path, extra=""):
    """The S17 case-4 job on the SI CSV record, short chunks (20 ms), as a job file in ``tmp_path``."""
    text = (DAQ / "s17-tdms.toml").read_text()
    head = text[:text.index("[measurements]")]
    job = tmp_path / "job.toml"
    job.write_text(head + f'[measurements]\nfile = "{DAQ / "record-si.csv"}"\nchunk = 0.02\n' + extra)
    return job


def two_dof(**changes):
    """A two-DOF model of one's own (springs of 1 MN/m, 10 kg masses) with ``changes`` to its inputs."""
    import numpy as np

    from core_akf.models import from_matrices

    kw = dict(K=np.array([[2.0, -1.0], [-1.0, 1.0]]) * 1e6, M=np.eye(2) * 10.0, dofs=[(1, "x"), (2, "x")],
              nodes={1: (1.0, 0.0), 2: (2.0, 0.0)}) | changes
    return from_matrices(**kw)


def read_channels(path, sensors=("acc:4:y", "acc:6:y"), **kw):
    """``(time, data)`` of ``sensors`` in a record file (:class:`core_akf.io.Record`)."""
    from core_akf.io import Record

    record = Record(str(path), list(sensors), **kw)
    return record.read()
