"""Reproduce the th_plate study: `python studies/th_plate.py [--quick] [--out DIR]` (same as `akf study th_plate`)."""
import sys

from akf.cli import main

if __name__ == "__main__":
    sys.exit(main(["study", "th_plate", *sys.argv[1:]]))
