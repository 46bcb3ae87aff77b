"""Small writers shared by the commands and the studies."""
from __future__ import annotations


def saved_plot(plot, *args, **kw):
    """Call a plot function that writes its figure to the ``.png`` path among ``args`` and
    return that path (for a dictionary of written files)."""
    plot(*args, **kw)
    return next(a for a in args if isinstance(a, str) and a.endswith(".png"))
