"""``akf calibrate``: learn a job's ``[filter] calibrate`` keys from its record by maximum
likelihood, print the fit and write ``calibrated.toml``: the job with the fitted values (its
comments and layout kept), to estimate day after day without calibrating again."""
from __future__ import annotations

import json
import os
import sys

from core_akf.checks import AKFInputError
from core_akf.outputs import atomic_path

from ..outputs import OutputFolder
from .common import add_print_job, print_written


def _calibrate(args):
    from ..calibrating import calibrate_job, calibration_record
    from ..estimate.files import listed_strain_outputs
    from ..examples import example_path
    from ..job import Job
    from .common import job_data, listing_or_template

    done = listing_or_template(args, "estimate")
    if done is not None:
        return done
    data = job_data(args, "estimate")
    overrides = {"filter.calibrate": check_parameters(args.parameters)} if args.parameters else {}
    job = Job.from_dict(data, "estimate", source=args.job, overrides=overrides)
    if not job.calibrate:
        raise AKFInputError("nothing to calibrate: list the [filter] keys to learn in [filter] calibrate = "
                            "[\"stiffness_factor\", ...] or give --parameters")
    listed_strain_outputs(job, job.structure)     # calibrated.toml is run by estimate: a wrong label named now
    out = args.out or os.path.join("akf-out", job.name)
    with OutputFolder(out, "--out"):
        sim = record = None
        model = job.filter_model()
        if job.spec.measurements is not None:
            record = job.open_record()
            Y = calibration_record(job, record, model)
            noise_cov = job.noise_cov()
        else:
            sim = job.simulate()
            Y = sim.measurements
            noise_cov = job.noise_cov(sim)
        *_, report = calibrate_job(job, model, job.sensors, job.forces, Y, noise_cov,
                                   None if record is None else record.n_steps)
        if record is not None:
            report["warnings"] = list(record.warnings) + report["warnings"]
        path = os.path.join(out, "calibrated.toml")
        source = args.job or example_path(args.example)
        write_calibrated(source, report, path)
        fit = os.path.join(out, "calibration.json")       # the fit with its standard errors (read by place)
        with atomic_path(fit) as tmp:
            with open(tmp, "w", encoding="utf-8") as fh:
                json.dump(report, fh, indent=1)
        files = {"calibrated_job": path, "calibration": fit}
        if args.report:                        # after the results: a report that fails is a warning
            from ..report import write_report
            written = write_report(out, "calibrate", job, {"calibration": report}, files, report["warnings"],
                                   source=args.job)
            if written is not None:
                files["report"] = written
    if args.json:
        print(json.dumps({"name": job.name, "calibration": report, "files": files}))
        for w in report["warnings"]:
            print(f"akf: warning: {w}", file=sys.stderr)
        return 0
    _print_fit(job, report, files)
    return 0


def _print_fit(job, report, files):
    """The fit as a table on stdout, its warnings and the files written."""
    print(f"{job.name}: calibrated {', '.join(job.calibrate)} on {report['record_steps']} steps "
          f"({report['seconds']:.2f} s, {report['evaluations']} filters)")
    print(f"  {report['window']}")
    if "model_note" in report:
        print(f"  {report['model_note']}")
    for note in report.get("notes", []):
        print(f"  {note}")
    if any(p.startswith(("force_std", "force_timescale", "force_band")) for p in report["multipliers"]):
        print(f"  force prior by the {report['method']} likelihood: {report['method_reason']}")
    print(f"  log-likelihood: {report['loglik_before']:.8g} -> {report['loglik_after']:.8g}")
    if report.get("whittle_loglik"):
        print("  Whittle log-likelihood of the signal bins: {:.8g} -> {:.8g} (the fit's own; the time-domain one above "
              "also weighs the bins without signal)".format(*report["whittle_loglik"]))
    print("  parameter                 factor     std error (relative): observed     robust")
    for name, factor in report["multipliers"].items():
        print(f"    {name:22s} {factor:10.5g}   {report['std_errors'][name]:29.3g} "
              f"{report['robust_std_errors'][name]:10.3g}")
    if "stiffness_factor" in report:
        print(f"  stiffness_factor = {report['stiffness_factor']:.6g} (relative to [structure])")
    if "frequency_factors" in report:
        print("  frequency_factors = [" + ", ".join(f"{f:.5g}" for f in report["frequency_factors"]) + "] ("
              + ", ".join(f"{f:.4g}" for f in report["frequencies_hz"]) + " Hz)")
    print("  consistency (innovation / predicted; ~1 is good):      before     after")
    for channel, before in report["consistency_before"].items():
        print(f"    {channel:>14s}                                  {before:8.3g}  {report['consistency_after'][channel]:8.3g}")
    for w in report["warnings"]:
        print(f"  WARNING: {w}")
    print_written(files)


def check_parameters(names):
    """``--parameters``, each a name ``[filter] calibrate`` takes; a typo is named as the flag's,
    with the closest names."""
    import difflib

    from ..schema import CALIBRATION_KEYS

    for name in names:
        if name not in CALIBRATION_KEYS:
            close = difflib.get_close_matches(name, CALIBRATION_KEYS, n=2)
            raise AKFInputError(f"--parameters {name}: not a parameter akf calibrate learns"
                                + (f"; did you mean {' or '.join(close)}?" if close else "")
                                + f" The parameters: {', '.join(CALIBRATION_KEYS)}")
    return list(names)


#: the [filter] keys akf calibrate writes (and the ones it removes: the fit is done)
WRITTEN = ("stiffness_factor", "frequency_factors", "noise_cov", "force_increment_cov", "model_error_cov", "force_std",
           "force_timescale", "force_band")


#: the [filter] keys that say how to calibrate: the calibrated job leaves them out
RUN_KEYS = ("calibrate", "calibrate_window", "calibrate_modes", "calibrate_method", "calibrate_held")


def write_calibrated(source, report, path):
    """Write the job file ``source`` with the fitted ``[filter]`` values of ``report`` (and without
    ``calibrate``, ``calibrate_window``, ``calibrate_modes``, ``calibrate_method`` and ``calibrate_held``) to ``path``.

    Comments and layout are kept (tomlkit), a replaced value keeps its comment (its unit), and
    the relative data paths (the record, a model's files) are rewritten to point from ``path``'s
    folder at the same files, so the written job runs as it is.  A ``[filter]`` written as an
    inline table or as dotted keys becomes a ``[filter]`` table.  The text written is checked
    by reading it back: it must hold the job with the fitted values.
    """
    import tomlkit
    import tomllib

    from ..job import data_path_keys

    with open(source, encoding="utf-8-sig") as fh:
        text = fh.read()
    doc = tomlkit.parse(text)
    expected = tomllib.loads(text)
    fitted = {key: report[key] for key in WRITTEN if key in report}
    for key in RUN_KEYS:
        expected.get("filter", {}).pop(key, None)
    expected.setdefault("filter", {}).update(fitted)
    table = _plain_table(doc, "filter")
    for key in RUN_KEYS:
        if key in table:
            del table[key]
    for key, value in fitted.items():
        _set_keeping_comment(table, key, value)
    if "damping" in report:            # the model's own damping: [structure] of a job on measured data
        if "measurements" in doc and "structure" in doc:
            _set_keeping_comment(_plain_table(doc, "structure"), "damping", report["damping"])
            expected["structure"]["damping"] = report["damping"]
        else:
            table.add(tomlkit.comment(f"fitted modal damping ratio {report['damping']}: not written into [structure], "
                                      "which also makes the simulated truth"))
    here, there = (os.path.dirname(os.path.abspath(f)) for f in (source, path))
    for section, key in data_path_keys(expected):
        value = expected[section][key]
        if not os.path.isabs(value):
            expected[section][key] = _relocated(value, here, there)
            _set_keeping_comment(_plain_table(doc, section), key, expected[section][key])
    table.add(tomlkit.comment(f"fitted by akf calibrate: log-likelihood {report['loglik_before']:.8g} -> "
                              f"{report['loglik_after']:.8g}"))
    written = tomlkit.dumps(doc)
    try:
        kept = tomllib.loads(written) == expected
    except tomllib.TOMLDecodeError:
        kept = False
    if not kept:                       # a layout tomlkit cannot edit in place: the data, without the comments
        written = ("# written by akf calibrate from " + os.path.basename(source) + " (its comments could not be "
                   "kept)\n" + tomlkit.dumps(expected))
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(written)
    return path


def _plain_table(doc, name):
    """The ``[name]`` table of a tomlkit document, to edit in place: an inline table, dotted keys or
    a table split over the file become one ``[name]`` table at the end (their comments are lost)."""
    import tomlkit
    from tomlkit.items import Table

    item = doc.get(name)
    if item is None:
        doc[name] = tomlkit.table()
    elif not isinstance(item, Table) or item.is_super_table():
        data = item.unwrap()
        del doc[name]
        table = tomlkit.table()
        for key, value in data.items():
            table[key] = _inline(value)
        doc[name] = table
    return doc[name]


def _inline(value):
    """A value for a table key: a dict as an inline table (not a sub-table)."""
    import tomlkit

    if not isinstance(value, dict):
        return value
    table = tomlkit.inline_table()
    table.update({k: _inline(v) for k, v in value.items()})
    return table


def _set_keeping_comment(table, key, value):
    """``table[key] = value``, keeping the comment (a unit, say) of the value it replaces."""
    import tomlkit

    new = tomlkit.item(_inline(value))
    if key in table:
        old = table.item(key)
        new.trivia.comment, new.trivia.comment_ws = old.trivia.comment, old.trivia.comment_ws
    table[key] = new


def _relocated(value, here, there):
    """A path relative to the folder ``here`` made relative to the folder ``there`` (absolute when
    no relative path joins them, as across Windows drives)."""
    target = os.path.normpath(os.path.join(here, value))
    try:
        return os.path.relpath(target, there).replace(os.sep, "/")
    except ValueError:
        return target


def register(sub):
    """Add ``calibrate`` to the ``akf`` sub-command parser."""
    p = sub.add_parser("calibrate", help="learn the filter's model and covariances from a job's record (maximum "
                       "likelihood) and write calibrated.toml")
    p.add_argument("job", nargs="?", help="job file (TOML) of akf estimate")
    p.add_argument("--example", help="built-in estimate example, e.g. s17-case4 (see --list-examples)")
    p.add_argument("--list-examples", action="store_true", help="list the built-in examples")
    p.add_argument("--parameters", nargs="+", metavar="KEY", help="the [filter] keys to learn (instead of [filter] "
                   "calibrate): stiffness_factor, frequencies, damping, noise_cov (noise_cov:<kind>, noise_cov:channels), "
                   "force_increment_cov, model_error_cov; force_std, force_timescale (a Matérn force_model); force_std, "
                   "force_band (a Butterworth force_model)")
    p.add_argument("--out", help="output folder (default akf-out/NAME)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    p.add_argument("--report", action="store_true", help="also write report.html: the fit, its standard errors and "
                   "the consistency before and after, on one self-contained page")
    add_print_job(p)
    p.set_defaults(func=_calibrate)
