"""The one error boundary of the commands (train.py, play.py, evaluate.py): the failures a user can
meet end a command in one line, `error: <message>`, and an exit code, with no traceback; anything
else is a bug and keeps its traceback.

A command states which exceptions are whose fault in a table (`ErrorTable`: exception types, first
match wins) and runs its work through `run`; the table, not a chain of `except` blocks, is the
command's error policy. Where a type is bad input in one phase of the work only (an OSError while
the outputs are checked, not while they are written), that phase says so (`bad_input_from`). The
exit codes every command shares:
- 2, bad input: a checkpoint, config, trajectory file, run directory or output that cannot be used,
  said before any long work starts;
- 1, the work cannot go on: a write that failed, a training whose physics or numbers broke down;
- 128 + the signal: stopped by Ctrl-C or SIGTERM after saying where it stopped (the table's
  `stopped` types, which carry the signal as `signum`);
- 130: a Ctrl-C that the work did not handle itself (torch or the envs still loading, a rollout).
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

BAD_INPUT = 2
CANNOT_GO_ON = 1
INTERRUPTED = 130  # 128 + SIGINT


class BadInput(Exception):
    """An input refused in one phase of a command's work (`bad_input_from`): bad input (exit 2)
    whatever the table says; str() is the message said."""


@contextmanager
def bad_input_from(*types: type[Exception], prefix: str = "") -> Iterator[None]:
    """Within the block, an exception of `types` is bad input: re-raised as BadInput, its message
    after `prefix` (`--export: `), its cause chained. For a type that is bad input in this phase of
    the work and not in others: an OSError while the outputs are checked (a file there without
    --force) is the user's, one while they are written (a full disk) is not."""
    try:
        yield
    except BadInput:
        raise
    except types as err:
        raise BadInput(f"{prefix}{err}") from err


@dataclass(frozen=True)
class ErrorTable:
    """Which exceptions end a command in one line, and with which exit code: `bad_input` (2; and
    BadInput always) and `cannot_go_on` (1); the first row that matches an exception wins, bad input
    first. `stopped`: a stop on a signal the work has already said (exit 128 + its `signum`).
    `interrupted`: what a Ctrl-C that the work did not handle says: a text, or a function that says
    it when the Ctrl-C comes (what the work had written by then)."""

    bad_input: tuple[type[BaseException], ...]
    cannot_go_on: tuple[type[BaseException], ...] = ()
    stopped: tuple[type[BaseException], ...] = ()
    interrupted: str | Callable[[], str] = "interrupted: nothing saved"

    def exit_code(self, err: BaseException) -> int | None:
        """The exit code that `err` ends the command with, or None: not a failure a user can meet."""
        for types, code in ((self.bad_input + (BadInput,), BAD_INPUT), (self.cannot_go_on, CANNOT_GO_ON)):
            if isinstance(err, types):
                return code
        return None

    def interrupted_text(self) -> str:
        return self.interrupted() if callable(self.interrupted) else self.interrupted


def run(work: Callable[[], int | None], table: ErrorTable, on_exit: Callable[[], None] | None = None) -> int:
    """`work()`'s exit code (None: 0), or the one its failure ends the command with, said in one
    line on stderr as `table` says; `on_exit` runs however the work ends, and its own failure never
    replaces the error said."""
    try:
        return work() or 0
    except table.stopped as stop:
        return 128 + stop.signum
    except KeyboardInterrupt:
        print(table.interrupted_text(), file=sys.stderr)
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
