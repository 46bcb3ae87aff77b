"""Write the impact records of this folder: three impacts on the S17 truss (IMP case 1 set-up:
a 4 ms half-sine over background excitation, 1 microstrain and 1 mg noise) at nodes 14, 6 and
11 with 10, 6 and 8 kN, each a TDMS file (npTDMS) with the channel names and units of a DAQ
(strain gauges SGnn in microstrain, accelerometers ACCnn in g).

Run from the repository root: ``python examples/impacts/make_events.py``.
"""
import os

from akf.examples.impact import example_scenario

HERE = os.path.dirname(os.path.abspath(__file__))
EVENTS = [("impact-0001", 14, 10e3), ("impact-0002", 6, 6e3), ("impact-0003", 11, 8e3)]


def channel_name(sensor):
    parts = sensor.split(":")
    return f"SG{parts[1]}" if parts[0] == "strain" else f"ACC{parts[1]}{parts[2].upper()}"


def main():
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    for k, (name, node, peak) in enumerate(EVENTS):
        sc = example_scenario("imp-truss-case1", impact_node=node, seed=k)
        scale = peak / 10e3                  # the example's pulse is 10 kN; background and noise scale along
        with TdmsWriter(os.path.join(HERE, f"{name}.tdms")) as w:
            w.write_segment([GroupObject("DAQ")] + [
                ChannelObject("DAQ", channel_name(s), sc.measurements[:, j] * scale * (1e6 if s.startswith("strain")
                                                                                      else 1 / 9.80665),
                              properties={"unit_string": "microstrain" if s.startswith("strain") else "g",
                                          "wf_increment": sc.dt, "wf_start_offset": 0.0})
                for j, s in enumerate(sc.sensors)])


if __name__ == "__main__":
    main()
