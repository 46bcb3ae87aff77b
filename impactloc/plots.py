"""The figures of impact localisation (IMP Figs. 4-8): the AD error against the assumed location,
the reconstructed force, the strain errors before and after tuning.  Each writes PNG files and
chooses no backend (:mod:`core_akf.figures`)."""
from __future__ import annotations

import os

import numpy as np

from core_akf.checks import ArrayLike

from .locate import LocateResult


def plot_locate(result: LocateResult, out: str, true_force: ArrayLike | None = None,
                true_strains: ArrayLike | None = None, split: int = 0) -> dict[str, str]:
    """PNG figures like IMP Figs. 4-8 in a folder.

    * ``error_vs_location.png`` -- AD error vs assumed location for one split (Fig. 4) and the
      distribution over all splits (Fig. 5);
    * ``force.png`` -- reconstructed force with assumed and tuned covariances (Fig. 6/7);
    * ``strain_errors.png`` -- RMS strain error per member/component before and after tuning
      (Fig. 8; needs ``true_strains``).

    Parameters
    ----------
    result : LocateResult
    out : str
        The folder.
    true_force : ndarray (N,), optional
        The true force history (N), drawn beside the reconstructions.
    true_strains : ndarray (N, n_strain), optional
        The true strains (m/m), for the strain-error figure.
    split : int
        The role split of the first panel.

    Returns
    -------
    dict
        Figure name -> path.
    """
    from core_akf.figures import save_figure, subplots

    files = {}
    sc = result.scan
    nodes = [n for n, _ in sc.locations]
    fig, axes = subplots(1, 2, figsize=(11, 3.6))
    axes[0].plot(nodes, sc.errors[:, split], "o-")
    axes[0].set_xlabel("assumed impact node")
    axes[0].set_ylabel("mean relative AD error")
    axes[0].set_title(f"one role split (AD: {sc.frame.query('split == @split')['ad_sensors'].iloc[0]})", fontsize=8)
    data = [row[np.isfinite(row)] for row in sc.errors]
    axes[1].boxplot(data, positions=range(len(nodes)), widths=0.6)
    axes[1].set_xticks(range(len(nodes)), [str(n) for n in nodes], fontsize=7)
    axes[1].set_xlabel("assumed impact node")
    axes[1].set_title(f"all {sc.errors.shape[1]} splits: identified node {sc.identified[0]} "
                      f"(confidence {sc.confidence:.2f}, margin {sc.margin:.1f})", fontsize=8)
    files["error_vs_location"] = save_figure(fig, os.path.join(out, "error_vs_location.png"))

    est0, est1 = result.initial.estimate, result.reconstruction.estimate
    fig, axes = subplots(2, 1, figsize=(9, 5))
    for ax, zoom in zip(axes, (False, True)):
        if true_force is not None:
            ax.plot(est1.time, np.asarray(true_force) / 1e3, "k:", lw=1.2, label="true")
        ax.plot(est0.time, result.initial.force / 1e3, color="tab:orange", lw=0.8, label="assumed covariances")
        ax.plot(est1.time, result.reconstruction.force / 1e3, "r-", lw=0.8, label="tuned covariances")
        ax.set_ylabel("force (kN)")
        if zoom:
            tp = result.reconstruction.summary.time_of_peak
            ax.set_xlim(tp - 0.03, tp + 0.05)
            ax.set_xlabel("time (s)")
    axes[0].legend(fontsize=7)
    axes[0].set_title(f"impact force at node {sc.identified[0]}: peak {result.reconstruction.summary.peak / 1e3:.2f} kN",
                      fontsize=9)
    files["force"] = save_figure(fig, os.path.join(out, "force.png"))

    if true_strains is not None:
        fig, ax = subplots(figsize=(9, 3.2))
        e0 = np.sqrt(np.mean((est0.strains - true_strains) ** 2, axis=0)) * 1e6
        e1 = np.sqrt(np.mean((est1.strains - true_strains) ** 2, axis=0)) * 1e6
        x = np.arange(1, e0.size + 1)
        ax.bar(x - 0.2, e0, 0.4, label=f"assumed (mean {e0.mean():.3f} µε)")
        ax.bar(x + 0.2, e1, 0.4, label=f"tuned (mean {e1.mean():.3f} µε)")
        ax.set_xlabel("member / strain component")
        ax.set_ylabel("RMS strain error (µε)")
        ax.legend(fontsize=7)
        files["strain_errors"] = save_figure(fig, os.path.join(out, "strain_errors.png"))
    return files
