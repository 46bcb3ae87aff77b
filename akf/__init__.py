"""The akf application layer: job files (one schema for estimate, place and locate), the
built-in paper cases, the ``akf`` command and its sub-commands, writers and the paper studies.

It sits on top of the libraries and is imported by none of them::

    core_akf  <-  sensoropt, impactloc  <-  akf
"""
from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("akf-toolkit")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0+unknown"
