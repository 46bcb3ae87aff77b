"""Paper reproductions behind ``akf study NAME``: each study runs the paper's cases, prints a
table, and writes a tidy CSV plus PNG figures (see ``studies/README.md`` for the side-by-side
comparison with the published numbers).

A study is a module (or an object) with ``NAME``, ``DESCRIPTION`` and
``run(out=None, quick=False, seed=0)`` returning a :class:`StudyResult`.  The registry maps study
names to import paths (``"package.module"`` or ``"package.module:attribute"``), so the placement
and impact studies (in ``sensoropt`` / ``impactloc``) are only imported when run.
"""
from __future__ import annotations

import importlib

from core_akf.checks import AKFInputError

from ._common import StudyResult  # noqa: F401

#: study name -> module path
STUDIES = {
    "s17_truss": "akf.studies.s17_truss",
    "th_plate": "akf.studies.th_plate",
    "th_placement": "akf.studies.th_placement",
    "imp_cases": "akf.studies.imp:cases",
    "imp_hit_rate": "akf.studies.imp:hit_rate",
    "learning": "akf.studies.learning",
    "accelerations": "akf.studies.accelerations",
}


def study_module(name):
    """The module of study ``name`` (raises AKFInputError for an unknown name)."""
    if name not in STUDIES:
        raise AKFInputError(f"unknown study {name!r}; available: {', '.join(sorted(STUDIES))}")
    path, _, attr = STUDIES[name].partition(":")
    module = importlib.import_module(path)
    return getattr(module, attr) if attr else module


def run_study(name, out=None, quick=False, seed=0, n_jobs=None):
    """Run study ``name``; ``quick`` uses short records (under a minute), ``out`` the output
    folder (default ``akf-out/studies/NAME``), ``n_jobs`` the joblib workers of a study that
    spreads work (None: the study's default)."""
    import inspect

    study = study_module(name)
    kw = {}
    if n_jobs is not None and "n_jobs" in inspect.signature(study.run).parameters:
        kw["n_jobs"] = n_jobs
    return study.run(out=out, quick=quick, seed=seed, **kw)
