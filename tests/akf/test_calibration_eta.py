"""A long calibration says how long before it is done (issue 36): the progress bar on stderr shows
an ETA within its first seconds."""
import re
import time

import core_akf.calibration as calibration
from akf.cli import main


def test_a_slow_calibration_shows_its_eta_within_the_first_seconds(tmp_path, capsys, monkeypatch):
    """Each batch of filters slowed by 100 ms (a model 100x larger, as it were): the fit takes
    seconds (4-6 s measured), and the bar on stderr shows an ETA ("elapsed<remaining", with
    time remaining) stamped within its first 10 s and before the end."""
    original = calibration.steady_logliks

    def slow(*args, **kw):
        time.sleep(0.1)
        return original(*args, **kw)
    monkeypatch.setattr(calibration, "steady_logliks", slow)
    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    t0 = time.perf_counter()
    assert main(["calibrate", "--example", "s17-case4", "--parameters", "stiffness_factor",
                 "--out", str(tmp_path)]) == 0
    took = time.perf_counter() - t0
    err = capsys.readouterr().err
    etas = [(int(a) * 60 + int(b), int(c) * 60 + int(d)) for a, b, c, d in
            re.findall(r"\[(\d\d):(\d\d)<(\d\d):(\d\d)", err)]
    assert etas, err[-500:]
    assert any(elapsed < min(10.0, took) and remaining > 0 for elapsed, remaining in etas), etas
