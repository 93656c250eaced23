"""Evaluate a controller on the LAS-MP benchmark: `python evaluate.py --help`."""

import sys

if __name__ == "__main__":
    try:
        from lasmp.eval.cli import main  # torch and the physics: seconds, in which Ctrl-C is likely

        code = main()
    except KeyboardInterrupt:  # before main() claimed anything (main reports its own)
        print("interrupted: nothing written", file=sys.stderr)
        code = 130
    sys.exit(code)
