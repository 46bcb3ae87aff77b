"""Inputs a user types: encodings of job files, strain and gravity units, scheduler addresses, populations."""
import os

import numpy as np
import pytest
from helpers import ROOT

from akf.cli import main
from core_akf.models import s17_truss

CASE4 = os.path.join(ROOT, "akf", "examples", "jobs", "s17-case4.toml")


@pytest.mark.parametrize("encoding, message", [
    ("utf-16", "is UTF-16 text"), ("utf-16-le", "looks like UTF-16 text without a byte-order mark"),
    ("latin-1", "looks like Latin-1 / Windows-1252 text"), ("binary", "not a text file")])
def test_job_file_in_another_encoding(tmp_path, capsys, encoding, message):
    text = open(CASE4, encoding="utf-8").read().replace('name = "s17-case4"', 'name = "s17-café"')
    job = tmp_path / "job.toml"
    if encoding == "binary":
        job.write_bytes(bytes(range(256)))
    else:
        job.write_bytes(text.encode(encoding))
    assert main(["estimate", str(job), "--no-plot", "--out", str(tmp_path / "o")]) == 2
    assert message in capsys.readouterr().err


def test_job_file_with_a_utf8_byte_order_mark_is_read(tmp_path):
    from akf.job import load_job_file

    job = tmp_path / "job.toml"
    job.write_bytes(b"\xef\xbb\xbf" + open(CASE4, "rb").read())
    assert load_job_file(job)["name"] == "s17-case4"


@pytest.mark.parametrize("table", ["structure", "filter", "simulation"])
def test_a_top_level_key_after_a_table_header(tmp_path, capsys, table):
    text = open(CASE4).read()
    lines = [line for line in text.splitlines() if not line.startswith("dt =")]
    at = lines.index(f"[{table}]") + 1
    job = tmp_path / "job.toml"
    job.write_text("\n".join(lines[:at] + ["dt = 0.000244140625"] + lines[at:]) + "\n")
    assert main(["estimate", str(job), "--no-plot", "--out", str(tmp_path / "o")]) == 2
    assert f"'dt' sits in [{table}], but it is a top-level key" in capsys.readouterr().err


@pytest.mark.parametrize("unit, gauge_factor, message", [
    ("mV", 2.1, "is a voltage in 'mV', not a bridge ratio"),
    ("rad", None, "'rad' is an angle, not a strain"),
    ("deg", None, "'deg' is an angle, not a strain")])
def test_strain_units_that_are_not_strain(unit, gauge_factor, message):
    from core_akf.io.units import conversion

    with pytest.raises(ValueError, match=message):
        conversion(unit, "strain", "SG1", gauge_factor=gauge_factor)


@pytest.mark.parametrize("unit, scale", [("uE", 1e-6), ("µE", 1e-6), ("ue", 1e-6), ("με", 1e-6), ("mm/m", 1e-3),
                                         ("µɛ", 1e-6), ("uɛ", 1e-6)])
def test_common_strain_abbreviations(unit, scale):
    from core_akf.io.units import conversion

    assert conversion(unit, "strain", "SG1")(np.array([2.0]))[0] == pytest.approx(2 * scale)


@pytest.mark.parametrize("unit", ["g", "G", "gn"])
def test_gravity_as_daq_systems_write_it(unit):
    from core_akf.io.units import conversion

    assert conversion(unit, "acc", "ACC1")(np.array([1.0]))[0] == pytest.approx(9.80665)


@pytest.mark.parametrize("unit, kind, scale", [("m/s2", "acc", 1.0), ("mm/s2", "acc", 1e-3), ("m s-2", "acc", 1.0),
                                               ("cm/s2", "acc", 1e-2), ("m/sec2", "acc", 1.0), ("ft/s2", "acc", 0.3048)])
def test_a_power_written_as_bare_digits_as_daq_systems_label_channels(unit, kind, scale):
    from core_akf.io.units import conversion

    assert conversion(unit, kind, "ACC1")(np.array([2.0]))[0] == pytest.approx(2 * scale)


@pytest.mark.parametrize("unit, message", [("m/s3", "'m/s3' is not a unit of acc"), ("xyz2", "unknown unit 'xyz2'")])
def test_bare_digits_that_make_no_acceleration_are_still_named(unit, message):
    from core_akf.io.units import conversion

    with pytest.raises(ValueError, match=message):
        conversion(unit, "acc", "ACC1")


def test_v_per_v_is_a_bridge_output():
    from core_akf.io.units import conversion

    c = conversion("V/V", "strain", "SG1", gauge_factor=2.0, bridge="full")
    assert c(np.array([1e-3]))[0] == pytest.approx(0.5e-3)


@pytest.mark.parametrize("address, message", [
    ("http://127.0.0.1:8787/status", "is a web address"), ("tcp://scheduler-host", "needs a host and a port"),
    ("tls://scheduler-host:8786", "no client certificate is configured"), ("ftp://h:21", "unknown address scheme")])
def test_scheduler_addresses_that_cannot_be_one(address, message):
    pytest.importorskip("distributed")
    from akf.parallel import check_scheduler

    with pytest.raises(ValueError, match=message):
        check_scheduler(address)


def test_scheduler_port_that_accepts_and_says_nothing_is_not_a_hang():
    pytest.importorskip("distributed")
    import socket
    import time

    from akf.parallel import probe_scheduler

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(4)
    t0 = time.perf_counter()
    try:
        with pytest.raises(ValueError, match="did not answer as a dask scheduler within 1 s"):
            probe_scheduler(f"tcp://127.0.0.1:{server.getsockname()[1]}", timeout=1.0)
    finally:
        server.close()
    assert time.perf_counter() - t0 < 30


def test_population_that_does_not_fit_in_memory(tmp_path, capsys):
    assert main(["place", "--example", "th-case5", "--population", "1000000000", "--out", str(tmp_path)]) == 2
    assert "a GA of population 1000000000 over 100 generations" in capsys.readouterr().err


def test_population_of_a_cost_front_that_does_not_fit_in_memory(tmp_path, capsys):
    """The NSGA-II front (objectives = ["error", "cost"]) drew 10^9 layouts one by one, silent past 90 s."""
    import tomlkit

    from akf.examples import load_example

    data = load_example("th-case5", "place")
    data["place"].update(objectives=["error", "cost"], population=10**9, generations=2)
    data["simulation"]["duration"] = 0.5
    job = tmp_path / "front.toml"
    job.write_text(tomlkit.dumps(data))
    assert main(["place", str(job), "--no-plot", "--out", str(tmp_path / "o")]) == 2
    assert "a GA of population 1000000000 over 2 generations" in capsys.readouterr().err


def test_a_simulated_record_that_cannot_fit_is_refused_before_its_loads_are_built(tmp_path, capsys):
    """A place job's duration of 1e300 s ended in numpy's "Maximum allowed size exceeded" (internal error)."""
    import tomlkit

    from akf.examples import load_example

    data = load_example("th-case5", "place")
    data["simulation"]["duration"] = 1e300
    job = tmp_path / "long.toml"
    job.write_text(tomlkit.dumps(data))
    assert main(["place", str(job), "--no-plot", "--out", str(tmp_path / "o")]) == 2
    assert "a 1e+300 s record at dt = 0.0005 s" in capsys.readouterr().err


def test_diversity_of_a_large_population_is_sampled():
    from sensoropt.encoding import DIVERSITY_SAMPLE, make_encoding

    enc = make_encoding(s17_truss(), kinds=("strain",), n_sensors=3)
    rng = np.random.default_rng(0)
    pop = [enc.random_layout(rng) for _ in range(DIVERSITY_SAMPLE + 300)]
    assert enc.diversity(pop) == pytest.approx(enc.diversity([pop[i] for i in np.linspace(
        0, len(pop) - 1, DIVERSITY_SAMPLE).astype(int)]))


@pytest.mark.parametrize("force, key, value, message", [
    (1, "duration", 1e-4, "the 'pulse' load is zero at every sample"),                   # between two samples
    (3, "start", 5.0, "ramp end"),                                                       # after its end
    (0, "f_high", 0.1, "the band 0-0.1 Hz holds no frequency of a record of 8192 steps"),
])
def test_a_load_the_record_s_samples_miss_is_named_by_its_force(force, key, value, message):
    from akf.examples import example_job
    from akf.job import Job

    data = example_job("s17-case4")
    component = data["simulation"]["loads"][force]["components"][-1]
    assert key in component or key == "f_high"
    component[key] = value
    with pytest.raises(ValueError, match=rf"simulation\.loads\[{force}\] \(force {force + 1}\)") as err:
        Job.from_dict(data, "estimate").simulate()
    assert message in str(err.value)


def test_a_load_after_the_record_s_end_is_a_named_warning(tmp_path, capsys):
    from akf.examples import example_job
    from akf.job import Job, LoadWarning

    data = example_job("s17-case4")
    data["simulation"]["loads"][1]["components"][0]["start"] = 500.0          # ms typed for s
    with pytest.warns(LoadWarning, match=r"simulation\.loads\[1\] \(force 2\): the 'pulse' load starts at 500 s, after"):
        loads = Job.from_dict(data, "estimate").loads()
    assert not np.any(loads[:, 1] > 1000)                 # the 5 kN pulse is not there
    # a record cut short on purpose (--duration) leaves the pulse at 0.5 s out without a word
    assert main(["estimate", "--example", "s17-case4", "--duration", "0.05", "--no-plot", "--out",
                 str(tmp_path / "o")]) == 0
    assert "after the record's end" not in capsys.readouterr().err
    data["simulation"]["duration"] = 0.6                       # the job's own length: the other loads start within it
    with pytest.warns(LoadWarning, match=r"the 'pulse' load starts at 500 s, after the record's end \(0.5998\d* s\)"):
        Job.from_dict(data, "estimate").simulate()


def test_a_sine_load_at_or_above_nyquist_is_refused_and_one_below_runs():
    from akf.examples import example_job
    from akf.job import Job

    data = example_job("s17-case4")
    sine = {"type": "sine", "frequency": 2048.0, "amplitude": 100.0}
    data["simulation"]["loads"][0]["components"] = [sine]
    with pytest.raises(ValueError, match="at or above the Nyquist frequency"):
        Job.from_dict(data, "estimate").simulate()
    sine["frequency"] = 100.0
    loads = Job.from_dict(data, "estimate").loads()
    assert np.max(np.abs(loads[:, 0])) == pytest.approx(100.0, rel=1e-3)


@pytest.mark.parametrize("example, command, key", [("s17-case4", "estimate", "peak"), ("s17-case4", "estimate", "rms"),
                                                   ("th-case5", "place", "peak"), ("imp-truss-case1", "locate", "peak")])
def test_loads_far_beyond_what_the_structure_bears_are_named_as_loads(tmp_path, capsys, example, command, key):
    """A load amplitude of 1e300 N was named by a consequence: a NaN noise covariance (estimate),
    a failed Riccati solve or "no layout the GA tried is admissible" (place)."""
    import tomlkit

    from akf.examples import load_example

    data = load_example(example, command)
    for load in data["simulation"]["loads"]:
        for component in load["components"]:
            if key in component:
                component[key] = 1e300
    if command == "place":
        data["place"].update(population=4, generations=1)
    job = tmp_path / "job.toml"
    job.write_text(tomlkit.dumps(data))
    assert main([command, str(job), "--no-plot", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "the simulated response at " in err and "the loads (peak " in err and "are far too large" in err, err


def test_a_simulated_response_beyond_any_sensor_is_refused_and_one_within_runs():
    from core_akf.simulate import simulate

    truss = s17_truss()
    with pytest.raises(ValueError, match=r"the simulated response at strain:13 reaches .* m/m .* beyond what a strain "
                                         r"gauge reads \(\|x\| <= 1 m/m\): the loads \(peak 1e\+12 N\)"):
        simulate(truss, ["strain:13"], ["8:y"], np.full((50, 1), 1e12), 1e-3)
    with pytest.raises(ValueError, match=r"reaches \S+ m/s\^2 .* beyond what an accelerometer reads"):
        simulate(truss, ["acc:8:y"], ["8:y"], np.full((50, 1), 1e308), 1e-3)
    sim = simulate(truss, ["strain:13", "acc:8:y"], ["8:y"], np.full((50, 1), 1e5), 1e-3)
    assert np.isfinite(sim.measurements).all()


@pytest.mark.parametrize("noise, message", [
    ({"strain": 0.5, "acc": 0.2}, r"noise_cov of strain:5 is 0.5 \(m/m\)\^2, a standard deviation of 0.7071 m/m, "
                                  r"above 1% of what a strain gauge reads"),
    ({"strain": 4e-14, "acc": 1e9}, r"noise_cov of acc:4:y is 1e\+09 \(m/s\^2\)\^2, a standard deviation of 3.162e\+04"),
    ([0.2] * 4 + [1e9] + [4e-14] * 4, r"noise_cov of acc:6:x is 1e\+09"),          # one variance per sensor
])
def test_a_noise_variance_in_other_units_is_named(noise, message):
    """noise_cov = {strain = 0.5} (a standard deviation of 0.7 m/m) or {acc = 1e9} ran to exit 0: the
    filter took the channels as saying nothing."""
    from akf.job import Job, load_job_file

    data = load_job_file(os.path.join(ROOT, "examples", "daq", "s17-tdms.toml"))
    data["filter"]["noise_cov"] = noise
    with pytest.raises(ValueError, match=message):
        Job.from_dict(data, "estimate").noise_cov()
    data["filter"]["noise_cov"] = {"strain": 4e-14, "acc": 0.2}
    assert Job.from_dict(data, "estimate").noise_cov() == {"strain": 4e-14, "acc": 0.2}
