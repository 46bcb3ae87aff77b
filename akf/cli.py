"""The ``akf`` command.  Sub-commands are plugins: every entry point of the group
``akf.commands`` names a function ``register(subparsers)`` that adds one sub-command (with
``set_defaults(func=...)``); this distribution registers ``estimate``, ``place``, ``locate``,
``study`` and ``show`` in its ``pyproject.toml``, and another installed package can add its own.

Exit codes: 0 done, 2 bad input, 3 undetectable sensor set, 4 the dask cluster lost the work,
130 interrupted.
"""
from __future__ import annotations

import argparse
import os
import sys
from importlib.metadata import entry_points

from core_akf.exceptions import AKFInputError, UndetectableError

from . import __version__
from .parallel import ClusterError

#: the entry-point group sub-commands register in
COMMAND_GROUP = "akf.commands"


def command_plugins():
    """The installed sub-command plugins: ``{name: entry point}``, sorted by name."""
    return {ep.name: ep for ep in sorted(entry_points(group=COMMAND_GROUP), key=lambda ep: ep.name)}


def build_parser():
    """The ``akf`` argument parser with every installed sub-command."""
    parser = argparse.ArgumentParser(prog="akf", description="Model-based structural monitoring with an "
                                     "augmented Kalman filter.")
    parser.add_argument("--version", action="version", version=f"akf-toolkit {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    plugins = command_plugins()
    if not plugins:
        raise SystemExit("akf: no sub-commands are installed (the package metadata is missing): "
                         "reinstall with `python -m pip install .`")
    for name, ep in plugins.items():
        try:
            register = ep.load()
        except Exception as exc:  # noqa: BLE001 -- a broken third-party plugin must not break akf
            print(f"akf: warning: the sub-command {name!r} ({ep.value}) could not be loaded: {exc}", file=sys.stderr)
            continue
        register(sub)
    return parser


def main(argv=None):
    """Run ``akf`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except UndetectableError as exc:
        print(f"akf: error: {exc}", file=sys.stderr)
        return 3
    except AKFInputError as exc:
        print(f"akf: error: {exc}", file=sys.stderr)
        return 2
    except ClusterError as exc:
        print(f"akf: error: {exc}", file=sys.stderr)
        return 4
    except BrokenPipeError:       # `akf ... | head`: the reader has gone; not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:        # an unreadable input or an output that cannot be written
        where = f" ({exc.filename})" if getattr(exc, "filename", None) else ""
        print(f"akf: error: {exc.strerror or exc}{where}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("akf: interrupted; files already written are complete, the others were not written", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
