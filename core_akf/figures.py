"""Figure helpers shared by the plots of every package.

Figures are made with :class:`matplotlib.figure.Figure` directly, without ``pyplot`` and without
choosing a backend: they render in scripts, on servers (no display needed) and in notebooks,
where a returned figure is shown inline.  Functions that plot return the figure; they write it to
a file only when given a path.
"""
from __future__ import annotations

import os


def subplots(nrows=1, ncols=1, *, figsize=None, **kw):
    """A new figure and its axes, like ``pyplot.subplots`` but not registered with pyplot.

    It needs no display backend and is never left open.

    Parameters
    ----------
    nrows, ncols : int
        The grid of axes.
    figsize : tuple of float, optional
        Width and height (inches).
    **kw
        Further arguments of :meth:`matplotlib.figure.Figure.subplots` (``squeeze``, ``sharex``).

    Returns
    -------
    fig : matplotlib.figure.Figure
    axes : Axes or ndarray of Axes
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    return fig, fig.subplots(nrows, ncols, **kw)


def figure(figsize=None):
    """A new :class:`~matplotlib.figure.Figure`, not registered with pyplot.

    Parameters
    ----------
    figsize : tuple of float, optional
        Width and height (inches).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    return Figure(figsize=figsize)


def save_figure(fig, path, dpi=110, tight=True, crop=False):
    """Lay out a figure and write it, complete or not at all.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : str
        The image file (its folder is created); written atomically, also on Ctrl-C.
    dpi : int
        Resolution (dots per inch).
    tight : bool
        :meth:`~matplotlib.figure.Figure.tight_layout` first.
    crop : bool
        Cut the empty margins off the written image (3-D axes).

    Returns
    -------
    str
        ``path``.
    """
    from .outputs import atomic_path

    if tight:
        fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format=os.path.splitext(path)[1].lstrip(".") or "png",
                    **({"bbox_inches": "tight", "pad_inches": 0.15} if crop else {}))
    return path


def plot_structure(structure, path=None, title=None, numbers=True, forces=(), sensors=()):
    """The structure with its user-facing numbers.

    Node ids, member ids (truss, in boxes), the supports (grey squares), and optionally force
    locations (red crosses, in the legend) and sensors (blue circles).

    Parameters
    ----------
    structure : Structure
        A planar or 3-D structure (3-D: :func:`plot_layout_3d`).
    path : str, optional
        Write the figure here.
    title : str, optional
        The title (default the structure's name).
    numbers : bool
        Write the node and member numbers.
    forces : sequence of force specs
        Force locations to mark ("8:y").
    sensors : sequence of sensor specs
        Sensors to mark ("strain:13", "acc:8:y").

    Returns
    -------
    matplotlib.figure.Figure
    """
    import numpy as np

    from .sensors import as_layout, strain_ends

    xy = structure.nodes
    if xy.shape[1] == 3:
        return plot_layout_3d(structure, sensors=sensors, forces=forces, path=path, title=title, numbers=numbers)
    span = np.ptp(xy, axis=0)
    aspect = span[1] / span[0] if span[0] > 0 else 1.0
    fig, ax = subplots(figsize=(min(12.0, 3 + 9 * min(1.0, 1 / max(aspect, 1e-3))), min(9.0, 2.5 + 8 * min(aspect, 1.0))))
    if structure.members is not None:
        for m, (a, b) in enumerate(structure.members, start=1):
            (x0, y0), (x1, y1) = xy[structure.node_rows([a, b])][:, :2]
            ax.plot([x0, x1], [y0, y1], "-", color="0.35", lw=1.2)
            if numbers:
                ax.annotate(str(m), ((x0 + x1) / 2, (y0 + y1) / 2), ha="center", va="center", fontsize=7,
                            color="tab:blue", bbox=dict(boxstyle="square,pad=0.15", fc="white", ec="tab:blue", lw=0.5))
    ax.plot(xy[:, 0], xy[:, 1], "o", color="k", ms=3, zorder=3)
    n_dof = len(structure.dof_names)
    free = set(int(d) // n_dof for d in structure.free_dofs)
    fixed_nodes = [i for i in range(structure.n_nodes) if i not in free or
                   len([d for d in structure.free_dofs if int(d) // n_dof == i]) < n_dof]
    if fixed_nodes:
        ax.plot(xy[fixed_nodes, 0], xy[fixed_nodes, 1], "s", color="0.55", ms=7, zorder=2,
                label="support (a constrained DOF)")
    if numbers:
        small = structure.n_nodes > 60
        for i, (x, y) in zip(structure.user_node_ids, xy[:, :2]):
            ax.annotate(str(i), (x, y), textcoords="offset points", xytext=(3, 3), fontsize=5 if small else 8)
    for j, (node, direction) in enumerate(_force_pairs(forces)):
        x, y = xy[structure.node_rows(node)[0], :2]
        ax.plot(x, y, "x", color="red", ms=11, mew=2, zorder=4, label=f"load {j + 1}: node {node} ({direction})")
    named = set()
    for s in (as_layout(list(sensors)) if len(sensors) else ()):
        ends = strain_ends(structure, s.member) if s.kind == "strain" and s.member is not None else None
        label = None if s.kind in named else {"strain": "strain gauge", "acc": "accelerometer"}.get(s.kind, s.kind)
        if ends is not None:
            ax.plot(*xy[structure.node_rows(list(ends))][:, :2].T, "-", color="tab:blue", lw=3, zorder=4, label=label)
        elif s.node is not None:      # a ring larger than a load's cross, drawn over it: both stay visible
            marker = SENSOR_STYLE.get(s.kind, ("o",))[0]
            ax.plot(*xy[structure.node_rows(s.node)[0], :2], marker, mfc="none", mec="tab:blue", ms=14, mew=1.5,
                    zorder=5, label=label)
        else:
            continue
        named.add(s.kind)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title or f"{structure.name or 'structure'}: {structure.n_nodes} nodes"
                 + (f", {len(structure.members)} members" if structure.members is not None else ""), fontsize=9)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    if path is not None:
        save_figure(fig, path)
    return fig


def _numbers_3d(ax, structure, P):
    """Node numbers (black) and member numbers (blue) on a 3-D axis at the drawn points ``P``: every
    k-th, at most :data:`NUMBERS_3D` of each; returns a note saying which when thinned."""
    ids = structure.user_node_ids
    step = max(1, -(-len(ids) // NUMBERS_3D))
    for i in range(0, len(ids), step):
        ax.text(*P[i], str(int(ids[i])), fontsize=6, color="k", zorder=6)
    note = [] if step == 1 else [f"node numbers: every {step}th"]
    if structure.members is not None:
        m_step = max(1, -(-len(structure.members) // NUMBERS_3D))
        rows = structure.node_rows(structure.members.ravel()).reshape(-1, 2)
        for k in range(0, len(rows), m_step):
            a, b = rows[k]
            ax.text(*(0.5 * (P[a] + P[b])), str(k + 1), fontsize=5, color="tab:blue", zorder=6)
        if m_step > 1:
            note.append(f"member numbers (blue): every {m_step}th")
    return "; ".join(note)


def _force_pairs(forces):
    """Force locations as ``(node, direction)`` pairs from pairs or ``"NODE:DIR"`` strings."""
    pairs = []
    for f in forces:
        if isinstance(f, str):
            node, _, direction = f.partition(":")
            f = (int(node), direction)
        pairs.append((f[0], f[1]))
    return pairs


#: sensor kind -> (marker, colour) in the layout figures
SENSOR_STYLE = {"strain": ("s", "tab:blue"), "acc": ("o", "tab:red"), "vel": ("^", "tab:orange"),
                "disp": ("D", "tab:green")}


#: at most this many node numbers and as many member numbers are written on a 3-D structure (every k-th)
NUMBERS_3D = 60


def plot_layout_3d(structure, sensors=(), forces=(), path=None, title=None, exaggerate=None, numbers=True):
    """A 3-D structure with a sensor layout.

    Members (grey lines), supports (grey squares), strain gauges (their member drawn thick in
    blue, a square at its middle), accelerometers and other point sensors (a marker at the node
    and an arrow along the measured direction), forces (red arrows).

    Parameters
    ----------
    structure : Structure
        A structure with 3-D node coordinates.
    sensors : sequence of sensor specs
        The layout to draw.
    forces : sequence of force specs
        Force locations to draw.
    path : str, optional
        Write the figure here.
    title : str, optional
        The title.
    exaggerate : float, optional
        Draw the cross-section (y and z) this many times larger than the length when the structure
        is slender (default: chosen to make it readable; the axis labels say so).
    numbers : bool
        Write node numbers (black) and member numbers (blue), every k-th of them so that at most
        :data:`NUMBERS_3D` of each are written (the figure's note says which).

    Returns
    -------
    matplotlib.figure.Figure
    """
    import numpy as np

    from .sensors import as_layout, strain_ends

    xyz = structure.nodes
    lo, span = xyz.min(axis=0), np.maximum(np.ptp(xyz, axis=0), 1e-12)
    if exaggerate is None:
        exaggerate = float(np.clip(span.max() / (4 * max(span[1], span[2])), 1.0, 5.0))
    scale = np.array([1.0, exaggerate, exaggerate])
    P = (xyz - lo) * scale
    fig = figure(figsize=(11, 3.9))
    ax = fig.add_subplot(projection="3d")
    if structure.members is not None:
        for a, b in structure.node_rows(structure.members.ravel()).reshape(-1, 2):
            ax.plot(*P[[a, b]].T, "-", color="0.7", lw=0.6)
    else:
        ax.scatter(*P.T, s=2, color="0.6")
    n_dof = len(structure.dof_names)
    counts = np.bincount(np.asarray(structure.free_dofs) // n_dof, minlength=structure.n_nodes)
    sup = np.flatnonzero(counts < n_dof)
    if sup.size:
        ax.scatter(*P[sup].T, marker="s", s=30, color="0.4", label="support")
    thinned = _numbers_3d(ax, structure, P) if numbers else ""
    arrow = 0.04 * span.max()
    dirs = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1), "w": (0, 0, 1)}
    labelled = set()
    unplaced, placed = [], []
    for s in (as_layout(list(sensors)) if len(sensors) else ()):
        marker, colour = SENSOR_STYLE[s.kind]
        ends = strain_ends(structure, s.member) if s.kind == "strain" and s.member is not None else None
        if s.kind == "strain" and s.member is not None and ends is None:
            unplaced.append(s.label)          # a row of a strain operator of one's own: no place to draw
            continue
        label = None if s.kind in labelled else {"strain": "strain gauge", "acc": "accelerometer"}.get(s.kind, s.kind)
        labelled.add(s.kind)
        if ends is not None:
            a, b = structure.node_rows(list(ends))
            ax.plot(*P[[a, b]].T, "-", color=colour, lw=3)
            point = 0.5 * (P[a] + P[b])
            text = f"{s.member}"
        else:
            point = P[structure.node_rows([s.node])[0]]
            text = f"{s.node}{s.direction or ''}"
            if s.direction in dirs:
                ax.quiver(*point, *(arrow * np.array(dirs[s.direction])), color=colour, lw=1.5)
        ax.scatter(*point, marker=marker, s=60, facecolors="none", edgecolors=colour, linewidths=2, label=label)
        placed.append((point, text, colour))
    # labels lifted in three tiers by their order along x, so that neighbours do not overlap
    for rank, i in enumerate(np.argsort([p[0][0] for p in placed], kind="stable")):
        point, text, colour = placed[i]
        ax.text(*(point + (0.02 + 0.035 * (rank % 3)) * span.max() * np.array([0, 0, 1])), text, fontsize=7,
                color=colour)
    notes = [f"not drawn (strain operator rows, no place): {', '.join(unplaced)}"] * bool(unplaced) + [thinned] * bool(thinned)
    if notes:
        ax.text2D(0.01, 0.02, "; ".join(notes), fontsize=7, transform=ax.transAxes)
    forces = _force_pairs(forces)
    for j, (node, direction) in enumerate(forces):
        point = P[structure.node_rows([node])[0]]
        d = np.array(dirs.get(direction, (0, 0, 1)), float)
        ax.quiver(*(point + 2 * arrow * d), *(-2 * arrow * d), color="red", lw=2,
                  label=f"load {j + 1}: node {node} ({direction})")
    ax.set_box_aspect(np.maximum(span * scale, 0.02 * span.max()), zoom=1.2)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)" if exaggerate == 1 else f"y (m, drawn x{exaggerate:.3g})")
    ax.set_zlabel("z (m)" if exaggerate == 1 else f"z (m, x{exaggerate:.3g})")
    for setter, k in ((ax.set_xticks, 0), (ax.set_yticks, 1), (ax.set_zticks, 2)):
        ticks = np.linspace(0, span[k], 3 if k else 5)
        setter(ticks * scale[k])
    ax.set_xticklabels([f"{v + lo[0]:.3g}" for v in np.linspace(0, span[0], 5)])
    ax.set_yticklabels([f"{v + lo[1]:.3g}" for v in np.linspace(0, span[1], 3)])
    ax.set_zticklabels([f"{v + lo[2]:.3g}" for v in np.linspace(0, span[2], 3)])
    ax.view_init(elev=24, azim=-68)
    ax.xaxis.labelpad = 12
    ax.set_title(title or f"{structure.name or 'structure'}: {structure.n_nodes} nodes"
                 + (f", {len(structure.members)} members" if structure.members is not None else ""), fontsize=9)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0.0, 0.95))
    fig.subplots_adjust(left=0.0, right=1.0, bottom=0.02, top=0.95)
    if path is not None:
        save_figure(fig, path, tight=False, crop=True)
    return fig
