"""The one error boundary of the commands: the failures a user can meet end a command in one line,
`error: <message>`, and an exit code, with no traceback; anything else is a bug and keeps its traceback.

A command states which exceptions are whose fault in a table (`ErrorTable`: exception types, first
match wins) and runs its work through `run`; the table, not a chain of `except` blocks, is the
command's error policy. The exit codes every command shares:
- 2, bad input: a checkpoint, config, trajectory file or run directory that cannot be used, said
  before any long work starts;
- 1, the work cannot go on: a write that failed, a training whose physics or numbers broke down;
- 128 + the signal: stopped by Ctrl-C or SIGTERM after saying where it stopped (the table's
  `stopped` types, which carry the signal as `signum`);
- 130: Ctrl-C before the command's own handling started (torch or the envs still loading).
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass

BAD_INPUT = 2
CANNOT_GO_ON = 1
INTERRUPTED = 130  # 128 + SIGINT


@dataclass(frozen=True)
class ErrorTable:
    """Which exceptions end a command in one line, and with which exit code: `bad_input` (2) and
    `cannot_go_on` (1); the first row that matches an exception wins, bad input first. `stopped`: a
    stop on a signal the work has already said (exit 128 + its `signum`). `interrupted`: what a Ctrl-C
    that the work did not handle says."""

    bad_input: tuple[type[BaseException], ...]
    cannot_go_on: tuple[type[BaseException], ...] = ()
    stopped: tuple[type[BaseException], ...] = ()
    interrupted: str = "interrupted: nothing saved"

    def exit_code(self, err: BaseException) -> int | None:
        """The exit code that `err` ends the command with, or None: not a failure a user can meet."""
        for types, code in ((self.bad_input, BAD_INPUT), (self.cannot_go_on, CANNOT_GO_ON)):
            if isinstance(err, types):
                return code
        return None


def run(work: Callable[[], int | None], table: ErrorTable, on_exit: Callable[[], None] | None = None) -> int:
    """`work()`'s exit code (None: 0), or the one its failure ends the command with, said in one
    line on stderr as `table` says; `on_exit` runs however the work ends, and its own failure never
    replaces the error said."""
    try:
        return work() or 0
    except table.stopped as stop:
        return 128 + stop.signum
    except KeyboardInterrupt:
        print(table.interrupted, file=sys.stderr)
        return INTERRUPTED
    except Exception as err:
        code = table.exit_code(err)
        if code is None:
            raise
        print(f"error: {err}", file=sys.stderr)
        return code
    finally:
        if on_exit is not None:
            try:
                on_exit()
            except Exception:  # after a failure: never replace the error said above
                pass
