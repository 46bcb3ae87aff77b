"""Sphinx configuration of the akf-toolkit documentation (``sphinx-build -W -b html docs docs/_build/html``).

The job-file reference, the JSON Schema and the gallery figures are generated at build time from
the code (``_generate.py``), so they cannot fall behind it.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(__file__))

project = "akf-toolkit"
author = "the akf-toolkit developers"
copyright = "2026, the akf-toolkit developers"
try:
    from importlib.metadata import version as _version

    release = _version("akf-toolkit")
except Exception:  # noqa: BLE001 -- building from a tree that is not installed
    release = "0+unknown"

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.mathjax", "numpydoc"]
myst_enable_extensions = ["dollarmath", "amsmath"]
myst_heading_anchors = 3
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build"]
html_theme = "alabaster"
html_static_path = []
autodoc_member_order = "bysource"
autodoc_default_options = {"members": True, "undoc-members": False}
numpydoc_show_class_members = False
#: numpydoc validation of the library's API (core_akf, sensoropt, impactloc; the app akf is left
#: out): every parameter documented, none documented that does not exist (an override without a
#: docstring of its own inherits one).  tests/test_docstrings.py checks the same on every public
#: callable, also those without a page, and that every one has a docstring.
numpydoc_validation_checks = {"PR01", "PR02"}
#: a result dataclass documents its fields as Attributes (no Parameters section): its constructor
#: is not for users, so PR01 does not apply
numpydoc_validation_overrides = {"PR01": [r"(?s)\A(?!.*\nParameters\n-+\n).*\nAttributes\n-+\n"]}


def _foreign_names():
    """Regexes of the names autodoc meets in a module of the library that are not defined there
    (``dataclass``, ``abstractmethod``, a function of another module imported under its name) or
    are another name of one of its objects (an old name kept for compatibility): they are
    validated where they are defined, or not at all."""
    import importlib
    import pkgutil
    import re

    out = {r"^akf\.", r"\.Algorithm\.individual$"}
    for package in ("core_akf", "sensoropt", "impactloc"):
        top = importlib.import_module(package)
        for module in [top] + [importlib.import_module(i.name) for i in pkgutil.walk_packages(top.__path__, package + ".")]:
            for name, obj in vars(module).items():
                home = getattr(obj, "__module__", None) or ""
                alias = callable(obj) and getattr(obj, "__name__", name) != name     # documented under its own name
                if alias or home != module.__name__:          # validated in its own module
                    out.add(rf"^{re.escape(module.__name__)}\.{re.escape(name)}$")
    return out


numpydoc_validation_exclude = _foreign_names()
numpydoc_xref_param_type = False
suppress_warnings = ["myst.header"]


def setup(app):
    from _generate import generate

    app.connect("builder-inited", lambda app: generate(os.path.join(app.srcdir, "_generated")))
