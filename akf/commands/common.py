"""Pieces every sub-command shares: listing its built-in examples, and one job file or one
example, not both."""
from __future__ import annotations

from core_akf.checks import AKFInputError


def print_examples(command):
    """Print the built-in examples of ``command`` with their descriptions."""
    from ..examples import example_names, load_example

    names = example_names(command)
    width = max(map(len, names)) + 2
    for name in names:
        print(f"{name:{width}s}{load_example(name)['description']}")


def print_written(files, notes=()):
    """The files a command wrote, then its notes (text output)."""
    for k, v in files.items():
        print(f"  wrote {k}: {v}")
    for note in notes:
        print(f"  note: {note}")


def finish(args, summary, files, figure_notes, notes=(), report=None):
    """A command's ending once its results are written: ``report.html`` with ``--report``
    (``report`` is ``(command, job, out)``; a report that fails is a warning), the figures'
    warnings, then the JSON ``summary`` (``--json``) or the files written with the notes; the
    exit code 0."""
    import json
    import sys

    if report is not None and getattr(args, "report", False):
        from ..report import write_report

        command, job, out = report
        warnings = list(figure_notes) + list(notes)
        path = write_report(out, command, job, summary, files, warnings, source=getattr(args, "job", None))
        figure_notes = list(figure_notes) + warnings[len(figure_notes) + len(notes):]
        if path is not None:
            files["report"] = path
    for note in figure_notes:
        print(f"akf: warning: {note}", file=sys.stderr)
    if args.json:
        summary["warnings"] = figure_notes
        print(json.dumps(summary))
        return 0
    print_written(files, notes)
    return 0


def check_job_or_example(args, kind="job file"):
    """Exactly one of ``args.job`` and ``args.example``; ``--n-jobs`` (if any) not 0."""
    if (args.job is None) == (args.example is None):
        raise AKFInputError(f"give a {kind} or --example NAME (see --list-examples)")
    if getattr(args, "n_jobs", 1) == 0:
        raise AKFInputError("--n-jobs must be a positive number of workers, or negative (-1: all cores), not 0")


def add_print_job(parser):
    """``--print-job`` for a sub-command with built-in examples."""
    parser.add_argument("--print-job", action="store_true", help="print the --example's job file (TOML, with its "
                        "comments) and exit: a template to start a job of your own from (> my_job.toml)")


def print_job(args, command=None):
    """Print the job file of ``args.example`` as it is written (an example of ``command``: one of
    another command is refused, naming it); returns the exit code."""
    from ..examples import example_path, load_example

    if not args.example:
        raise AKFInputError("--print-job prints a built-in example's job file: give --example NAME (see --list-examples)")
    if command is not None:
        load_example(args.example, command)          # refuses an example of another command, naming it
    with open(example_path(args.example), encoding="utf-8") as fh:
        print(fh.read(), end="")
    return 0


def seed(text):
    """An argparse type: a seed is a whole number >= 0 (numpy's generators take no other)."""
    import argparse

    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"a seed is a whole number >= 0, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"a seed is a whole number >= 0, got {value}")
    return value


def worker_count(text):
    """An argparse type: ``--n-jobs`` is a whole number of workers, -1 (and below) counting back from
    every core as joblib does; 0 is no number of workers.

    Parameters
    ----------
    text : str

    Returns
    -------
    int
    """
    import argparse

    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"a number of workers is a whole number (-1: all cores), got {text!r}") from None
    if value == 0:
        raise argparse.ArgumentTypeError("a number of workers is >= 1, or negative (-1: all cores), not 0")
    return value


def listing_or_template(args, command):
    """``--list-examples`` or ``--print-job`` of ``command``: print it and return the exit code 0;
    None when neither was asked for."""
    if args.list_examples:
        print_examples(command)
        return 0
    if args.print_job:
        return print_job(args, command)
    return None


def job_data(args, command, kind="job file"):
    """The job file or built-in example of ``args`` (exactly one of them) as read, a dict: the
    command checks it once, with its overrides (:meth:`akf.job.Job.from_dict`)."""
    from ..examples import load_example
    from ..job import load_job_file

    check_job_or_example(args, kind)
    return load_example(args.example, command) if args.example else load_job_file(args.job)
