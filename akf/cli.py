"""The ``akf`` command.  Sub-commands are plugins: every entry point of the group
``akf.commands`` names a function ``register(subparsers)`` that adds one sub-command (with
``set_defaults(func=...)``); this distribution registers ``estimate``, ``place``, ``locate``,
``study`` and ``show`` in its ``pyproject.toml``, and another installed package can add its own.

Exit codes: 0 done, 1 an internal error (a fault of akf: one line, the traceback with -v), 2 bad
input, 3 undetectable sensor set, 4 the dask cluster lost the work, 130 interrupted.
"""
from __future__ import annotations

import argparse
import logging
import os
import sys
import traceback
import warnings
from importlib.metadata import entry_points

from core_akf.checks import AKFInputError, UndetectableError
from core_akf.tasks import WorkerLostError

from . import __version__
from .parallel import ClusterError

#: the entry-point group sub-commands register in
COMMAND_GROUP = "akf.commands"


def command_plugins():
    """The installed sub-command plugins: ``{name: entry point}``, sorted by name."""
    return {ep.name: ep for ep in sorted(entry_points(group=COMMAND_GROUP), key=lambda ep: ep.name)}


#: how the library's messages (which name arguments) read on the command line: phrase -> CLI words
CLI_WORDING = (
    ("use steady=False to run", "use --filter time-varying (steady = false in [filter]) to run"),
    ("pass resume=True to continue it, or remove the file to start afresh",
     "run again with --resume to continue it, or with --overwrite to start afresh"),
    ("pass allow_undetectable=True", "pass --allow-undetectable"),
    ("start anew with resume=False and the file removed", "start anew with --overwrite"),
    ("with fewer workers (n_jobs), or n_jobs=1 to run in this process", "with a smaller --n-jobs, or without it"),
    ("give its gauge_factor (and bridge:", "give its gauge_factor in [measurements] (and bridge:"),
    ("microstrain: set units={", "microstrain: set in [measurements] units = {"),
)


def cli_wording(message):
    """A library message in the words of the command line (:data:`CLI_WORDING`): the core names
    its arguments (``steady=False``), the command line its flags and job keys."""
    for phrase, words in CLI_WORDING:
        message = message.replace(phrase, words)
    return message


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
    for p in [parser, *sub.choices.values()]:        # before or after the sub-command: akf -q estimate, akf estimate -q
        _add_verbosity(p, top=p is parser)
    return parser


def _add_verbosity(p, top):
    default = None if not top else 0      # a sub-command's own flag only overrides when given
    group = p.add_mutually_exclusive_group()
    try:
        group.add_argument("-v", "--verbose", dest="verbosity" if top else "sub_verbosity", action="store_const",
                           const=1, default=default, help="more detail: debug messages (figure errors in full, ...)")
        group.add_argument("-q", "--quiet", dest="verbosity" if top else "sub_verbosity", action="store_const",
                           const=-1, default=default, help="results and warnings only: no progress bars or notes")
    except argparse.ArgumentError:        # a plugin that has its own -v or -q keeps it
        pass


#: whether --quiet set TQDM_DISABLE (and a later run of this process may take it back)
_TQDM_SWITCHED_OFF = False


class _Handler(logging.StreamHandler):
    """The ``akf`` logger's messages on the current ``sys.stdout`` (warnings on ``sys.stderr``)."""

    def emit(self, record):
        self.stream = sys.stderr if record.levelno >= logging.WARNING else sys.stdout
        super().emit(record)


def configure_logging(verbosity=0):
    """Show the ``akf`` logger's messages on the terminal: INFO and up (``verbosity`` 0), WARNING
    and up (-1, ``--quiet``: progress bars off as well), DEBUG and up (1, ``--verbose``).  Used
    as a library, nothing is configured: the messages go where the caller's logging sends them."""
    logger = logging.getLogger("akf")
    for h in [h for h in logger.handlers if isinstance(h, _Handler)]:
        logger.removeHandler(h)
    handler = _Handler()
    handler.setFormatter(logging.Formatter("%(message)s"))
    logger.addHandler(handler)
    logger.setLevel({-1: logging.WARNING, 0: logging.INFO, 1: logging.DEBUG}[verbosity])
    logger.propagate = False
    global _TQDM_SWITCHED_OFF
    if verbosity < 0 and os.environ.get("TQDM_DISABLE") != "1":
        os.environ["TQDM_DISABLE"] = "1"          # tqdm's own switch: every progress bar off
        _TQDM_SWITCHED_OFF = True
    elif verbosity >= 0 and _TQDM_SWITCHED_OFF:
        os.environ.pop("TQDM_DISABLE", None)      # a later run in the same process that is not quiet
        _TQDM_SWITCHED_OFF = False


#: the packages whose warnings are the toolkit's own words
OWN_PACKAGES = ("akf", "core_akf", "sensoropt", "impactloc")


def show_warning(message, category, filename, lineno, file=None, line=None):
    """A Python warning as one line in the user's words, ``akf: warning: ...``: no file path and
    no source line; one from another library names its kind and where it came from."""
    source = os.path.splitext(os.path.basename(filename or ""))[0]
    own = category.__module__.split(".")[0] in OWN_PACKAGES or any(
        f"{os.sep}{p}{os.sep}" in (filename or "") for p in OWN_PACKAGES)
    text = cli_wording(str(message)) if own else f"{category.__name__} from {source}: {message}"
    print(f"akf: warning: {text}", file=sys.stderr if file is None else file)


def main(argv=None):
    """Run ``akf`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    args = build_parser().parse_args(argv)
    verbosity = getattr(args, "sub_verbosity", None)
    configure_logging(verbosity if verbosity is not None else (args.verbosity or 0))
    with warnings.catch_warnings():
        warnings.showwarning = show_warning
        return _run(args)


def _run(args):
    """``args.func(args)``, every error an exit code and one line on stderr."""
    try:
        return args.func(args)
    except UndetectableError as exc:
        print(f"akf: error: {cli_wording(str(exc))}", file=sys.stderr)
        return 3
    except AKFInputError as exc:
        print(f"akf: error: {cli_wording(str(exc))}", file=sys.stderr)
        return 2
    except (ClusterError, WorkerLostError) as exc:
        print(f"akf: error: {cli_wording(str(exc))}", file=sys.stderr)
        return 4
    except BrokenPipeError:       # `akf ... | head`: the reader has gone; not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:        # an unreadable input or an output that cannot be written
        where = f" ({exc.filename})" if getattr(exc, "filename", None) else ""
        print(f"akf: error: {exc.strerror or exc}{where}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        from .outputs import Interrupted

        text = str(exc) if isinstance(exc, Interrupted) else "interrupted; files already written are complete, the others were not written"
        print(f"akf: {text}", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 -- a bug of ours: one clear line, the traceback with -v
        if logging.getLogger("akf").isEnabledFor(logging.DEBUG):
            traceback.print_exc()
        where = "" if exc.__traceback__ is None else f" in {traceback.extract_tb(exc.__traceback__)[-1].name}"
        print(f"akf: internal error{where}: {type(exc).__name__}: {exc}\n  the input was not refused with a message, "
              "so this is a fault of akf: please report it with the command and its input (run again with -v for "
              "the traceback)", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
