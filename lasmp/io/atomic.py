"""Atomic file writes: nothing a run produces is ever left half-written.

Both helpers write to a temporary file in the target's directory (a hidden `.<name>.*.tmp`),
flush it to disk, give it mode 0644 and rename it over the target (`os.replace` is atomic on
POSIX); on any error the temporary file is removed and the target is untouched. A failure of the
file system (disk full, no permission, a parent that is a file) raises `AtomicWriteError`, whose
message is one line naming the target: also where a writer wraps the OSError in its own exception
(torch's zip writer raises `RuntimeError: [enforce fail at inline_container.cc]` after the OSError
of a full disk), since the OSError is then only in the exception's chain and a handler of OSError
would never see it. Only a killed process leaves a temporary file behind:
`remove_stale_temporaries` clears them where no writer can be running (a locked run directory).

`claim_output` claims a command's output file before the work (create-exclusive, so a file the user
already has is refused without --force, with no window between a check and the write); the block's
atomic write then replaces the claim.
"""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

TEMPORARY_SUFFIX = ".tmp"


class AtomicWriteError(OSError):
    """Writing a file failed in the file system; the target is unchanged. str() is one line."""

    def __init__(self, path: str | os.PathLike, cause: OSError):
        super().__init__(cause.errno, cause.strerror or str(cause), os.fspath(path))

    def __str__(self) -> str:
        return f"cannot write {self.filename}: {self.strerror} (the file is left as it was)"


@contextmanager
def _replacing(path: str | os.PathLike) -> Iterator[str]:
    """Yield a temporary file name next to `path`; rename it over `path` when the block succeeds."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=TEMPORARY_SUFFIX, dir=path.parent)
    except OSError as err:
        raise AtomicWriteError(path, err) from err
    os.close(fd)
    try:
        yield tmp
        os.chmod(tmp, 0o644)  # mkstemp makes 0600
        os.replace(tmp, path)
    except BaseException as err:
        with contextlib.suppress(OSError):  # never let the cleanup replace the error (a read-only disk)
            if os.path.exists(tmp):
                os.unlink(tmp)
        cause = file_system_error(err)
        if cause is not None and not isinstance(err, AtomicWriteError):
            raise AtomicWriteError(path, cause) from err
        raise


def file_system_error(err: BaseException) -> OSError | None:
    """The OSError behind `err`: `err` itself, or one in its chain (`__cause__` / `__context__`) when
    a writer raised its own exception while handling it; None for other errors (a bug, an
    interruption), which must not be reported as a failed write."""
    seen = set()
    while isinstance(err, Exception) and id(err) not in seen:
        if isinstance(err, OSError):
            return err
        seen.add(id(err))
        err = err.__cause__ or err.__context__
    return None


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


class OutputExistsError(FileExistsError):
    """The output file exists and the command was not given --force; str() is one line naming it and
    the option (an OSError, so the writers' handlers of a failed write report it too)."""

    def __init__(self, path: str | os.PathLike, option: str):
        super().__init__(errno.EEXIST, "already exists", os.fspath(path))
        self.option = option

    def __str__(self) -> str:
        return (
            f"{self.filename} already exists: choose another {self.option}, or pass --force to overwrite it"
        )


def _missing_dirs(path: Path) -> list[Path]:
    """The directories of `path` that do not exist yet, outermost first (lasmp.io.inputs.missing_dirs)."""
    missing, parent = [], path.absolute().parent
    while not (parent.exists() or parent.is_symlink()) and parent != parent.parent:
        missing.append(parent)
        parent = parent.parent
    return missing[::-1]


def _still_the_claim(path: Path, ident: tuple[int, int]) -> bool:
    """`path` is the empty placeholder `claim_output` made (not a file that replaced it, nor content
    written into it in place)."""
    try:
        st = os.lstat(path)
    except OSError:
        return False
    return (st.st_dev, st.st_ino) == ident and st.st_size == 0


def _remove_dirs(dirs: list[Path]) -> None:
    for d in reversed(dirs):  # innermost first; one that is no longer empty stays
        with contextlib.suppress(OSError):
            d.rmdir()


@contextmanager
def claim_output(path: str | os.PathLike, *, force: bool, option: str = "--out") -> Iterator[Path]:
    """`with claim_output(path, force=args.force, option="--json") as out: <work>; atomic_write...(out)`.

    Claims `path` for this run BEFORE the work: creates it exclusively (O_CREAT | O_EXCL) as an empty
    placeholder, so a file already there (the user's, another run's, a symbolic link) is refused with
    OutputExistsError, one line naming it and --force, and is left byte for byte; and no other run can
    claim the name while this one works (no check-then-write race). With `force` an existing file is
    kept until the block's write replaces it. The block writes the final content atomically over the
    placeholder (`atomic_open`, `atomic_write_with`, or a save built on them). When the block fails
    (an exception, SystemExit, Ctrl-C) or writes nothing, the placeholder is removed, with the
    directories the claim created; a file that replaced it is kept. A directory in its place, or a
    failing file system, is an AtomicWriteError naming `path`."""
    path = Path(path)
    if path.is_dir():
        raise AtomicWriteError(path, IsADirectoryError(errno.EISDIR, f"{option} is a directory; give a file"))
    created = _missing_dirs(path)
    ident = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
    except FileExistsError:
        if not force:
            raise OutputExistsError(path, option) from None
    except OSError as err:
        _remove_dirs(created)
        raise AtomicWriteError(path, err) from err
    else:
        st = os.fstat(fd)
        os.close(fd)
        ident = (st.st_dev, st.st_ino)
    try:
        yield path
    finally:
        if ident is not None and _still_the_claim(path, ident):  # still the empty claim: nothing was written
            with contextlib.suppress(OSError):
                path.unlink()
            _remove_dirs(created)


def remove_stale_temporaries(directory: str | os.PathLike) -> list[Path]:
    """Delete the temporary files that writes killed mid-way left in `directory` (not below it);
    return them. Only where no write can be under way (the caller holds the directory's lock)."""
    stale = [p for p in Path(directory).glob(f".*{TEMPORARY_SUFFIX}") if p.is_file()]
    for p in stale:
        p.unlink(missing_ok=True)
    return stale
