"""``akf show MODEL``: a built-in structure with its node and member numbers (PNG) and its
first natural frequencies, to write sensors and forces (``strain:13``, ``acc:8:y``, ``8:y``)."""
from __future__ import annotations

import json
import os

from core_akf.outputs import OutputFolder

from ..jobs import MODELS, build_structure


def _show(args):
    from core_akf.figures import plot_structure

    structure = build_structure({"model": args.model})
    f = structure.frequencies()[: args.modes]
    info = {"model": args.model, "nodes": structure.n_nodes, "dofs": structure.n,
            "dof_directions": list(structure.dof_names),
            "strain_outputs": structure.n_strain, "first_strain_output": structure.strain_labels[0],
            "last_strain_output": structure.strain_labels[-1], "frequencies_hz": [float(x) for x in f]}
    if structure.members is not None:
        info["members"] = int(len(structure.members))
    files = {}
    if not args.no_plot:
        out = args.out or os.path.join("akf-out", "show")
        with OutputFolder(out, "--out"):
            files["figure"] = os.path.join(out, f"{args.model}.png")
            plot_structure(structure, files["figure"])
    if args.json:
        print(json.dumps(dict(info, files=files)))
        return 0
    print(f"{args.model}: {structure.n_nodes} nodes, {structure.n} free DOFs ({'/'.join(structure.dof_names)} per node)"
          + (f", {info['members']} members" if "members" in info else ""))
    print(f"  strain outputs: {structure.n_strain} ({info['first_strain_output']} ... {info['last_strain_output']})")
    print("  first natural frequencies (Hz): " + ", ".join(f"{x:.4g}" for x in f))
    for k, v in files.items():
        print(f"  wrote {k}: {v}")
    return 0


def register(sub):
    """Add ``show`` to the ``akf`` sub-command parser."""
    p = sub.add_parser("show", help="draw a built-in structure with its node and member numbers")
    p.add_argument("model", choices=sorted(MODELS), help="built-in structure")
    p.add_argument("--modes", type=int, default=6, help="natural frequencies to print (default 6)")
    p.add_argument("--out", help="output folder (default akf-out/show)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--no-plot", action="store_true", help="do not write the PNG figure")
    p.set_defaults(func=_show)
