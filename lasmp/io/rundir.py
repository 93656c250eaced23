"""Run directories: one training at a time in each, and never a new run over an old one.

- A directory *holds a run* when it has a `config.yaml` or a `model_<N>.pt` (`run_files`).
- `RunLock`: a training holds `fcntl.flock` on `<dir>/.lock`, a file that holds its PID, for as long
  as it runs; a second process gets `RunDirError` naming that PID. The kernel drops the lock when a
  process ends, however it ends, so a `.lock` left by a killed training blocks nothing; a training
  that ends removes it (where it can: on a directory turned read-only the `.lock` stays, and the
  error that ended the training is the one reported).
- `claim`: create the directory, lock it, check what it holds and remove the temporary files of
  saves killed mid-write; a start that fails leaves no directory it created behind.

This module imports no torch, so that another process can take a run's lock cheaply.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from lasmp.io.atomic import remove_stale_temporaries

LOCK_NAME = ".lock"
FULL, POLICY = "model", "policy"  # the file name prefixes of full and policy checkpoints in a run
CHECKPOINT_NAME = re.compile(rf"({FULL}|{POLICY})_(\d+)\.pt")


class RunDirError(ValueError):
    """A run directory cannot be used as asked; the message names it and says why."""


def run_checkpoints(run_dir: str | Path, full_only: bool = False) -> dict[int, Path]:
    """The checkpoints of `run_dir` by iteration, oldest first: `model_<N>.pt` (full) and
    `policy_<N>.pt` (policy only; `full_only` leaves them out). Where both exist for an N, the full
    one: it holds everything the policy one does."""
    found: dict[int, Path] = {}
    for path in Path(run_dir).glob("*_*.pt"):
        m = CHECKPOINT_NAME.fullmatch(path.name)
        if m and not (full_only and m.group(1) == POLICY):
            n = int(m.group(2))
            if n not in found or m.group(1) == FULL:
                found[n] = path
    return dict(sorted(found.items()))


def run_files(run_dir: str | Path) -> list[str]:
    """The names of the files that make `run_dir` a run's directory: config.yaml, model_<N>.pt."""
    run_dir = Path(run_dir)
    names = ["config.yaml"] if (run_dir / "config.yaml").is_file() else []
    return names + [p.name for p in run_checkpoints(run_dir, full_only=True).values()]


def describe(names: list[str]) -> str:
    """At most four names, then how many more."""
    shown = ", ".join(names[:4])
    return shown + (f" and {len(names) - 4} more" if len(names) > 4 else "")


class RunLock:
    """An exclusive lock on a run directory for this process (see the module docstring)."""

    def __init__(self, run_dir: str | Path, path: Path | None = None):
        self.run_dir = Path(run_dir)
        self.path = self.run_dir / LOCK_NAME if path is None else path
        self._fd: int | None = None

    def busy(self, holder: str) -> Exception:
        """The error when another process holds the lock (subclasses name their own users)."""
        return RunDirError(
            f"{self.run_dir} is in use by another training (PID {holder}): wait for it to end, or "
            "give another runner.log_dir"
        )

    def acquire(self) -> None:
        """Take the lock, or raise RunDirError naming the PID of the process that holds it."""
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.read(fd, 32).decode(errors="replace").strip() or "unknown"
                os.close(fd)
                raise self.busy(holder) from None
            # a holder that ended may have removed the file between our open and our lock: lock anew
            try:
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        try:
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode())
        except OSError:  # a full disk cannot take the PID: no lock is held by a lost descriptor
            with contextlib.suppress(OSError):
                self.path.unlink(missing_ok=True)  # while still held, as release does
            os.close(fd)
            raise
        self._fd = fd

    def release(self) -> None:
        """Unlock and remove `.lock`. Never raises: it runs while another error may be on its way out
        (a save that failed when the directory turned read-only), and a `.lock` it cannot remove
        blocks nothing (the kernel's lock is what counts, and closing the file drops it)."""
        if self._fd is None:
            return
        fd, self._fd = self._fd, None
        with contextlib.suppress(OSError):  # while still held: a process that opened it locks anew
            self.path.unlink(missing_ok=True)
        with contextlib.suppress(OSError):
            fcntl.flock(fd, fcntl.LOCK_UN)
        with contextlib.suppress(OSError):
            os.close(fd)

    def __enter__(self) -> RunLock:
        self.acquire()
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def _make_dirs(path: Path) -> list[Path]:
    """mkdir -p; return the directories it created, outermost first."""
    if path.exists() and not path.is_dir():
        raise RunDirError(f"runner.log_dir={path} is a file, not a directory")
    missing = []
    for p in (path, *path.parents):
        if p.exists():
            break
        missing.append(p)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise RunDirError(f"cannot make runner.log_dir={path}: {err.strerror} ({err.filename})") from None
    return missing[::-1]


@contextmanager
def claim(run_dir: str | Path, check: Callable[[Path], None]) -> Iterator[Path]:
    """Create `run_dir`, lock it, call `check(run_dir)` (which raises if the directory must not be
    used), remove stale temporary files (printing them), and hold the lock through the block. If
    anything fails, the directories made here are removed again where they are still empty."""
    run_dir = Path(run_dir)
    made = _make_dirs(run_dir)
    lock = RunLock(run_dir)
    try:
        try:
            lock.acquire()
        except OSError as err:  # a full disk cannot take the lock's PID: name the file
            raise RunDirError(f"cannot write {lock.path}: {err.strerror or err}") from None
        try:
            check(run_dir)
            stale = remove_stale_temporaries(run_dir)
            if stale:
                print(
                    f"removed {len(stale)} temporary file(s) of a save that was killed mid-write: "
                    f"{describe([p.name for p in stale])}",
                    flush=True,
                )
            yield run_dir
        finally:
            lock.release()
    except BaseException:
        for d in reversed(made):
            try:
                d.rmdir()
            except OSError:  # it holds what the run wrote
                break
        raise
