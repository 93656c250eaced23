"""A Ctrl-C that no command handles (most often while it is still loading torch, MuJoCo and Hydra,
seconds in which a user changes their mind) ends it with one line instead of the traceback of
whichever module was importing. Every write of lasmp is atomic, so nothing is left half-written.

Installed by the command-line entry points only, before their first heavy import: train.py, play.py,
evaluate.py, and `python -m lasmp.<tool>` (by lasmp/__init__.py, which runs first). A program that
imports lasmp keeps Python's own handling. The exit status stays Python's for an interrupt (the
process ends by SIGINT: 130 in a shell)."""

from __future__ import annotations

import sys

MESSAGE = "interrupted: stopped (no file is left half-written)"


def quiet_ctrl_c() -> None:
    """Report an uncaught KeyboardInterrupt in one line; any other exception goes to the hook before."""
    previous = sys.excepthook

    def on_uncaught(kind, value, tb) -> None:
        if issubclass(kind, KeyboardInterrupt):
            print(f"\n{MESSAGE}", file=sys.stderr, flush=True)
        else:
            previous(kind, value, tb)

    sys.excepthook = on_uncaught
