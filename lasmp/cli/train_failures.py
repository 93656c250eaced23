"""A training's failures worded for its user: a rank of a torchrun job that lost the others
(`RankLost`, with the command that resumes the run), a write error that names its file (`named`), and
TensorBoard's writer thread kept quiet when its error is said by the main thread."""

from __future__ import annotations

import contextlib
import os
import threading
from pathlib import Path

from lasmp.algo.runner import LasmpRunner
from lasmp.cli.command_line import resume_command
from lasmp.compat.rsl_rl import raised_storing_code_state
from lasmp.compat.tensorboard import events_file, is_writer_thread, raised_in_tensorboard, writer_thread_error
from lasmp.io.atomic import AtomicWriteError
from lasmp.io.rundir import run_checkpoints


class RankLost(RuntimeError):
    """A rank of a torchrun job lost the others (one was killed, ran out of memory or crashed): the
    message says so, names the run's newest checkpoint and the command that resumes from it."""

    def __init__(self, rank: int, world_size: int, log_dir: Path, last: int, iteration: int):
        saved = run_checkpoints(log_dir, full_only=True) if log_dir.is_dir() else {}
        head = (
            f"rank {rank} of the torchrun job lost the connection to the other processes (one of them ended: "
            "killed, out of memory or crashed, see its own output); this one stops too"
        )
        if saved:
            n, newest = next(reversed(saved.items()))
            command = resume_command(str(newest), str(log_dir), last - n).replace(
                "python train.py", f"torchrun --nproc_per_node={world_size} train.py", 1
            )
            tail = f". The newest checkpoint is {newest} (iteration {n}); resume with:\n  {command}"
        else:
            tail = f". No checkpoint was saved in {log_dir} (iteration {iteration} was under way): start the run anew"
        super().__init__(head + tail)


def named(err: OSError, runner: LasmpRunner, log_dir: Path) -> OSError:
    """A write error of training as one that names its file. The saves name theirs
    (`AtomicWriteError`); rsl_rl's git diff and TensorBoard's events file raise a bare OSError,
    without a file name, from their writes, or (TensorBoard reopens its events file for each append)
    one that names the events file in bytes."""
    writer = runner.logger.writer
    events = events_file(writer)
    if err.filename is not None:
        named_events = events is not None and os.fsdecode(err.filename) == os.fsdecode(events)
        return AtomicWriteError(Path(os.fsdecode(events)), err) if named_events else err
    if raised_storing_code_state(err):
        where = log_dir / "git"  # rsl_rl's record of the code's state: git/<repository>.diff
    elif events is not None and (err is writer_thread_error(writer) or raised_in_tensorboard(err)):
        where = Path(events)
    else:
        where = log_dir
    return AtomicWriteError(where, err)


@contextlib.contextmanager
def quiet_writer_threads():
    """TensorBoard writes its events file from a thread; on a full or read-only disk that thread dies
    printing a traceback, and the main thread raises the same error at its next write, where train()
    names the file (`_named`). Its traceback is left out; any other thread's is printed as usual."""
    previous = threading.excepthook

    def hook(args):
        if not (issubclass(args.exc_type, OSError) and is_writer_thread(args.thread)):
            previous(args)

    threading.excepthook = hook
    try:
        yield
    finally:
        threading.excepthook = previous
