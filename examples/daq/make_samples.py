"""Write the sample records of this folder: the S17 truss, load case 4, 0.25 s simulated and
stored the way data-acquisition systems store it -- channel names of their own, units of their
own (microstrain, g, mm/s^2, a bridge output in mV/V), one accelerometer mounted upside down --
in each format, by the format's own library: CSV and Parquet (pandas/pyarrow), TDMS (npTDMS),
UFF 58 (pyuff, ASCII), HDF5 (h5py).  ``record-si.csv`` holds the same samples converted to SI by
the plain formulas below, with columns named like the sensors: the reference of the round trip.

Run from the repository root: ``python examples/daq/make_samples.py``.
"""
import os

import numpy as np
import pandas as pd

from akf.examples import example_job
from akf.job import Job

HERE = os.path.dirname(os.path.abspath(__file__))
G_N = 9.80665
GAUGE_FACTOR = 2.1
#: sensor -> (file channel, unit, resolution in that unit, sign as mounted)
CHANNELS = {
    "acc:4:y": ("ACC_4Y", "g", 1e-9, 1.0), "acc:6:y": ("ACC_6Y", "g", 1e-9, 1.0),
    "acc:8:y": ("ACC_8Y", "mm/s^2", 1e-6, 1.0), "acc:12:y": ("ACC_12Y", "m/s^2", 1e-9, 1.0),
    "acc:6:x": ("ACC_6X", "g", 1e-9, -1.0),
    "strain:5": ("SG5", "microstrain", 1e-6, 1.0), "strain:9": ("SG9", "microstrain", 1e-6, 1.0),
    "strain:13": ("SG13", "mV/V", 1e-10, 1.0), "strain:26": ("SG26", "microstrain", 1e-6, 1.0),
}


def to_file_units(sensor, si):
    """SI -> the file's unit (what the DAQ wrote), quantised to its resolution and stored as the
    double nearest to that short decimal (so every format holds the same numbers)."""
    name, unit, res, sign = CHANNELS[sensor]
    x = sign * si
    if unit == "g":
        x = x / G_N
    elif unit == "mm/s^2":
        x = x * 1e3
    elif unit == "microstrain":
        x = x * 1e6
    elif unit == "mV/V":          # quarter bridge: strain = 4 r / (GF (1 + 2 r)), r in V/V
        x = 1e3 * (GAUGE_FACTOR * x) / (4.0 - 2.0 * GAUGE_FACTOR * x)
    return np.array([float(f"{v:.10g}") for v in np.round(x / res) * res])


def to_si(sensor, raw):
    """The file's values back to SI, by the formulas (independent of core_akf.io)."""
    name, unit, res, sign = CHANNELS[sensor]
    if unit == "g":
        x = raw * G_N
    elif unit == "mm/s^2":
        x = raw * 1e-3
    elif unit == "microstrain":
        x = raw * 1e-6
    elif unit == "mV/V":
        r = raw * 1e-3
        x = 4.0 * r / (GAUGE_FACTOR * (1.0 + 2.0 * r))
    else:
        x = raw
    return sign * x


def main():
    job = example_job("s17-case4")
    job["simulation"]["duration"] = 0.25
    sim = Job.from_dict(job, "estimate").simulate()
    dt = float(job["dt"])
    sensors = job["sensors"]
    n = sim.measurements.shape[0]
    t = np.arange(n) * dt
    raw = {CHANNELS[s][0]: to_file_units(s, sim.measurements[:, j]) for j, s in enumerate(sensors)}
    units = {CHANNELS[s][0]: CHANNELS[s][1] for s in sensors}

    si = pd.DataFrame({"time": t} | {s: to_si(s, raw[CHANNELS[s][0]]) for s in sensors})
    si.to_csv(os.path.join(HERE, "record-si.csv"), index=False, float_format="%.17g")
    frame = pd.DataFrame({"time": t} | raw)
    frame.to_csv(os.path.join(HERE, "record.csv"), index=False, float_format="%.17g")
    frame.to_parquet(os.path.join(HERE, "record.parquet"), index=False)

    from nptdms import ChannelObject, GroupObject, TdmsWriter
    with TdmsWriter(os.path.join(HERE, "record.tdms")) as w:
        w.write_segment([GroupObject("DAQ")] + [
            ChannelObject("DAQ", name, values, properties={"unit_string": units[name], "wf_increment": dt,
                                                           "wf_start_offset": 0.0})
            for name, values in raw.items()])

    import h5py
    with h5py.File(os.path.join(HERE, "record.h5"), "w", track_order=True) as f:
        f.attrs["dt"], f.attrs["t0"] = dt, 0.0
        for name, values in raw.items():
            f.create_dataset(name, data=values, track_times=False).attrs["unit"] = units[name]

    import pyuff
    sets = []
    for s in sensors:
        name = CHANNELS[s][0]
        node = int(s.split(":")[1])
        direction = {"x": 1, "y": 2}.get(s.split(":")[-1], 0)
        sets.append(pyuff.prepare_58(
            binary=0, id1=name, func_type=1, rsp_node=node, rsp_dir=direction, ref_node=0, ref_dir=0,
            ord_data_type=4, abscissa_spacing=1, num_pts=n, x=t, data=raw[name], abscissa_spec_data_type=17,
            abscissa_axis_units_lab="s", ordinate_spec_data_type=0, ordinate_axis_units_lab=units[name],
            orddenom_spec_data_type=0, z_axis_spec_data_type=0))
    pyuff.UFF(os.path.join(HERE, "record.uff")).write_sets(sets, mode="overwrite")


if __name__ == "__main__":
    main()
