"""``--report``: one self-contained HTML page of a run, to hand to a client, a colleague or a reviewer.

The page holds the job as run, the command line and the versions, the model (its size and first
frequencies: the filter's and the truth's), every warning, the run's figures (embedded PNG: no
network, no external font or script), its tables (each number named with the CSV file and
column it comes from) and, after a calibration, the fit with its standard errors.  It is written
after the results, by :func:`write_report`; a report that fails is a warning, never a lost run.

No template library: the page is a dozen sections built from the run's dicts, and
:func:`html.escape` on every value is all the templating it needs.
"""
from __future__ import annotations

import base64
import html
import logging
import os
import platform
import sys
import time

log = logging.getLogger("akf")

#: a report larger than this is a warning (the figures are embedded as PNG)
MAX_BYTES = 5 * 2 ** 20

#: what a channel's diagnostics mean, for the table of each channel
CHANNEL_NOTES = (
    ("consistency", "innovation RMS over its predicted standard deviation: about 1 when the model and the covariances "
     "fit. Below 1: the prior (Q, S or the force model) or R is wider than the record needs, or a channel with "
     "little signal; above 1: R too small, a model that is off (calibrate it), a load the prior does not allow."),
    ("whiteness", "share of the first 20 autocorrelation lags of the innovations inside the 95 % band of white noise: "
     "near 1 when the filter leaves nothing predictable; low values: a model or force prior that misses a "
     "frequency the record holds."),
    ("loglik", "the channel's share of the log-likelihood of the innovations (higher is likelier; compare runs of "
     "one record only)."),
)

_STYLE = """
body { font-family: sans-serif; max-width: 1100px; margin: 1.5em auto; color: #222; line-height: 1.4; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; margin-top: 1.6em; }
table { border-collapse: collapse; font-size: 0.85em; margin: 0.5em 0; }
td, th { border: 1px solid #ccc; padding: 2px 6px; text-align: right; }
th { background: #f2f2f2; } td.t, th.t { text-align: left; }
pre { background: #f6f6f6; padding: 0.6em; overflow-x: auto; font-size: 0.8em; }
figure { margin: 1em 0; } figure img { max-width: 100%; height: auto; border: 1px solid #eee; }
figcaption, .src { font-size: 0.8em; color: #555; }
.warn { background: #fff4e5; border-left: 4px solid #e69500; padding: 0.3em 0.6em; margin: 0.3em 0; }
"""

#: marks every figure with its rendered size once the page has loaded (read by the browser test)
_SCRIPT = """
window.addEventListener("load", function () {
  var sizes = [];
  document.querySelectorAll("figure img").forEach(function (img) {
    sizes.push(img.naturalWidth + "x" + img.naturalHeight + "/" + img.clientWidth + "x" + img.clientHeight);
  });
  document.body.setAttribute("data-figures", sizes.join(" "));
});
"""


def _e(value):
    return html.escape(str(value))


def _number(value):
    if isinstance(value, float):
        return f"{value:.6g}"
    return _e(value)


def _table(rows, columns, source=None, left=()):
    """An HTML table of ``rows`` (dicts) in ``columns`` (``(key, header)``); ``source`` names the CSV
    file the numbers come from."""
    head = "".join(f'<th class="{"t" if k in left else ""}">{_e(h)}</th>' for k, h in columns)
    body = "".join("<tr>" + "".join(f'<td class="{"t" if k in left else ""}">{_number(r.get(k, ""))}</td>'
                                    for k, _ in columns) + "</tr>" for r in rows)
    note = f'<div class="src">from {_e(source)}</div>' if source else ""
    return f"<table><tr>{head}</tr>{body}</table>{note}"


def _figure(path, caption):
    with open(path, "rb") as fh:
        return _embedded(fh.read(), os.path.basename(path), f"{caption} ({os.path.basename(path)})")


def _embedded(png, name, caption):
    data = base64.b64encode(png).decode("ascii")
    return (f'<figure><img alt="{_e(name)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{_e(caption)}</figcaption></figure>")


def _layout(job):
    """The job's sensors and forces as labels (none for a placement's sensors)."""
    sensors = [s.label for s in job.sensors] if job.spec.sensors else []
    return sensors, [f"{n}:{d}" for n, d in job.forces] if job.spec.forces else []


def _layout_figure(job):
    """The layout drawn on the structure (:func:`core_akf.figures.plot_structure`), embedded."""
    import io

    import matplotlib.pyplot as plt

    from core_akf.figures import plot_structure

    try:
        sensors, forces = _layout(job)
        fig = plot_structure(job.structure, sensors=sensors, forces=forces, numbers=job.structure.n_nodes <= 200,
                             title=f"{job.name}: the layout")
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", dpi=90, bbox_inches="tight")
        plt.close(fig)
    except Exception as exc:  # noqa: BLE001 -- a structure the drawing does not know: a line instead
        return f"<p>the layout could not be drawn: {_e(exc)}</p>"
    return _embedded(buffer.getvalue(), "layout", "the sensors (blue) and the unknown forces (red) on the structure, "
                     "with its node and member numbers")


def _versions():
    import numpy
    import scipy

    from . import __version__
    return (f"akf {__version__}, Python {platform.python_version()}, numpy {numpy.__version__}, "
            f"scipy {scipy.__version__}, {platform.system()} {platform.machine()}")


def _model_section(job):
    """The model: its size and first frequencies, the filter's and (a simulation's) the truth's."""
    rows = []
    try:
        truth, model = job.structure, job.filter_model()
        k = min(6, model.n)
        rows.append({"what": "the filter's model", "name": model.name, "dofs": model.n,
                     "frequencies": ", ".join(f"{f:.4g}" for f in model.frequencies(k))})
        if job.spec.simulation is not None and job.spec.measurements is None:
            rows.append({"what": "the truth of the simulation ([structure])", "name": truth.name, "dofs": truth.n,
                         "frequencies": ", ".join(f"{f:.4g}" for f in truth.frequencies(min(6, truth.n)))})
    except Exception as exc:  # noqa: BLE001 -- a model the report cannot describe is a line, not a lost report
        return f"<p>the model could not be described: {_e(exc)}</p>"
    nodes = getattr(job.structure, "n_nodes", "")
    sensors, forces = _layout(job)
    return (f"<p>{_e(nodes)} nodes; sensors: {_e(', '.join(sensors) or 'none given (placement chooses them)')}; "
            f"unknown forces: {_e(', '.join(forces))}; time step {_e(job.dt)} s.</p>"
            + _table(rows, [("what", "model"), ("name", "name"), ("dofs", "DOFs / modes"),
                            ("frequencies", "first natural frequencies (Hz)")], left=("what", "name", "frequencies")))


def _channels_section(metrics):
    sensors = metrics.get("sensors") or []
    if not sensors or not all(isinstance(r, dict) for r in sensors):       # placement: the layout's labels
        return ""
    columns = [("channel", "channel"), ("unit", "unit"), ("measured_rms", "measured RMS"),
               ("innovation_rms", "innovation RMS"), ("consistency", "consistency"), ("whiteness", "whiteness"),
               ("loglik", "loglik"), ("missing_fraction", "missing fraction")]
    notes = "".join(f"<li><b>{_e(k)}</b>: {_e(v)}</li>" for k, v in CHANNEL_NOTES)
    return ("<h2>Per channel: does the filter fit the record?</h2>"
            + _table(sensors, columns, "summary.csv (rows of quantity 'sensor', the same column names)",
                     left=("channel", "unit"))
            + f"<ul>{notes}</ul>")


def _forces_section(metrics):
    forces = metrics.get("forces") or []
    if not forces or not all(isinstance(r, dict) for r in forces):
        return ""
    rows = [dict(r, rms_error=(metrics.get("rms_force") or {}).get(r.get("channel"), "")) for r in forces]
    columns = [("channel", "force"), ("rms", "RMS (N)"), ("peak", "peak (N)"), ("time_of_peak", "time of peak (s)"),
               ("rms_error", "RMS error against the reference (N)")]
    extra = ""
    if metrics.get("avg_strain_error_microstrain") is not None:
        extra = (f"<p>average strain error over every strain output: {metrics['avg_strain_error_microstrain']:.4g} µε "
                 "(summary.csv, rows of quantity 'strain', column rms_error, in m/m)</p>")
    return ("<h2>Forces</h2>" + _table(rows, columns, "summary.csv (rows of quantity 'force'; the series in "
                                       "timeseries.csv)", left=("channel",)) + extra)


#: the entries of a command's results that have sections of their own, or are not results
_OWN_SECTIONS = {"forces", "calibration", "warnings", "units", "files", "notes", "rms_force", "rms_strain",
                 "positions", "ranking", "name"}


def _results_section(metrics):
    """The command's scalar results and short lists (its ``--json``), with their units where the
    command gives them."""
    units = metrics.get("units") if isinstance(metrics.get("units"), dict) else {}
    rows = []
    for key, value in metrics.items():
        if key in _OWN_SECTIONS:
            continue
        if isinstance(value, (bool, int, float, str)) and len(str(value)) <= 300:
            rows.append({"key": key, "value": value, "unit": units.get(key, "") if isinstance(units.get(key), str) else ""})
        elif isinstance(value, list) and len(value) <= 40 and all(isinstance(v, (int, float, str)) for v in value):
            rows.append({"key": key, "value": ", ".join(_number(v) for v in value), "unit": ""})
    if not rows:
        return ""
    return "<h2>Results</h2>" + _table(rows, [("key", "result"), ("value", "value"), ("unit", "unit")],
                                       "the command's --json (the same keys)", left=("key", "value", "unit"))


def _calibration_section(cal):
    if not cal:
        return ""
    names = list(cal.get("multipliers", {}))
    rows = [{"name": n, "factor": cal["multipliers"][n], "se": cal.get("std_errors", {}).get(n, ""),
             "robust": cal.get("robust_std_errors", {}).get(n, "")} for n in names]
    consistency = [{"channel": c, "before": b, "after": cal.get("consistency_after", {}).get(c, "")}
                   for c, b in cal.get("consistency_before", {}).items()]
    method = (f"<p>force prior by the {_e(cal['method'])} likelihood: {_e(cal.get('method_reason', ''))}</p>"
              if cal.get("method") == "whittle" else "")
    notes = "".join(f"<p>{_e(cal[k])}</p>" for k in ("window", "model_note") if cal.get(k))
    return ("<h2>Calibration</h2>" + notes + method
            + f"<p>log-likelihood {_number(cal.get('loglik_before'))} → {_number(cal.get('loglik_after'))}; "
              f"{_e(cal.get('evaluations', ''))} filters in {_number(cal.get('seconds', ''))} s</p>"
            + _table(rows, [("name", "parameter"), ("factor", "fitted factor"), ("se", "std error (observed, relative)"),
                            ("robust", "std error (robust, relative)")], "calibration.json (multipliers, std_errors, "
                     "robust_std_errors)", left=("name",))
            + _table(consistency, [("channel", "channel"), ("before", "consistency before"),
                                   ("after", "consistency after")], "calibration.json (consistency_before, "
                     "consistency_after)", left=("channel",)))


def _job_text(job, source):
    if source and os.path.isfile(source):
        with open(source, encoding="utf-8-sig") as fh:
            return fh.read()
    try:
        from .examples import example_path
        with open(example_path(job.name), encoding="utf-8") as fh:
            return fh.read()
    except Exception:  # noqa: BLE001 -- a job built in Python has no text: its name stands for it
        return f"(a job built in Python: {job.name})"


def report_html(command, job, metrics, files, warnings, source=None, argv=None, figures=None):
    """The report's HTML text.

    Parameters
    ----------
    command : str
        The command that ran (``"estimate"``, ``"calibrate"``, ...).
    job : akf.job.Job
        The job as run.
    metrics : dict
        The run's results (the JSON of the command: ``sensors``, ``forces``, ``calibration``, ...).
    files : dict
        ``{name: path}`` of the files written; every ``.png`` among them is embedded.
    warnings : list of str
        Every warning of the run.
    source : str, optional
        The job file (its text is shown as run).
    argv : list of str, optional
        The command line (default ``sys.argv``).
    figures : dict, optional
        ``{name: caption}`` of the figures (default the file names).

    Returns
    -------
    str
    """
    argv = sys.argv if argv is None else argv
    figures = figures or {}
    pngs = [(k, p) for k, p in files.items() if isinstance(p, str) and p.endswith(".png") and os.path.isfile(p)]
    written = [(k, p) for k, p in files.items() if isinstance(p, str) and os.path.isfile(p)]
    parts = [f"<h1>akf {_e(command)}: {_e(job.name)}</h1>",
             f"<p>{_e(job.description)}</p>" if job.description else "",
             f"<p class=src>{_e(time.strftime('%Y-%m-%d %H:%M:%S %Z'))}; command: <code>{_e(' '.join(argv))}</code>; "
             f"{_e(_versions())}</p>"]
    parts.append("<h2>Warnings</h2>" + ("".join(f'<div class="warn">{_e(w)}</div>' for w in warnings)
                                         if warnings else "<p>none</p>"))
    parts.append("<h2>Model and layout</h2>" + _model_section(job) + _layout_figure(job))
    parts.append(_results_section(metrics))
    parts.append(_forces_section(metrics))
    parts.append(_channels_section(metrics))
    parts.append(_calibration_section(metrics.get("calibration")))
    if pngs:
        parts.append("<h2>Figures</h2>" + "".join(_figure(p, figures.get(k, k)) for k, p in pngs))
    parts.append("<h2>Files of the run</h2><ul>" + "".join(
        f"<li>{_e(k)}: <code>{_e(os.path.basename(p))}</code></li>" for k, p in written) + "</ul>")
    parts.append(f"<h2>The job as run</h2><pre>{_e(_job_text(job, source))}</pre>")
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>akf {_e(command)}: {_e(job.name)}</title><style>{_STYLE}</style>"
            f"<script>{_SCRIPT}</script></head><body>" + "\n".join(p for p in parts if p) + "</body></html>\n")


def write_report(out, command, job, metrics, files, warnings, source=None, figures=None):
    """Write ``out/report.html`` after the run's results (:func:`report_html`).

    Returns the path, or None: a report that cannot be written is a warning appended to
    ``warnings`` (the results are already written).
    """
    from core_akf.outputs import atomic_path

    path = os.path.join(out, "report.html")
    try:
        text = report_html(command, job, metrics, files, list(warnings), source=source, figures=figures)
        with atomic_path(path) as tmp:
            with open(tmp, "w", encoding="utf-8") as fh:
                fh.write(text)
    except Exception as exc:  # noqa: BLE001 -- a report that fails never loses the run
        log.debug("report failed", exc_info=True)
        warnings.append(f"report.html not written ({type(exc).__name__}: {exc}); the result files are complete")
        return None
    size = os.path.getsize(path)
    if size > MAX_BYTES:
        warnings.append(f"report.html is {size / 2 ** 20:.1f} MB (its figures are embedded); --no-plot leaves them out")
    return path
