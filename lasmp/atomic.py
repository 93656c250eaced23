"""Atomic file writes: nothing a run produces is ever left half-written.

Both helpers write to a temporary file in the target's directory, flush it to disk, give it
mode 0644 and rename it over the target (`os.replace` is atomic on POSIX); on any error the
temporary file is removed and the target is untouched.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def _replacing(path: str | os.PathLike) -> Iterator[str]:
    """Yield a temporary file name next to `path`; rename it over `path` when the block succeeds."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        yield tmp
        os.chmod(tmp, 0o644)  # mkstemp makes 0600
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


@contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "wb") -> Iterator:
    """`with atomic_open(path) as f: ...` writes `path` all at once or not at all."""
    with _replacing(path) as tmp, open(tmp, mode) as f:
        yield f
        f.flush()
        os.fsync(f.fileno())


def atomic_write_with(path: str | os.PathLike, write: Callable[[str], None]) -> None:
    """For writers that take a file name: `write(tmp_name)`, then the same rename as `atomic_open`."""
    with _replacing(path) as tmp:
        write(tmp)
