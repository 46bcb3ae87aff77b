"""Files the documentation is built from the code: the JSON Schema (from :mod:`akf.schema`) and
the gallery figures (quick runs of the built-in examples).  The job-file reference is committed
(``docs/reference/jobs.md``, ``python -m akf.schema > docs/reference/jobs.md``) so that it reads on
any repository browser; a test keeps it current."""
import contextlib
import os
import shutil
import tempfile


def _write(path, text):
    old = open(path, encoding="utf-8").read() if os.path.exists(path) else None
    if old != text:                      # unchanged files keep their time stamp (no rebuild)
        with open(path, "w", encoding="utf-8") as fh:
            fh.write(text)


def gallery(out):
    """The gallery figures (PNG) in ``out``: the built-in structures, an estimate, a placement, an
    impact localisation and the learning study, each from a short run of a built-in example."""
    from akf.cli import main

    wanted = {"s17_truss.png", "th_plate.png", "imp_plate.png", "estimate.png", "sensors.png", "layout.png",
              "convergence.png", "error_vs_location.png", "force.png", "strain_errors.png", "likelihood.png",
              "smoothed.png", "accelerations.png", "timescale.png"}
    if all(os.path.exists(os.path.join(out, w)) for w in wanted):
        return
    with tempfile.TemporaryDirectory() as tmp, open(os.devnull, "w") as quiet, \
            contextlib.redirect_stdout(quiet), contextlib.redirect_stderr(quiet):
        for model in ("s17_truss", "th_plate", "imp_plate"):
            main(["show", model, "--out", os.path.join(tmp, "show"), "--json"])
        main(["estimate", "--example", "s17-case4", "--duration", "1", "--out", os.path.join(tmp, "estimate"), "--json"])
        main(["place", "--example", "th-case5", "--generations", "10", "--population", "20", "--json",
              "--out", os.path.join(tmp, "place")])
        main(["locate", "--example", "imp-truss-case1", "--json", "--out", os.path.join(tmp, "locate")])
        main(["study", "learning", "--quick", "-q", "--out", os.path.join(tmp, "learning")])
        main(["study", "accelerations", "--quick", "-q", "--out", os.path.join(tmp, "accelerations")])
        for root, _, files in os.walk(tmp):
            for f in files:
                if f in wanted:
                    shutil.copy(os.path.join(root, f), os.path.join(out, f))


def generate(out):
    from akf.schema import json_schema_text

    os.makedirs(out, exist_ok=True)
    _write(os.path.join(out, "job.schema.json"), json_schema_text())
    gallery(out)
