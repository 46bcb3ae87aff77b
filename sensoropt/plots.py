"""Figures: GA convergence, a layout drawn on the plate mesh, the Pareto front.  Each function
returns the :class:`~matplotlib.figure.Figure` (shown inline in a notebook) and writes it to
``path`` when one is given."""
from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from core_akf.checks import Forces
from core_akf.figures import save_figure, subplots

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure

    from .encoding import CandidateSet

_MARKERS = {"ex": ("s", "tab:blue"), "ey": ("D", "tab:green"), "gxy": ("^", "tab:purple"), "acc": ("o", "tab:red")}


def plot_convergence(logbook: pd.DataFrame, path: str | None = None, title: str = "placement GA") -> Figure:
    """Best and mean fitness and the diversity per generation.

    Parameters
    ----------
    logbook : pandas.DataFrame
        A GA logbook (:attr:`~sensoropt.ga.PlacementResult.logbook`).
    path : str, optional
        Write the figure here.
    title : str

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = subplots(figsize=(7, 3.6))
    ax.plot(logbook["generation"], logbook["best"], "k-", label="best")
    ax.plot(logbook["generation"], logbook["mean"], "b--", lw=0.8, label="mean")
    ax.set_yscale("log")
    ax.set_xlabel("generation")
    ax.set_ylabel("average strain error (µε)")
    if "diversity" in logbook:
        ax2 = ax.twinx()
        ax2.plot(logbook["generation"], logbook["diversity"], color="tab:orange", lw=0.8, label="diversity")
        ax2.set_ylabel("diversity (grid units)", color="tab:orange")
    ax.legend(loc="upper right", fontsize=7)
    ax.set_title(title, fontsize=9)
    return _finish(fig, path)


def plot_layout(encoding: CandidateSet, layout: Sequence[int], path: str | None = None, title: str = "",
                forces: Forces = ()) -> Figure:
    """A sensor layout on its structure.

    On the plate grid: the mesh (nodes as dots, clamped nodes grey), the sensors with kind
    markers and node ids, and the force locations (red crosses); on any other structure the
    layout drawn on the structure (3-D for 3-D coordinates, :func:`core_akf.figures.plot_structure`).

    Parameters
    ----------
    encoding : CandidateSet or PlateGrid
    layout : sequence of int
        Candidate indices.
    path : str, optional
        Write the figure here.
    title : str
    forces : sequence of force specs
        Force locations to mark.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from .encoding import PlateGrid

    if not isinstance(encoding, PlateGrid):
        from core_akf.figures import plot_structure

        return plot_structure(encoding.structure, path=path, title=title, numbers=encoding.structure.n_nodes <= 60,
                              forces=forces, sensors=encoding.sensors(layout))
    s = encoding.structure
    xy = s.nodes
    fig, ax = subplots(figsize=(6, 5))
    ax.plot(xy[:, 0], xy[:, 1], ".", color="0.75", ms=4)
    free = set(encoding.node.tolist())
    clamped = [n for n in range(1, s.n_nodes + 1) if n not in free]
    if clamped:
        c = xy[np.array(clamped) - 1]
        ax.plot(c[:, 0], c[:, 1], "s", color="0.4", ms=4, label="no admissible sensor")
    for kind, (m, col) in _MARKERS.items():
        pts = [encoding.node[i] for i in layout if encoding.kind[i] == kind]
        if pts:
            p = xy[np.array(pts) - 1]
            ax.plot(p[:, 0], p[:, 1], m, color=col, ms=10, mfc="none", mew=2, label=kind)
    for i in layout:
        x, y = xy[encoding.node[i] - 1]
        ax.annotate(f"{encoding.node[i]}", (x, y), textcoords="offset points", xytext=(6, 6), fontsize=8)
    for j, (node, direction) in enumerate(forces):
        x, y = xy[node - 1]
        ax.plot(x, y, "x", color="red", ms=10, mew=2, label=f"load {j + 1}: node {node} ({direction})")
        ax.annotate(f"F{j + 1}", (x, y), textcoords="offset points", xytext=(-14, -12), fontsize=8, color="red")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1, 0.5))
    ax.set_title(title, fontsize=9)
    return _finish(fig, path)


def plot_pareto(front: pd.DataFrame, path: str | None = None, title: str = "error vs number of sensors") -> Figure:
    """The Pareto front: error against cost (or the number of sensors), log scale.

    Parameters
    ----------
    front : pandas.DataFrame
        :attr:`~sensoropt.pareto.ParetoResult.front`.
    path : str, optional
        Write the figure here.
    title : str

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = subplots(figsize=(6, 3.6))
    x = front["cost"] if "cost" in front else front["n_sensors"]
    ax.plot(x, front["error"], "o-")
    for xi, e, n in zip(x, front["error"], front["n_sensors"]):
        ax.annotate(str(n), (xi, e), textcoords="offset points", xytext=(4, 4), fontsize=7)
    ax.set_xlabel("cost (sensors)")
    ax.set_ylabel("average strain error (µε)")
    ax.set_yscale("log")
    ax.set_title(title, fontsize=9)
    return _finish(fig, path)


def _finish(fig, path):
    if path is not None:
        save_figure(fig, path)
    return fig
