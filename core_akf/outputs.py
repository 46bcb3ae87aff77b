"""Files that cannot be corrupted: every file is written to a temporary name in the same folder
and renamed into place (:func:`atomic_path`), so a result file is either complete or absent --
also when the run is interrupted (Ctrl-C) or killed -- with the permissions of the user's umask;
and, inside :func:`confine_writes`, never through a symbolic link that leads out of the folder.
(The application's run lock on an output folder is :class:`akf.outputs.OutputFolder`.)
"""
from __future__ import annotations

import contextlib
import os
import tempfile

from .checks import AKFInputError

#: the output folders in use by this process: (path as given, made absolute; its real path)
_ACTIVE: list = []


def _umask():
    """The process' file-creation mask: read from ``/proc`` where there is one (no change to the
    process, safe beside threads), else set and set back."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def confined(path):
    """A path, checked not to lead out of an output folder in use.

    No symbolic link inside an output folder in use (:func:`confine_writes`) may lead the path
    outside that folder: a write or a delete through such a link would change a file elsewhere.
    Paths outside every folder in use are returned unchecked.

    Parameters
    ----------
    path : str

    Returns
    -------
    str
        ``path``.

    Raises
    ------
    AKFInputError
        For a path that a link leads out of the folder.
    """
    absolute = os.path.abspath(path)
    for root, real_root in _ACTIVE:
        if absolute != root and not absolute.startswith(root + os.sep):
            continue
        real = os.path.realpath(absolute)
        if real != real_root and not real.startswith(real_root + os.sep):
            raise AKFInputError(f"{path} leads outside the output folder {root} (through a symbolic link to {real}); "
                                "remove the link or write to another folder")
    return path


@contextlib.contextmanager
def confine_writes(path):
    """Inside the ``with`` block, refuse writes through links that lead out of a folder.

    :func:`confined` (and so every :func:`atomic_path` write) refuses a path under the folder
    ``path`` that a symbolic link leads out of it.

    Parameters
    ----------
    path : str
        The output folder.

    Yields
    ------
    str
        The folder's absolute path.
    """
    entry = (os.path.abspath(path), os.path.realpath(path))
    _adopt(entry[0])
    _ACTIVE.append(entry)
    try:
        yield entry[0]
    finally:
        with contextlib.suppress(ValueError):
            _ACTIVE.remove(entry)


@contextlib.contextmanager
def atomic_path(path):
    """A temporary path that becomes ``path`` when the block ends without an error.

    On success it is renamed to ``path`` (atomic on one file system); on any error or
    interruption it is removed, leaving ``path`` as it was.  The file gets the permissions of a
    plain ``open`` (0666 less the umask), not the 0600 of a temporary file; a path that a
    symbolic link leads out of the output folder in use is refused (:func:`confined`).

    Parameters
    ----------
    path : str
        The file to write.

    Yields
    ------
    str
        The temporary path to write to.
    """
    confined(path)
    ours(path)
    folder = os.path.dirname(os.path.abspath(path)) or "."
    base, ext = os.path.splitext(os.path.basename(path))
    fd, tmp = tempfile.mkstemp(prefix=f".{base}.", suffix=f".tmp{ext}", dir=folder)
    os.close(fd)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.remove(tmp)
        raise
    _record(path)


#: the list of the files akf wrote into an output folder (one relative path per line)
MANIFEST = ".akf-files"


def _folder_of(path):
    """The output folder in use that holds ``path``, or None."""
    absolute = os.path.abspath(path)
    for root, _ in _ACTIVE:
        if absolute.startswith(root + os.sep):
            return root
    return None


def _written(root):
    """The relative paths listed in a folder's :data:`MANIFEST`."""
    try:
        with open(os.path.join(root, MANIFEST), encoding="utf-8") as fh:
            return set(fh.read().splitlines())
    except OSError:
        return set()


def _adopt(root):
    """A folder written by an earlier akf (no :data:`MANIFEST` yet, :func:`_earlier_run`) gets one
    that lists every file in it, when a run starts there: its outputs are akf's."""
    if not os.path.isdir(root) or os.path.exists(os.path.join(root, MANIFEST)) or not _earlier_run(root):
        return
    names = {os.path.relpath(os.path.join(d, f), root) for d, _, files in os.walk(root) for f in files}
    _write_manifest(root, names)


#: what marks a folder that an akf without :data:`MANIFEST` wrote: its checkpoints, its time series header
_EARLIER_MARKS = {".akf-resume.npz": None, "checkpoint.json": b'{"format": ["akf-toolkit GA checkpoint"',
                  "timeseries.csv": b"time,quantity,channel,unit,estimated"}


def _earlier_run(root):
    """Whether a folder without a :data:`MANIFEST` holds the output of an earlier akf: it lies under
    an ``akf-out`` folder (the default of every command) or holds one of :data:`_EARLIER_MARKS`."""
    if "akf-out" in os.path.abspath(root).split(os.sep):
        return True
    for name, head in _EARLIER_MARKS.items():
        try:
            with open(os.path.join(root, name), "rb") as fh:
                if head is None or fh.read(len(head)) == head:
                    return True
        except OSError:
            continue
    return False


def ours(path):
    """Refuse to replace or delete a file in an output folder in use that akf did not write there.

    A file of the user's own that happens to have an output's name (``summary.csv``, a
    ``--checkpoint`` path) is left as it is, also with ``--overwrite``.  Outside an output folder
    in use, and for a path that does not exist, nothing is checked.

    Parameters
    ----------
    path : str

    Returns
    -------
    str
        ``path``.

    Raises
    ------
    AKFInputError
        For an existing file that is not in the folder's list of what akf wrote (:data:`MANIFEST`).
    """
    root = _folder_of(path)
    if root is None or not os.path.lexists(path):
        return path
    written = _written(root)
    inside = [os.path.join(d, f) for d, _, files in os.walk(path) for f in files] if os.path.isdir(path) else [path]
    for p in inside:          # a folder (Parquet parts) is ours when every file in it is
        if os.path.relpath(os.path.abspath(p), root) not in written:
            raise AKFInputError(f"{p} exists and was not written there by akf (it is not in {MANIFEST}): it is left "
                                "as it is; move it away, or write to another folder")
    return path


def _record(path):
    """Add ``path`` to its output folder's :data:`MANIFEST` (written whole and renamed)."""
    root = _folder_of(path)
    if root is None:
        return
    names = _written(root)
    name = os.path.relpath(os.path.abspath(path), root)
    if name not in names:
        _write_manifest(root, names | {name})


def _write_manifest(root, names):
    fd, tmp = tempfile.mkstemp(prefix=f"{MANIFEST}.", suffix=".tmp", dir=root)
    with os.fdopen(fd, "w", encoding="utf-8") as fh:
        fh.write("".join(f"{n}\n" for n in sorted(names)))
    os.chmod(tmp, 0o666 & ~_umask())
    os.replace(tmp, os.path.join(root, MANIFEST))


def write_csv(frame, path, **kwargs):
    """Write a DataFrame to CSV atomically (:func:`atomic_path`).

    Parameters
    ----------
    frame : pandas.DataFrame
    path : str
        The CSV file.
    **kwargs
        Arguments of :meth:`pandas.DataFrame.to_csv` (``index=False`` unless given).

    Returns
    -------
    str
        ``path``.
    """
    kwargs.setdefault("index", False)
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, **kwargs)
    return path

