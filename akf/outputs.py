"""The run lock on an output folder: a run takes :class:`OutputFolder` on its folder, which is
created (a clear error if the path is a file or not writable) and locked, so that a second run into
the same folder refuses instead of interleaving its files with the first.  While it is held, no
file is written or deleted through a symbolic link that leads out of the folder
(:func:`core_akf.outputs.confine_writes`)."""
from __future__ import annotations

import contextlib
import os
import socket
import time

from core_akf.checks import AKFInputError
from core_akf.outputs import confine_writes

LOCK_NAME = ".akf-run.lock"


class Interrupted(KeyboardInterrupt):
    """Ctrl-C during a run that keeps partial files for ``--resume``: the message says which."""


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
            self._confined = confine_writes(self.path)
            self._confined.__enter__()
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
            self._confined.__exit__(None, None, None)
        return False
