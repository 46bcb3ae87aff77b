"""``akf oma``: operational modal analysis of a job's accelerometer channels (SSI-cov,
:mod:`core_akf.oma`): the identified modes paired with the filter's model, the stabilisation
table, then the stabilisation diagram -- a cross-check of the model before calibrating it."""
from __future__ import annotations

import json
import os
import sys

from core_akf.outputs import write_csv

from ..outputs import OutputFolder
from .common import add_print_job, finish


def _oma(args):
    import numpy as np

    from ..calibrating import identify_modes
    from ..figures import draw
    from ..job import Job
    from .common import job_data, listing_or_template

    done = listing_or_template(args, "estimate")
    if done is not None:
        return done
    job = Job.from_dict(job_data(args, "estimate"), "estimate", source=args.job)
    out = args.out or os.path.join("akf-out", job.name, "oma")
    with OutputFolder(out, "--out"):
        if job.spec.measurements is not None:
            record = job.open_record()
            for w in record.warnings:
                print(f"akf: warning: {w}", file=sys.stderr)
            Y = np.vstack([chunk for _, chunk in record.chunks(record.n_steps)])
            source = "the record"
        else:
            Y = job.simulate().measurements
            source = "the simulated record"
        model = job.filter_model()
        res, paired, labels, Y, source, k = identify_modes(job, model, Y, source, block_rows=args.block_rows,
                                                           max_order=args.max_order)
        files = {"modes": write_csv(paired, os.path.join(out, "oma_modes.csv")),
                 "stabilisation_table": write_csv(res.poles, os.path.join(out, "stabilisation.csv"))}
        summary = {"name": job.name, "channels": labels, "steps": int(Y.shape[0]), "source": source,
                   "modes": json.loads(paired.to_json(orient="records")), "notes": res.notes, "files": files,
                   "units": {"frequency_hz": "Hz", "damping": "ratio of critical"}}
        if not args.json:
            print(f"{job.name}: operational modal analysis (SSI-cov) of {len(labels)} accelerometers, "
                  f"{Y.shape[0] * job.dt:.4g} s of {source}")
            print(f"  {'f (Hz)':>10s} {'damping':>8s} {'orders':>6s}  {'model mode':>10s} {'model f (Hz)':>12s} "
                  f"{'ratio':>8s} {'MAC':>6s}")
            for r in paired.itertuples():
                mode = "-" if r.model_mode is None or r.model_mode != r.model_mode else f"{int(r.model_mode)}"
                print(f"  {r.frequency_hz:10.4f} {r.damping:8.4f} {r.orders:6d}  {mode:>10s} "
                      f"{r.model_frequency_hz:12.4f} {r.frequency_ratio:8.5f} {r.mac:6.3f}")
            for note in res.notes:
                print(f"akf: note: {note}", file=sys.stderr)
            sys.stdout.flush()
        figure_notes = []
        if not args.no_plot:
            draw(files, "stabilisation", figure_notes, plot_stabilisation, res, os.path.join(out, "stabilisation.png"),
                 f"{job.name}: stabilisation diagram", model_hz=model.frequencies(k))
    return finish(args, summary, files, figure_notes)


def plot_stabilisation(res, path, title, model_hz=()):
    """The stabilisation diagram: every physical pole by frequency and model order, the stable
    ones filled, the identified modes (solid) and the model's modes (dashed) as vertical lines,
    over the band of the stable poles."""
    from core_akf.figures import subplots

    fig, ax = subplots(figsize=(7, 4))
    p = res.poles
    ax.plot(p["frequency_hz"][~p["stable"]], p["order"][~p["stable"]], "x", ms=3, color="0.6", label="pole")
    ax.plot(p["frequency_hz"][p["stable"]], p["order"][p["stable"]], "o", ms=3, color="C0", label="stable pole")
    top = 1.15 * max([*p["frequency_hz"][p["stable"]], *res.modes["frequency_hz"], 1e-9])
    for i, f in enumerate(res.modes["frequency_hz"]):
        ax.axvline(f, color="C3", lw=0.8, label="identified mode" if i == 0 else None)
        ax.annotate(f"{f:.4g}", (f, 1.0), xycoords=("data", "axes fraction"), rotation=90, fontsize=6,
                    va="top", ha="right", color="C3")
    shown = [f for f in model_hz if f <= top]
    for i, f in enumerate(shown):
        ax.axvline(f, color="k", lw=0.7, ls="--", label="filter's model" if i == 0 else None)
    ax.set_xlim(0, top)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("model order")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    return fig


def register(sub):
    """Add ``oma`` to the ``akf`` sub-command parser."""
    p = sub.add_parser("oma", help="operational modal analysis of a job's accelerometers (SSI-cov), paired with "
                       "the filter's model")
    p.add_argument("job", nargs="?", help="job file (TOML) of akf estimate")
    p.add_argument("--example", help="built-in estimate example, e.g. s17-case4 (see --list-examples)")
    p.add_argument("--list-examples", action="store_true", help="list the built-in examples")
    p.add_argument("--block-rows", type=int, help="lags of each half of the Hankel matrix (default 20)")
    p.add_argument("--max-order", type=int, help="the highest model order of the diagram (default 60)")
    p.add_argument("--out", help="output folder (default akf-out/NAME/oma)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    p.add_argument("--no-plot", action="store_true", help="do not write the stabilisation diagram")
    add_print_job(p)
    p.set_defaults(func=_oma)
