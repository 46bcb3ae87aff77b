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
numpydoc_validation_checks = set()
numpydoc_xref_param_type = False
suppress_warnings = ["myst.header"]


def setup(app):
    from _generate import generate

    app.connect("builder-inited", lambda app: generate(os.path.join(app.srcdir, "_generated")))
