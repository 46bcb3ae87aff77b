"""``akf show MODEL`` or ``akf show JOB.toml``: a built-in structure, or the structure of a job
file (a model of one's own included), with its node and member numbers (PNG), its first natural
frequencies and what each strain output is, to write sensors and forces (``strain:13``,
``acc:8:y``, ``8:y``).  ``akf show JOB.toml --transfer``: what the job's layout sees of each force
per frequency (:func:`core_akf.filter.force_transfer`)."""
from __future__ import annotations

import json
import os
import re
import sys

from core_akf.checks import AKFInputError
from core_akf.sensors import parse_force_locations, selection_matrices

from ..job import MODELS, build_structure, check_stiffness_factors
from ..outputs import OutputFolder
from ..schema import JOB_NAME_PATTERN


def _structure_of(target):
    """``(structure, name, sensors, forces, filter model)`` of a built-in model name or a job file
    (:func:`_filter_model`)."""
    if target in MODELS and target != "matrices":
        return build_structure({"model": target}), target, [], [], None
    if not os.path.isfile(target):
        raise AKFInputError(f"{target!r} is neither a built-in structure ({', '.join(sorted(set(MODELS) - {'matrices'}))}) "
                            "nor a job file")
    from ..job import load_job_file, resolve_paths

    job = resolve_paths(load_job_file(target), os.path.dirname(os.path.abspath(target)))   # any command's job
    if not isinstance(job.get("structure"), dict):
        raise AKFInputError(f"{target}: the job file has no [structure] table")
    name = str(job.get("name") or os.path.splitext(os.path.basename(target))[0])
    if not re.fullmatch(JOB_NAME_PATTERN, name):
        raise AKFInputError(f"{target}: name must be a plain name (no '/', no '\\', not starting with '.'): the figure "
                            f"{name}.png is written into the output folder, and this name would leave it")
    structure = build_structure(job["structure"])
    sensors, forces = job.get("sensors") or [], job.get("forces") or []
    for key, value, example in (("sensors", sensors, '["strain:13", "acc:8:y"]'), ("forces", forces, '["8:y"]')):
        if not isinstance(value, list) or not all(isinstance(x, str) for x in value):
            raise AKFInputError(f"{target}: {key} must be a list of texts such as {example}, got {value!r}"[:300])
    if sensors:                                     # a sensor off the structure: named here, not in the figure
        selection_matrices(structure, sensors)
    if forces:
        parse_force_locations(structure, forces)
    return structure, name, list(sensors), list(forces), _filter_model(job, structure)


def _filter_model(job, structure):
    """The filter's model of a job file -- ``[filter] stiffness_factor`` and ``frequency_factors``
    on ``[structure]`` (placement's default stiffness factor for a place job) -- and what makes it
    differ from the truth in words; None when it is the structure itself."""
    from core_akf.defaults import default

    f = job.get("filter") if isinstance(job.get("filter"), dict) else {}
    placing = isinstance(job.get("place"), dict) and not isinstance(job.get("simulation"), dict)
    factor = f.get("stiffness_factor", default("placement_stiffness_factor" if placing else "stiffness_factor"))
    factors = f.get("frequency_factors") or []
    numbers = [factor] + (list(factors) if isinstance(factors, list) else [factors])
    if not isinstance(factors, list) or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in numbers):
        raise AKFInputError(f"{job.get('name') or 'the job'}: [filter] stiffness_factor must be a number and "
                            f"frequency_factors a list of numbers, got {factor!r} and {factors!r}"[:300])
    check_stiffness_factors(factor, factors)
    if factor == 1.0 and not factors:
        return None
    model = structure.scaled(float(factor))
    if factors:
        model = model.with_frequency_factors([float(x) for x in factors])
    words = f"stiffness_factor {factor:g}" + (f", frequency_factors {list(factors)}" if factors else "")
    return model, words


def strain_outputs(structure):
    """What every strain output is: ``[{"output": "strain:k", "is": ...}]`` -- a truss member or
    an extensometer (its two nodes), a row of a strain operator of one's own, or a plate node's
    component."""
    from core_akf.sensors import strain_ends

    rows = []
    for k, label in enumerate(structure.strain_labels, start=1):
        if structure.strain_kind != "member":
            rows.append({"output": label, "is": "surface strain at a plate node"})
            continue
        ends = strain_ends(structure, k)
        what = ("extensometer" if structure.meta.get("extensometers") else "member") if ends else "strain operator row"
        rows.append({"output": label, "is": what, "nodes": list(ends) if ends else None,
                     "row": None if ends else k})
    return rows


def _transfer(args):
    """``akf show JOB.toml --transfer``: the steady filter's force transfer function of the job's layout."""
    import numpy as np

    from core_akf.filter import Filter, force_transfer, recovered_band

    from ..figures import draw, plot_transfer
    from ..job import load_job

    if not os.path.isfile(args.model):
        raise AKFInputError(f"--transfer needs a job file of akf estimate (sensors, forces, [filter]); {args.model!r} is "
                            "not a file")
    job = load_job(args.model, "estimate")
    name = job.spec.name or os.path.splitext(os.path.basename(args.model))[0]
    sim = job.simulate() if job.spec.simulation is not None and isinstance(job.spec.filter.noise_cov, (str, type(None))) \
        else None
    model = job.filter_model()
    f = Filter(model, [job.sensors], job.forces, job.dt, model_error_cov=job.model_error_cov,
               force_model=job.force_model, noise_cov=job.noise_cov(sim), dummy=job.dummy)
    nyquist = 0.5 / job.dt
    natural = model.frequencies(min(model.n, 40))
    natural = natural[(natural > 0) & (natural < nyquist)]
    low = (natural[0] if natural.size else nyquist) / 100.0
    freqs = np.geomspace(low, nyquist, 600)
    T = force_transfer(f, np.r_[0.0, freqs])[0]
    labels = [f"{node}:{d}" for node, d in job.forces]
    rows = []
    for j, label in enumerate(labels):
        band = recovered_band(np.r_[0.0, freqs], np.abs(T[:, j, j]))
        cross = np.abs(np.delete(T[1:, j, :], j, axis=1)).max(initial=0.0)
        rows.append({"force": label, "static_gain": float(abs(T[0, j, j])), "recovered_band_hz": band,
                     "max_cross_talk": float(cross)})
    info = {"job": name, "sensors": [s.label for s in job.sensors], "force_model": job.force_model.describe(),
            "load_hold": job.force_model.hold, "frequencies_hz": [float(low), float(nyquist)], "forces": rows}
    if not args.json:
        print(f"{name}: what {len(job.sensors)} sensors see of each force (steady filter, "
              f"{job.force_model.describe()}, load hold {job.force_model.hold})")
        for r in rows:
            band = r["recovered_band_hz"]
            seen = "nowhere" if band is None else f"{band[0]:.4g}-{band[1]:.4g} Hz"
            print(f"  {r['force']:>10s}: static |F̂/F| = {r['static_gain']:.3g}; recovered within 3 dB: {seen}; "
                  f"largest cross-talk {r['max_cross_talk']:.3g}")
        sys.stdout.flush()
    files, notes = {}, []
    if not args.no_plot:
        out = args.out or os.path.join("akf-out", "show")
        with OutputFolder(out, "--out"):
            draw(files, "transfer", notes, plot_transfer, freqs, T[1:], labels, natural,
                 os.path.join(out, f"{name}-transfer.png"), f"{name}: |F̂/F| of the steady filter")
    if args.json:
        print(json.dumps(dict(info, files=files, warnings=notes)))
        return 0
    for k, v in files.items():
        print(f"  wrote {k}: {v}")
    for note in notes:
        print(f"  WARNING: {note}")
    return 0


def _show(args):
    from core_akf.figures import plot_structure

    if args.transfer:
        return _transfer(args)
    structure, name, sensors, forces, filtered = _structure_of(args.model)
    f = structure.frequencies(min(args.modes, structure.n))
    info = {"model": name, "nodes": structure.n_nodes, "dofs": structure.n,
            "dof_directions": list(structure.dof_names), "node_ids": [int(structure.user_node_ids.min()),
                                                                       int(structure.user_node_ids.max())],
            "strain_outputs": structure.n_strain, "frequencies_hz": [float(x) for x in f]}
    if filtered is not None:
        info["filter_frequencies_hz"] = [float(x) for x in filtered[0].frequencies(len(f))]
        info["filter_model"] = filtered[1]
    if structure.n_strain:
        info["first_strain_output"] = structure.strain_labels[0]
        info["last_strain_output"] = structure.strain_labels[-1]
        info["strains"] = strain_outputs(structure)
    if structure.members is not None:
        info["members"] = int(len(structure.members))
    files, notes = {}, []
    if not args.json:
        _print(info, structure)
        sys.stdout.flush()
    if not args.no_plot:
        from ..figures import draw

        out = args.out or os.path.join("akf-out", "show")
        with OutputFolder(out, "--out"):
            title = (f"{name}" + (f" ({structure.name})" if structure.name and structure.name != name else "")
                     + f": {structure.n_nodes} nodes" + (f", {info['members']} members" if "members" in info else ""))
            draw(files, "figure", notes, plot_structure, structure, os.path.join(out, f"{name}.png"),
                 sensors=sensors, forces=forces, numbers=structure.n_nodes <= 200 or structure.nodes.shape[1] == 3,
                 title=title)
    if args.json:
        print(json.dumps(dict(info, files=files, warnings=notes)))
        return 0
    for k, v in files.items():
        print(f"  wrote {k}: {v}")
    for note in notes:
        print(f"  WARNING: {note}")
    return 0


def _print(info, structure):
    print(f"{info['model']}: {structure.n_nodes} nodes (ids {info['node_ids'][0]}..{info['node_ids'][1]}), "
          f"{structure.n} {'modal coordinates' if structure.is_reduced else 'free DOFs'} "
          f"({'/'.join(structure.dof_names)} per node)" + (f", {info['members']} members" if "members" in info else ""))
    if not structure.n_strain:
        print("  strain outputs: none (give extensometers or strain rows for strains)")
    else:
        print(f"  strain outputs: {structure.n_strain} ({info['first_strain_output']} ... {info['last_strain_output']})")
        rows = info["strains"]
        if rows[0]["is"] in ("extensometer", "strain operator row"):
            shown = rows if len(rows) <= 12 else rows[:6] + [None] + rows[-6:]
            for r in shown:
                if r is None:
                    print("    ...")
                elif r["nodes"]:
                    print(f"    {r['output']:>12s}  {r['is']} {r['nodes'][0]}-{r['nodes'][1]}")
                else:
                    print(f"    {r['output']:>12s}  row {r['row']} of the strain operator")
    truth = "" if "filter_frequencies_hz" not in info else " of [structure] (the truth of a simulation)"
    print(f"  first natural frequencies (Hz){truth}: " + ", ".join(f"{x:.4g}" for x in info["frequencies_hz"]))
    if "filter_frequencies_hz" in info:
        print(f"  the filter's model ({info['filter_model']}): "
              + ", ".join(f"{x:.4g}" for x in info["filter_frequencies_hz"]))


def register(sub):
    """Add ``show`` to the ``akf`` sub-command parser."""
    p = sub.add_parser("show", help="draw a structure (built-in or a job file's) with its node and member numbers")
    p.add_argument("model", metavar="MODEL_OR_JOB", help="a built-in structure (" + ", ".join(sorted(set(MODELS) - {
        "matrices"})) + ") or a job file (TOML) whose [structure] to show, with its sensors and forces")
    p.add_argument("--modes", type=int, default=6, help="natural frequencies to print (default 6)")
    p.add_argument("--out", help="output folder (default akf-out/show)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--no-plot", action="store_true", help="do not write the PNG figure")
    p.add_argument("--transfer", action="store_true", help="with a job file of akf estimate: the steady filter's "
                   "|F̂/F| per force against frequency, the band in which the layout recovers each force")
    p.set_defaults(func=_show)
