"""How long ``--report`` adds after the results, by hand: ``python bench/report_bench.py``.

Runs the issue's four commands on their built-in examples (shortened as in
``tests/akf/test_report.py``) with ``--report`` and times :func:`akf.report.write_report` alone: the
page is written after the results, so this is all a user waits for it.  Target (issue 36): <= 2 s
each.  Prints a row per command: seconds, the page's size and its figures.
"""
from __future__ import annotations

import os
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "akf"))
TARGET_S = 2.0


def main():
    from test_report import COMMANDS  # noqa: E402  (the tests' shortened commands)

    import akf.report
    from akf.cli import main as akf_main

    timed = []
    original = akf.report.write_report

    def timing(*args, **kw):
        t0 = time.perf_counter()
        path = original(*args, **kw)
        timed.append(time.perf_counter() - t0)
        return path
    akf.report.write_report = timing
    print(f"{'command':10s} {'report s':>9s} {'MB':>6s} {'figures':>8s}")
    with tempfile.TemporaryDirectory() as folder:
        for command, args in COMMANDS.items():
            out = os.path.join(folder, command)
            akf_main(["-q", *args, "--report", "--out", out])
            path = os.path.join(out, "report.html")
            with open(path, encoding="utf-8") as fh:
                figures = fh.read().count("<img ")
            print(f"{command:10s} {timed[-1]:9.2f} {os.path.getsize(path) / 2 ** 20:6.2f} {figures:8d}"
                  f"   {'met' if timed[-1] <= TARGET_S else 'NOT met'} (<= {TARGET_S:g} s)")


if __name__ == "__main__":
    main()
