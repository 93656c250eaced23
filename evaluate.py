"""Evaluate a controller on the LAS-MP benchmark: `python evaluate.py --help`."""

import sys

if __name__ == "__main__":
    from lasmp.io.ctrl_c import quiet_ctrl_c

    quiet_ctrl_c()  # before torch and the physics load: a Ctrl-C then says one line (main reports its own)
    from lasmp.cli.preflight import exit_unless_mujoco_imports

    exit_unless_mujoco_imports()  # a bad MUJOCO_GL: one line, not the traceback of the import below
    from lasmp.eval.cli import main

    sys.exit(main())
