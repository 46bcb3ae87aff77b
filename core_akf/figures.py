"""Figure helpers shared by the CLI, the studies and the optimisers (matplotlib, no display)."""
from __future__ import annotations

import os


def pyplot():
    """``matplotlib.pyplot`` with the non-interactive Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path, dpi=110):
    """Lay out, write (creating the folder) and close ``fig``; returns ``path``."""
    import matplotlib.pyplot as plt

    from .outputs import atomic_path

    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    try:
        with atomic_path(path) as tmp:          # complete or absent, also on Ctrl-C
            fig.savefig(tmp, dpi=dpi, format=os.path.splitext(path)[1].lstrip(".") or "png")
    finally:
        plt.close(fig)
    return path
