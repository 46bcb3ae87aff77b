"""Reproduce the s17_truss study: `python studies/s17_truss.py [--quick] [--out DIR]` (same as `akf study s17_truss`)."""
import sys

from akf.cli import main

if __name__ == "__main__":
    sys.exit(main(["study", "s17_truss", *sys.argv[1:]]))
