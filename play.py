"""Play a trained LAS-MP policy: `python play.py --checkpoint PATH [--video out.mp4] [--export onnx --out DIR]`.

`python play.py --help` lists the options; the logic lives in lasmp/cli/play.py.
"""

import sys

if __name__ == "__main__":
    from lasmp.io.ctrl_c import quiet_ctrl_c

    quiet_ctrl_c()  # before torch and MuJoCo load: a Ctrl-C then says one line
    from lasmp.cli.preflight import exit_unless_mujoco_imports

    exit_unless_mujoco_imports()  # a bad MUJOCO_GL: one line, not the traceback of the import below
    from lasmp.cli.play import main

    sys.exit(main(sys.argv[1:]))
