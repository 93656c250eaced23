"""lasmp: a quadruped keeping its balance on a moving platform (LAS-MP), on MuJoCo and rsl_rl."""

import os
import sys

# torch's OpenMP threads (libgomp) spin for a while after each parallel region before they sleep. In
# training the policy's forward pass runs right before the physics step, so spinning threads would take
# cores from MuJoCo's own worker threads (docs/performance.md#threads). A short spin still bridges the
# learner's back-to-back parallel regions. libgomp reads the variable when torch loads it, so it is set
# on importing lasmp (before torch); a value already set wins.
os.environ.setdefault("GOMP_SPINCOUNT", "10000")

# `python -m lasmp.<tool>`: while Python locates the tool's module, importing this package first,
# sys.argv[0] is "-m" (documented); a Ctrl-C while the tool loads then says one line (lasmp/io/ctrl_c.py)
if getattr(sys, "argv", [])[:1] == ["-m"]:
    from lasmp.io.ctrl_c import quiet_ctrl_c

    quiet_ctrl_c()
