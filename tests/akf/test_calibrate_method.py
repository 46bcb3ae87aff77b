"""``[filter] calibrate_method``: the JSON and the printout say which likelihood fitted the force
prior and why; the key is checked and not written into ``calibrated.toml``."""
import json

import pytest

from akf.cli import main


def _job(tmp_path, capsys, method=None):
    """The s17-acc example on a 0.5 s record, learning force_std and force_timescale."""
    assert main(["calibrate", "--example", "s17-acc", "--print-job"]) == 0
    text = capsys.readouterr().out.replace("duration = 2.0", "duration = 0.5")
    extra = 'calibrate = ["force_std", "force_timescale"]\n' + (f'calibrate_method = "{method}"\n' if method else "")
    text = text.replace("[filter]\n", "[filter]\n" + extra, 1)
    path = tmp_path / "job.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("method, expected, why", [(None, "whittle", "empty bins"), ("time", "time", "as asked")])
def test_the_json_says_which_likelihood_ran_and_why(tmp_path, capsys, method, expected, why):
    job = _job(tmp_path, capsys, method)
    assert main(["calibrate", str(job), "--out", str(tmp_path / "out"), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)["calibration"]
    assert report["method"] == expected and why in report["method_reason"]
    assert (report["whittle_loglik"] is None) == (expected == "time")
    if expected == "whittle":
        assert report["whittle_loglik"][1] > report["whittle_loglik"][0]
    written = (tmp_path / "out" / "calibrated.toml").read_text()
    assert "calibrate_method" not in written and "force_std = " in written


def test_the_printout_names_the_likelihood(tmp_path, capsys):
    job = _job(tmp_path, capsys)
    assert main(["-q", "calibrate", str(job), "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "force prior by the whittle likelihood:" in out and "Whittle log-likelihood of the signal bins" in out


def test_an_unknown_method_is_named_by_its_key(tmp_path, capsys):
    job = _job(tmp_path, capsys, "spectral")
    assert main(["calibrate", str(job), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "calibrate_method" in err and "whittle" in err
