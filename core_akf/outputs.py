"""Output folders that cannot be corrupted: a lock per folder and atomic file writes.

A run takes :class:`OutputFolder` on its folder: the folder is created (a clear error if the
path is a file or not writable) and locked, so a second run into the same folder refuses instead
of interleaving its files with the first.  Every file is written to a temporary name in the same
folder and renamed into place (:func:`atomic_path`), so a result file is either complete or
absent -- also when the run is interrupted (Ctrl-C) or killed.
"""
from __future__ import annotations

import contextlib
import os
import socket
import tempfile
import time

from .exceptions import AKFInputError

LOCK_NAME = ".akf-run.lock"
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
    """``path``, after checking that no symbolic link inside an output folder in use
    (:class:`OutputFolder`) leads it outside that folder: a write or a delete through such a link
    would change a file elsewhere.  Paths outside every folder in use are returned unchecked."""
    absolute = os.path.abspath(path)
    for root, real_root in _ACTIVE:
        if absolute != root and not absolute.startswith(root + os.sep):
            continue
        real = os.path.realpath(absolute)
        if real != real_root and not real.startswith(real_root + os.sep):
            raise AKFInputError(f"{path} leads outside the output folder {root} (through a symbolic link to {real}); "
                                "remove the link or write to another folder")
    return path


def _pid_alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:      # exists, owned by someone else
        return True
    except OSError:
        return False
    return True


class OutputFolder:
    """Create and lock an output folder for one run (a context manager).

    Parameters
    ----------
    path : str -- the folder; created with its parents if missing
    what : str -- how the user named it in messages (e.g. ``"--out"``)
    """

    def __init__(self, path, what="output folder"):
        self.path = os.path.abspath(path)
        self.what = what
        self._lock = os.path.join(self.path, LOCK_NAME)
        self._held = False

    def __enter__(self):
        if os.path.exists(self.path) and not os.path.isdir(self.path):
            raise AKFInputError(f"{self.what} {self.path!r} is a file, not a folder; give a folder path")
        try:
            os.makedirs(self.path, exist_ok=True)
        except OSError as exc:
            raise AKFInputError(f"cannot create {self.what} {self.path!r}: {exc.strerror or exc}") from None
        if not os.access(self.path, os.W_OK | os.X_OK):
            raise AKFInputError(f"{self.what} {self.path!r} is not writable; choose another folder")
        for _ in range(2):
            try:
                fd = os.open(self._lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                if self._stale():
                    with contextlib.suppress(FileNotFoundError):
                        os.remove(self._lock)
                    continue
                raise AKFInputError(
                    f"{self.what} {self.path!r} is in use by another akf run ({self._owner()}); wait for it to "
                    f"finish or write to another folder (if no run is active, delete {self._lock})") from None
            except OSError as exc:
                raise AKFInputError(f"cannot write into {self.what} {self.path!r}: {exc.strerror or exc}") from None
            with os.fdopen(fd, "w") as fh:
                fh.write(f"{os.getpid()} {socket.gethostname()} {time.strftime('%Y-%m-%d %H:%M:%S')}\n")
            self._held = True
            _ACTIVE.append((self.path, os.path.realpath(self.path)))
            return self
        raise AKFInputError(f"cannot lock {self.what} {self.path!r}")

    def _read_lock(self):
        try:
            with open(self._lock) as fh:
                parts = fh.read().split()
            return int(parts[0]), parts[1], " ".join(parts[2:])
        except (OSError, ValueError, IndexError):
            return None

    def _stale(self):
        info = self._read_lock()
        if info is None:
            return False          # being written right now, or unreadable: treat as held
        pid, host, _ = info
        return host == socket.gethostname() and not _pid_alive(pid)

    def _owner(self):
        info = self._read_lock()
        return "unknown process" if info is None else f"pid {info[0]} on {info[1]}, started {info[2]}"

    def file(self, name):
        """Path of a file ``name`` inside the folder."""
        return os.path.join(self.path, name)

    def __exit__(self, *exc):
        if self._held:
            with contextlib.suppress(FileNotFoundError):
                os.remove(self._lock)
            self._held = False
            with contextlib.suppress(ValueError):
                _ACTIVE.remove((self.path, os.path.realpath(self.path)))
        return False


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path next to ``path``; on success rename it to ``path`` (atomic on one
    file system), on any error or interruption remove it, leaving ``path`` as it was.  The file
    gets the permissions of a plain ``open`` (0666 less the umask), not the 0600 of a temporary
    file; a path that a symbolic link leads out of the output folder in use is refused
    (:func:`confined`)."""
    confined(path)
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


def write_csv(frame, path, **kwargs):
    """Write a DataFrame to CSV atomically (``index=False`` unless given); returns ``path``."""
    kwargs.setdefault("index", False)
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, **kwargs)
    return path

