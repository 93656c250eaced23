"""The one place lasmp reaches below TensorBoard's public API.

rsl_rl logs through torch's `SummaryWriter`, which writes TensorBoard's events file from a thread of
its own (TensorBoard's `EventFileWriter`). A write there that fails (a full or read-only disk) raises
a bare OSError, without the file's name, or one naming it in bytes; train.py names the file in its
one-line error (`lasmp.cli.train_failures.named`) and keeps the thread's own traceback off the terminal
(`lasmp.cli.train_failures.quiet_writer_threads`). Neither TensorBoard nor torch offers a public way to tell the
events file's path or the thread's error, so these read, and lasmp reads nowhere else
(`tests/test_compat.py` greps lasmp for them):

- the writer's `file_writer.event_writer` (torch's `FileWriter` and the `EventFileWriter` it holds;
  undocumented attributes) and the EventFileWriter's private `_file_name`: `events_file`;
- the EventFileWriter's private `_async_writer._worker` (the writer thread) and its `exception`:
  `writer_thread_error`;
- the writer thread's class, told by its module (`tensorboard....`, a private class):
  `is_writer_thread`; and TensorBoard's frames in a traceback: `raised_in_tensorboard`.

rsl_rl's and Hydra's private names are read in the sibling modules `lasmp/compat/rsl_rl.py` and
`lasmp/compat/hydra.py`. `tests/test_tb_compat.py` exercises each function against the installed
torch and TensorBoard, so that an upgrade that renames one fails there, pointing here.
"""

from __future__ import annotations

import threading
import traceback

_PACKAGE = "tensorboard"


def _event_writer(writer: object) -> object | None:
    """The `EventFileWriter` of a torch `SummaryWriter` (or of a subclass: rsl_rl's W&B and Neptune
    writers); None for any other writer, or none."""
    return getattr(getattr(writer, "file_writer", None), "event_writer", None)


def events_file(writer: object) -> str | bytes | None:
    """The path of the events file `writer` (rsl_rl's logger's `writer`) appends to; None when it
    writes none."""
    return getattr(_event_writer(writer), "_file_name", None)


def writer_thread_error(writer: object) -> BaseException | None:
    """The exception `writer`'s writer thread stopped on; the writer raises the same one in the main
    thread at its next write or flush. None while the thread runs, or without such a thread."""
    worker = getattr(getattr(_event_writer(writer), "_async_writer", None), "_worker", None)
    return getattr(worker, "exception", None)


def is_writer_thread(thread: threading.Thread | None) -> bool:
    """Whether `thread` (a `threading.excepthook` argument's) is TensorBoard's writer thread."""
    return type(thread).__module__.startswith(_PACKAGE)


def raised_in_tensorboard(err: BaseException) -> bool:
    """Whether TensorBoard's code is on the way `err` came up (a frame of a file of its package)."""
    return any(_PACKAGE in frame.filename for frame in traceback.extract_tb(err.__traceback__))
