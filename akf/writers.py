"""Small writers shared by the commands and the studies."""
from __future__ import annotations

import logging
import os

log = logging.getLogger("akf")


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
