"""Figure helpers shared by the plots of every package.

Figures are made with :class:`matplotlib.figure.Figure` directly, without ``pyplot`` and without
choosing a backend: they render in scripts, on servers (no display needed) and in notebooks,
where a returned figure is shown inline.  Functions that plot return the figure; they write it to
a file only when given a path.
"""
from __future__ import annotations

import os


def subplots(nrows=1, ncols=1, *, figsize=None, **kw):
    """A new figure and its axes, like ``pyplot.subplots`` but not registered with pyplot (so it
    needs no backend and is never left open): ``(Figure, Axes or array of Axes)``."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    return fig, fig.subplots(nrows, ncols, **kw)


def figure(figsize=None):
    """A new :class:`~matplotlib.figure.Figure` (not registered with pyplot)."""
    from matplotlib.figure import Figure

    return Figure(figsize=figsize)


def save_figure(fig, path, dpi=110):
    """Lay out ``fig`` and write it to ``path`` (creating the folder; complete or absent, also on
    Ctrl-C); returns ``path``."""
    from .outputs import atomic_path

    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format=os.path.splitext(path)[1].lstrip(".") or "png")
    return path


def plot_structure(structure, path=None, title=None, numbers=True, forces=(), sensors=()):
    """The structure with its user-facing numbers: node ids, member ids (truss, in boxes), the
    supports (grey squares), and optionally force locations (red crosses, in the legend) and
    sensors (blue circles).  Returns the Figure; writes it to ``path`` if given."""
    import numpy as np

    xy = structure.nodes
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
    for j, (node, direction) in enumerate(forces):
        x, y = xy[structure.node_rows(node)[0], :2]
        ax.plot(x, y, "x", color="red", ms=11, mew=2, zorder=4, label=f"load {j + 1}: node {node} ({direction})")
    for s in sensors:
        parts = str(s).split(":")
        if len(parts) >= 3 or (parts[0] != "strain" and len(parts) >= 2):
            node = int(parts[1])
            ax.plot(*xy[structure.node_rows(node)[0], :2], "o", mfc="none", mec="tab:blue", ms=10, mew=1.5, zorder=4)
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
