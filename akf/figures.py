"""The app's figures and its figure writer: :func:`draw` runs a plot after the results are written,
never at their cost; the figures of ``akf estimate`` (simulated and measured jobs alike) -- the
estimated forces (with the reference when there is one) and the strain errors, every sensor's
measured signal against its one-step prediction, the fatigue map -- and the location map of
``akf locate``.  Each plot takes plain arrays, writes ``path`` and returns it."""
from __future__ import annotations

import logging
import os

import numpy as np

log = logging.getLogger("akf")

#: above this many strain outputs, the error panel ranks the worst :data:`WORST` instead of a bar each
MANY_OUTPUTS = 40
WORST = 25


def plot_estimate(time, forces, force_labels, path, title, reference=None, strain_errors=None, consistency=None,
                  note="", force_std=None):
    """Estimated forces (kN) against time, the reference (dashed, drawn on top) if given, the RMS
    strain error per output (µε; the worst :data:`WORST` ranked when there are many) and the
    consistency per sensor (``{channel: innovation RMS / predicted}``) if given; ``force_std``
    (N, same shape as ``forces``) draws +-2 sigma bands around a smoothed estimate, and beside each
    force a zoom on a stretch where the band can be seen (:func:`band_window`, shaded on the
    whole record): on a kN axis over the whole record a band of a few N is a line."""
    from core_akf.figures import figure, save_figure

    nf = forces.shape[1]
    panels = nf + (1 if strain_errors else 0) + (1 if consistency else 0)
    fig = figure(figsize=(11 if force_std is not None else 9,
                          2.2 * panels + (1.5 if strain_errors and len(strain_errors) > MANY_OUTPUTS else 0)))
    zoomed = force_std is not None
    grid = fig.add_gridspec(panels, 2 if zoomed else 1, width_ratios=[3, 1] if zoomed else None)
    for j, label in enumerate(force_labels):
        ax = fig.add_subplot(grid[j, 0])
        if zoomed:
            ax.fill_between(time, (forces[:, j] - 2 * force_std[:, j]) / 1e3, (forces[:, j] + 2 * force_std[:, j]) / 1e3,
                            color="tab:red", alpha=0.2, lw=0, label="±2σ (smoothed)", zorder=1)
        ax.plot(time, forces[:, j] / 1e3, "-", color="tab:red", lw=0.9,
                label="AKF estimate" + (" (smoothed)" if zoomed else ""), zorder=2)
        if reference is not None:
            ax.plot(time, reference[:, j] / 1e3, "--", color="k", lw=0.9, label="reference", zorder=3)
        ax.set_ylabel(f"force {label}\n(kN)")
        ax.legend(loc="upper right", fontsize=7)
        if j == nf - 1:
            ax.set_xlabel("time (s)" + note)
        if zoomed:
            a, b = band_window(forces[:, j], force_std[:, j])
            ax.axvspan(time[a], time[b - 1], color="0.6", alpha=0.25, lw=0, zorder=0)
            _band_zoom(fig.add_subplot(grid[j, 1]), time[a:b], forces[a:b, j], force_std[a:b, j],
                       None if reference is None else reference[a:b, j], label)
    if strain_errors:
        _strain_error_panel(fig.add_subplot(grid[nf, :]), strain_errors)
    if consistency:
        ax = fig.add_subplot(grid[panels - 1, :])
        ax.bar(range(len(consistency)), list(consistency.values()), color="tab:blue")
        ax.axhline(1.0, color="k", lw=0.8, ls="--")
        ax.set_xticks(range(len(consistency)), list(consistency), rotation=45, fontsize=7)
        ax.set_ylabel("innovation /\npredicted")
    fig.suptitle(title)
    return save_figure(fig, path)


#: the zoom of :func:`band_window` stops growing where the estimate spans this many times its 2σ
BAND_SPAN = 7.0


def band_window(values, std, span=None):
    """The stretch ``(start, stop)`` of a smoothed estimate on which its ±2σ band can be seen.

    Centred on the record's middle, it grows while the estimate's range over it stays within
    ``span`` (default :data:`BAND_SPAN`) times the median 2σ, to at most a fifth of the record;
    drawn on its own axis, the band then fills at least a tenth of it.

    Parameters
    ----------
    values, std : ndarray (N,)
        The estimate and its standard deviation (same unit).
    span : float, optional

    Returns
    -------
    (int, int)
    """
    values, std = np.asarray(values, float), np.asarray(std, float)
    n = values.size
    two_sigma = 2 * float(np.median(std)) if n else 0.0
    if n < 4 or not two_sigma > 0:
        return 0, n
    limit = (BAND_SPAN if span is None else span) * two_sigma
    lo, hi = max(0, n // 2 - 2), min(n, n // 2 + 3)
    while hi - lo < max(5, n // 5) and (lo > 0 or hi < n):
        grow = max(1, (hi - lo) // 4)
        a, b = max(0, lo - grow), min(n, hi + grow)
        if np.ptp(values[a:b]) > limit:
            break
        lo, hi = a, b
    return lo, hi


def _band_zoom(ax, time, values, std, reference, label):
    """The zoom beside a force: the estimate with its ±2σ band (N), and the reference."""
    from matplotlib.ticker import MaxNLocator

    ax.fill_between(time, values - 2 * std, values + 2 * std, color="tab:red", alpha=0.25, lw=0)
    marker = "." if time.size <= 60 else None
    ax.plot(time, values, "-", color="tab:red", lw=0.9, marker=marker, ms=3)
    if reference is not None:
        ax.plot(time, reference, "--", color="k", lw=0.9)
    low, high = float(np.min(values - 2 * std)), float(np.max(values + 2 * std))
    pad = 0.05 * (high - low)
    ax.set_ylim(low - pad, high + pad)
    ax.set_title(f"zoom: ±2σ = ±{2 * float(np.median(std)):.3g} N", fontsize=8)
    ax.set_ylabel(f"{label} (N)", fontsize=7)
    ax.tick_params(labelsize=6)
    ax.ticklabel_format(axis="x", useOffset=False)
    ax.xaxis.set_major_locator(MaxNLocator(3))
    ax.set_xlabel("time (s)", fontsize=7)


def _strain_error_panel(ax, errors):
    labels, values = list(errors), np.array(list(errors.values())) * 1e6
    if len(values) <= MANY_OUTPUTS:
        ax.bar(range(len(values)), values, color="tab:blue")
        ax.set_xticks(range(len(values)), [lab.replace("strain:", "") for lab in labels], rotation=90, fontsize=6)
        ax.set_xlabel("strain output")
    else:
        order = np.argsort(values)[::-1][:WORST]
        ax.barh(range(len(order)), values[order][::-1], color="tab:blue")
        ax.set_yticks(range(len(order)), [labels[i] for i in order][::-1], fontsize=6)
        ax.set_xlabel(f"RMS strain error (µε): the {len(order)} worst of {len(values)} outputs; mean "
                      f"{values.mean():.3g}, median {np.median(values):.3g} µε (all in summary.csv)")
        return
    ax.set_ylabel("RMS strain\nerror (µε)")


def plot_sensors(time, measured, predicted, sensors, path, title):
    """Every sensor's measured signal against its one-step prediction, in readable units (strain
    in µε); several columns for many sensors."""
    from core_akf.figures import save_figure, subplots
    from core_akf.sensors import UNITS

    k = len(sensors)
    ncols = 1 if k <= 10 else 2 if k <= 24 else 3
    nrows = -(-k // ncols)
    fig, axes = subplots(nrows, ncols, figsize=(9 * min(ncols, 2), 1.5 * nrows + 0.8), squeeze=False, sharex=True)
    for j, s in enumerate(sensors):
        ax = axes[j % nrows, j // nrows]
        scale, unit = (1e6, "µε") if s.kind == "strain" else (1.0, UNITS[s.kind])
        ax.plot(time, measured[:, j] * scale, "-", color="k", lw=0.6, label="measured")
        ax.plot(time, predicted[:, j] * scale, "-", color="tab:red", lw=0.6, alpha=0.8, label="predicted (one step)")
        ax.set_ylabel(f"{s.label}\n({unit})", fontsize=7)
        ax.tick_params(labelsize=7)
        if j == 0:
            ax.legend(loc="upper right", fontsize=7)
    for j in range(k, nrows * ncols):
        axes[j % nrows, j // nrows].set_visible(False)
    for c in range(ncols):
        axes[nrows - 1, c].set_xlabel("time (s)")
    fig.suptitle(title)
    return save_figure(fig, path)


def plot_transfer(frequencies, transfer, force_labels, natural_frequencies, path, title):
    """``|F_hat / F|`` of each force against frequency (log axes), with the cross-talk from the
    other forces dashed and the structure's natural frequencies as grey lines: the band in which
    the layout recovers a force (:func:`core_akf.filter.force_transfer`, one layout's
    ``(n_f, n_p, n_p)``)."""
    from core_akf.figures import save_figure, subplots

    n_p = len(force_labels)
    fig, axes = subplots(n_p, 1, figsize=(8, 1.9 * n_p + 0.9), squeeze=False, sharex=True)
    for j, label in enumerate(force_labels):
        ax = axes[j, 0]
        for fn in natural_frequencies:
            ax.axvline(fn, color="0.85", lw=0.8, zorder=0)
        ax.axhspan(1 / np.sqrt(2), np.sqrt(2), color="tab:green", alpha=0.08, lw=0)
        ax.loglog(frequencies, np.abs(transfer[:, j, j]), "-", color="k", lw=1.2, label=f"{label} from {label}")
        for k in range(n_p):
            if k != j:
                ax.loglog(frequencies, np.abs(transfer[:, j, k]), "--", lw=0.7, label=f"from {force_labels[k]}")
        ax.set_ylim(1e-3, 10.0)
        ax.set_ylabel(f"|F̂/F| {label}", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.legend(loc="lower right", fontsize=6, ncol=min(n_p, 4))
    axes[-1, 0].set_xlabel("frequency (Hz); grey: natural frequencies; green: within 3 dB")
    fig.suptitle(title)
    return save_figure(fig, path)


#: the fatigue map's colour scale spans the largest damage down to this fraction of it
FATIGUE_RANGE = 1e4


def plot_fatigue(structure, channels, damage, path, title, sensors=(), quantity="Miner's damage"):
    """The damage map on the structure (members or nodes coloured by ``damage``, log scale from
    the largest down to 1/:data:`FATIGUE_RANGE` of it; a 3-D structure in 3-D) above the ten most
    damaged outputs, ranked on a linear axis.  The strain gauges are
    marked: the outputs no gauge sees are the point of estimating them.  ``quantity`` names what
    is drawn (the damage-equivalent range when no cycle reaches the curve's cut-off)."""
    import matplotlib as mpl
    import numpy as np

    from core_akf.figures import figure, save_figure
    from core_akf.sensors import as_layout, strain_ends

    channels, damage = list(channels), np.asarray(damage, float)
    positive = damage[damage > 0]
    lo, hi = (positive.min(), positive.max()) if positive.size else (1e-12, 1.0)
    floor = max(lo, hi / FATIGUE_RANGE)      # what is 1e4 x below the worst does not matter: one colour
    extend = "min" if floor > lo else "neither"
    norm = mpl.colors.LogNorm(vmin=floor, vmax=max(hi, floor * 10))
    cmap = mpl.colormaps["inferno_r"]
    xyz = structure.nodes
    three_d = xyz.shape[1] == 3
    if three_d:                  # a slender structure's cross-section drawn larger, as plot_layout_3d does
        lo, span = xyz.min(axis=0), np.maximum(np.ptp(xyz, axis=0), 1e-12)
        scale = np.array([1.0, *[float(np.clip(span.max() / (4 * max(span[1], span[2])), 1.0, 5.0))] * 2])
        xyz = (xyz - lo) * scale
    fig = figure(figsize=(10, 7.5))
    grid = fig.add_gridspec(2, 1, height_ratios=[1.3, 1.0])
    ax = fig.add_subplot(grid[0], projection="3d") if three_d else fig.add_subplot(grid[0])
    dims = 3 if three_d else 2

    def colour(d):
        return "0.8" if d <= 0 else cmap(norm(d))
    if structure.members is not None:
        for a, b in structure.node_rows(structure.members.ravel()).reshape(-1, 2):
            ax.plot(*xyz[[a, b], :dims].T, "-", color="0.85", lw=0.8)
    per_node = {}
    for label, d in zip(channels, damage):
        parts = label.split(":")
        ends = strain_ends(structure, int(parts[1])) if len(parts) == 2 else None
        if ends is not None:
            a, b = structure.node_rows(list(ends))
            ax.plot(*xyz[[a, b], :dims].T, "-", color=colour(d), lw=3)
        elif len(parts) == 3:
            row = structure.node_rows([int(parts[1])])[0]
            per_node[row] = max(per_node.get(row, 0.0), d)
    if per_node:
        rows = np.array(list(per_node))
        values = np.array([per_node[r] for r in rows])
        ax.scatter(*xyz[rows, :dims].T, c=[colour(v) for v in values], s=40, edgecolors="none")
    gauges = [s for s in as_layout(list(sensors)) if s.kind == "strain"] if len(sensors) else []
    for s in gauges:
        ends = strain_ends(structure, s.member) if s.member is not None else None
        point = (xyz[structure.node_rows(list(ends))].mean(axis=0) if ends is not None else
                 xyz[structure.node_rows([s.node])[0]] if s.node is not None else None)
        if point is not None:
            ax.scatter(*point[:dims], marker="s", s=60, facecolors="none", edgecolors="tab:blue", linewidths=1.5)
    if gauges:
        ax.scatter([], [], marker="s", facecolors="none", edgecolors="tab:blue", label="strain gauge")
        ax.legend(fontsize=7, loc="upper left")
    if three_d:
        ax.set_box_aspect(np.maximum(np.ptp(xyz, axis=0), 0.02 * np.ptp(xyz, axis=0).max()), zoom=1.2)
        ax.view_init(elev=24, azim=-68)
        ax.set_xlabel("x (m)")
        if scale[1] > 1:
            ax.set_ylabel(f"y (m, x{scale[1]:.3g})")
            ax.set_zlabel(f"z (m, x{scale[1]:.3g})")
    else:
        ax.set_aspect("equal")
    ax.set_title(f"{quantity} (grey: none; the scale spans the largest down to 1/{FATIGUE_RANGE:g} of it)", fontsize=9)
    fig.colorbar(mpl.cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax, shrink=0.8, label=quantity,
                 pad=0.12 if three_d else 0.05, extend=extend)
    ax2 = fig.add_subplot(grid[1])
    top = np.argsort(-damage, kind="stable")[:10]
    ax2.barh(range(len(top)), damage[top], color=[colour(d) for d in damage[top]])
    ax2.set_yticks(range(len(top)), [channels[i] for i in top], fontsize=8)
    ax2.invert_yaxis()
    ax2.set_xlabel(f"{quantity} over the record (linear: the bars compare as the values do)")
    ax2.set_title(f"the ten outputs of the largest {quantity}", fontsize=9)
    fig.suptitle(title, fontsize=10)
    save_figure(fig, path)
    return fig


def plot_events(structure, frame, path, title):
    """The located impacts on the structure (``akf locate`` over many records): a disc per event at
    its node, sized by the peak force and numbered in the order of events.csv; writes ``path``."""
    from core_akf.figures import plot_structure, save_figure

    fig = plot_structure(structure, numbers=structure.n_nodes <= 60)
    ax = fig.axes[0]
    ok = frame[frame["node"].notna()]
    peaks = np.abs(ok["peak_force_N"].to_numpy(float))
    sizes = 60 + 340 * peaks / max(peaks.max(), 1e-300)
    xy = structure.nodes[structure.node_rows(ok["node"].astype(int).to_numpy())][:, :2]
    # the discs under the numbers (text is drawn at zorder 3): a located node stays readable
    sc = ax.scatter(xy[:, 0], xy[:, 1], s=sizes, c=ok["confidence"].to_numpy(float), cmap="viridis", vmin=0, vmax=1,
                    alpha=0.55, edgecolors="k", zorder=2.5)
    for k, (x, y), p in zip(ok.index, xy, peaks):
        ax.annotate(f"#{k + 1}: {p / 1e3:.3g} kN", (x, y), textcoords="offset points", xytext=(8, -12), fontsize=8,
                    fontweight="bold", color="darkred", zorder=6)
    fig.colorbar(sc, ax=ax, label="confidence (share of role splits)", orientation="horizontal", shrink=0.4, pad=0.2)
    ax.set_title(f"{title}: {len(ok)} of {len(frame)} impacts located (disc size: peak force, "
                 f"largest {peaks.max() / 1e3:.3g} kN)", fontsize=9)
    return save_figure(fig, path)


def draw(files, key, notes, plot, *args, **kw):
    """Draw a figure after the results are written, never at their cost.

    Calls ``plot(*args, **kw)``, a plot function that writes its figure to the ``.png`` path among
    ``args``; on success records that path as ``files[key]`` and returns it.  A figure that fails
    (a model the drawing does not know, a font, the disk) is a note in ``notes`` naming the figure
    and the error, and the return value is ``None``: the results already written stay the run's
    result.
    """
    path = next(a for a in args if isinstance(a, str) and a.endswith(".png"))
    try:
        plot(*args, **kw)
    except Exception as exc:  # noqa: BLE001 -- any failure of a figure is only a warning
        log.debug("figure %s failed", path, exc_info=True)
        notes.append(f"figure {os.path.basename(path)} not drawn ({type(exc).__name__}: {exc}); the result files "
                     "are complete")
        return None
    files[key] = path
    return path
