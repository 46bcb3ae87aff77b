"""``akf study NAME``: reproduce a paper's cases (table, CSV and figures)."""
from __future__ import annotations

import os

from ..outputs import OutputFolder
from ..parallel import add_scheduler_option, scheduler
from .common import seed, worker_count


def _study(args):
    from ..studies import STUDIES, run_study, study_module

    if args.list or args.name is None:
        width = max(len(n) for n in STUDIES)
        for name in STUDIES:
            try:
                desc = study_module(name).DESCRIPTION
            except ImportError as exc:  # a study of an optional package that is not installed
                desc = f"(unavailable: {exc})"
            print(f"{name:{width}s} {desc}")
        return 0
    study_module(args.name)                          # an unknown name fails before a folder is made
    out = args.out or os.path.join("akf-out", "studies", args.name)
    with OutputFolder(out, "--out"), scheduler(args.scheduler, resume="run the same command again (seeded: it repeats exactly)"):
        n_jobs = args.n_jobs if args.n_jobs is not None else (-1 if args.scheduler else None)
        result = run_study(args.name, out=out, quick=args.quick, seed=args.seed, n_jobs=n_jobs)
    for key, path in result.files.items():
        if key in ("table", "summary"):
            print(f"  wrote {key}: {path}")
    n_png = sum(1 for p in result.files.values() if str(p).endswith(".png"))
    if n_png:
        print(f"  wrote {n_png} figure(s) to {os.path.dirname(result.files['table'])}")
    return 0


def register(sub):
    """Add ``study`` to the ``akf`` sub-command parser."""
    p = sub.add_parser("study", help="reproduce a paper's cases: table, CSV and figures")
    p.add_argument("name", nargs="?", help="study name (see --list)")
    p.add_argument("--list", action="store_true", help="list the studies")
    p.add_argument("--quick", action="store_true", help="short records (under a minute)")
    p.add_argument("--out", help="output folder (default akf-out/studies/NAME)")
    p.add_argument("--seed", type=seed, default=0, help="noise seed")
    p.add_argument("--n-jobs", type=worker_count, help="joblib workers of the placement and impact studies (default: the "
                   "study's; every worker with --scheduler)")
    add_scheduler_option(p)
    p.set_defaults(func=_study)
