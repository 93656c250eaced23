"""Evaluate a controller on the LAS-MP benchmark: `python evaluate.py --help`."""

import sys

from lasmp.eval.cli import main

if __name__ == "__main__":
    sys.exit(main())
