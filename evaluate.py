"""Evaluate a controller on the LAS-MP benchmark: `python evaluate.py --help`."""

import sys

if __name__ == "__main__":
    from lasmp.ctrl_c import quiet_ctrl_c

    quiet_ctrl_c()  # before torch and the physics load: a Ctrl-C then says one line (main reports its own)
    from lasmp.eval.cli import main

    sys.exit(main())
