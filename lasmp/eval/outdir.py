"""Where evaluate.py writes, and how: one evaluation at a time per directory, and its result whole.

- `default_out_dir`: eval/<controller> for Stand Still; for a checkpoint eval/<run directory>-<8 hex
  digits>/<checkpoint stem>, the digits a hash of the run directory's full path, so two checkpoints
  of the same run-directory and file names in different places (results/study/lasmp/seed0/policy_449.pt
  and results/study/lasmp_centre/seed0/policy_449.pt) never share one.
- `ResultDir`: the output directory of one evaluation, claimed before any episode is played. It
  holds a lock (`lasmp.io.rundir.RunLock`'s: `fcntl.flock` on a file holding the PID; the kernel drops
  it however the process ends) for the whole evaluation, so a second evaluation into the same
  directory is refused instead of silently replacing the first. Every file of the result is written
  into a private staging directory, then put in place as one unit: a directory that did not exist is
  the staging directory renamed; into one that exists (a study's result directory also holds the
  run's config and policy), the files are moved in with `metrics.json` last, after the earlier
  result's files are removed, so a `metrics.json` is never beside files of another evaluation.
  Where the directory did not exist, the lock and the staging directory are its hidden siblings
  (`.<name>.lock`, `.<name>.staging-*`); where it exists, they are inside it (`.lock`, `.staging-*`),
  on its file system. A refused, failed or interrupted evaluation leaves nothing behind: not its
  staging directory, not its lock file, not the directories it made.
- `where_written`: the line that says where the result went.
"""

from __future__ import annotations

import errno
import hashlib
import os
import shutil
import signal
import sys
import tempfile
import threading
from contextlib import contextmanager
from pathlib import Path

from lasmp.algo.checkpoint import latest_checkpoint
from lasmp.eval import episodes as ep
from lasmp.eval.benchmark import VALIDATION
from lasmp.eval.report import atomic_write_text, dumps
from lasmp.io.inputs import file_sha256, missing_dirs, size_in_words
from lasmp.io.rundir import LOCK_NAME, RunLock

METRICS_FILE = "metrics.json"  # written last: a directory with one holds a whole result
ESTIMATES_PLOT = "estimates.png"
# every file an evaluation writes (and the plain episodes.csv of older ones): an earlier result's
# files that a new result does not replace are removed with it, never left beside it
RESULT_FILES = (
    METRICS_FILE,
    "metrics.md",
    ep.EPISODES_FILE,
    ep.EPISODES_FILE.removesuffix(".gz"),
    ep.MIRROR_EPISODES_FILE,
    ESTIMATES_PLOT,
)
# a lower bound of what a result needs on disk: metrics.json and .md, and the gzip-compressed
# episode rows (about 230 bytes each for Xi_eval); only a disk that certainly cannot take it is refused
MIN_RESULT_BYTES = 8 * 1024
MIN_BYTES_PER_EPISODE = 100
HASH_DIGITS = 8


def where_written(out_dir: Path, names: list[str]) -> str:
    """The last line evaluate.py prints: where its results are, for a reader who did not pass --out."""
    return f"results in {out_dir}: {', '.join(names)}"


class OutDirError(ValueError):
    """--out cannot take a result: it already holds one, another evaluation writes it, or it cannot
    be written."""


class ResultWriteError(OSError):
    """Writing the result failed in the file system (a full disk, a file system turned read-only);
    str() is one line naming the file and saying what was left where."""

    def __init__(self, path: Path, cause: OSError, left: str):
        super().__init__(cause.errno, cause.strerror or str(cause), os.fspath(path))
        self.left = left

    def __str__(self) -> str:
        return f"cannot write {self.filename}: {self.strerror} ({self.left})"


def checkpoint_file(checkpoint: str | os.PathLike | None) -> Path | None:
    """The file a --checkpoint names: itself, or a run directory's latest checkpoint (None: none)."""
    if checkpoint is None:
        return None
    path = Path(checkpoint)
    return latest_checkpoint(path) if path.is_dir() else path


def default_out_dir(args, root: Path = Path("eval")) -> Path:
    """eval/<controller> without a checkpoint; else eval/<run directory>-<hash>/<checkpoint stem>
    [_<controller>], from the checkpoint file (a run directory's latest checkpoint), plus
    `_validation` on the validation benchmark (its metrics never land where Xi_eval's do). The hash is
    of the run directory's resolved path: the same checkpoint always lands in the same place, and two
    checkpoints never share one, whatever their run directories and files are called."""
    on_validation = (
        "_validation" if Path(getattr(args, "benchmark", None) or "") == Path(VALIDATION.path) else ""
    )
    if args.checkpoint is None:
        return root / f"{args.controller}{on_validation}"
    path = checkpoint_file(args.checkpoint).resolve()
    digest = hashlib.sha256(os.fsencode(path.parent)).hexdigest()[:HASH_DIGITS]
    suffix = f"_{args.controller}" if args.controller else ""
    return root / f"{path.parent.name}-{digest}" / f"{path.stem}{suffix}{on_validation}"


class _Lock(RunLock):
    """RunLock's lock (flock on a file holding the PID, released without raising) on `path`, the
    --out's own lock file, with evaluate's message."""

    def __init__(self, path: Path, shown: Path):
        super().__init__(path.parent, path)
        self.shown = shown

    def busy(self, holder: str) -> Exception:
        return OutDirError(
            f"{self.shown} is being written by another evaluation or training (PID {holder}): wait "
            "for it to end, or give another --out"
        )


@contextmanager
def _signals_deferred():
    """Ctrl-C and SIGTERM wait until the block ends (the main thread only), so that moving a result
    into place is never cut in two."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    sigs = (signal.SIGINT, signal.SIGTERM)
    old = {s: signal.signal(s, lambda signum, frame: pending.append(signum)) for s in sigs}
    try:
        yield
    finally:
        for s, handler in old.items():
            if handler is not None:  # None: a handler not set from Python, which cannot be restored
                signal.signal(s, handler)
        if pending:
            signal.raise_signal(pending[0])


class ResultDir:
    """One evaluation's output directory (module docstring): `claim()` it before any work, write
    every file into `staging`, `commit(names)`, and `close()` it whatever happens."""

    def __init__(self, out_dir: str | os.PathLike, force: bool):
        self.shown = Path(out_dir)  # as the user gave it, for the messages
        self.real = self.shown.resolve()  # a symlinked --out is written where it points
        self.force = force
        self.staging: Path | None = None
        self.committed = False
        self._made: list[Path] = []
        self._lock: _Lock | None = None
        self._keep_staging = False

    # -- before the work --------------------------------------------------------------------------
    def check(self) -> None:
        """What can be checked without creating anything: not a file, no earlier result unless --force."""
        if self.real.name == "":
            raise OutDirError(f"cannot write results to {self.shown}: give a directory below it")
        existing = next(p for p in (self.real, *self.real.parents) if p.exists())
        if not existing.is_dir():
            what = "it is" if existing == self.real else f"{existing} is"
            raise OutDirError(f"cannot write results to {self.shown}: {what} a file, not a directory")
        existing = self.real / METRICS_FILE
        if existing.exists() and not self.force:
            raise OutDirError(
                f"{self.shown / METRICS_FILE} already exists (an earlier result): choose another --out, "
                "or pass --force to overwrite it"
            )

    def claim(self) -> ResultDir:
        """Check, make the missing parents, take the lock, check again under it, clear what killed
        evaluations left, and make the staging directory: a real write, so an unwritable --out
        fails here, before any episode. On failure everything made here is removed again."""
        self.check()
        inside = self.real.is_dir()
        where = self.real if inside else self.real.parent
        try:
            self._made = missing_dirs(where)
            where.mkdir(parents=True, exist_ok=True)
            lock = where / (LOCK_NAME if inside else f".{self.real.name}{LOCK_NAME}")
            self._lock = _Lock(lock, self.shown)
            self._lock.acquire()
            self.check()  # another evaluation may have finished between the first check and the lock
            prefix = ".staging-" if inside else f".{self.real.name}.staging-"
            for stale in where.glob(f"{prefix}*"):  # left by an evaluation that was killed
                shutil.rmtree(stale, ignore_errors=True)
            self.staging = Path(tempfile.mkdtemp(prefix=prefix, dir=where))
            os.chmod(self.staging, 0o755)  # mkdtemp makes 0700; renamed into place it is the result
        except OSError as err:
            self.close()
            raise OutDirError(f"cannot write results to {self.shown}: {err.strerror or err}") from None
        except BaseException:
            self.close()
            raise
        return self

    def check_space(self, num_episodes: int) -> None:
        """Refuse a disk that certainly cannot take the result (MIN_* above), before the work."""
        st = os.statvfs(self.staging)
        if st.f_blocks == 0:  # a file system that does not report its size
            return
        free = st.f_bavail * st.f_frsize
        need = MIN_RESULT_BYTES + MIN_BYTES_PER_EPISODE * num_episodes
        if free < need:
            raise OutDirError(
                f"cannot write results to {self.shown}: its disk has {size_in_words(free)} free, the results "
                f"of {num_episodes} episodes need at least {size_in_words(need)}: free some space or give "
                "another --out"
            )

    # -- after the work ---------------------------------------------------------------------------
    def write(self, name: str, writer) -> str:
        """`writer(path)` writes `name` into the staging directory; a file-system error becomes a
        ResultWriteError naming the file where it was to go. Returns `name`."""
        try:
            writer(self.staging / name)
        except OSError as err:
            raise ResultWriteError(self.shown / name, err, f"nothing written to {self.shown}") from err
        return name

    def commit(self, names: list[str]) -> None:
        """Put the staged files `names` in place as one unit (module docstring)."""
        with _signals_deferred():
            if not self.real.exists():
                try:
                    os.rename(self.staging, self.real)
                    self.committed = True
                    self.staging = None
                    return
                except OSError as err:  # made meanwhile by someone else: move the files in instead
                    if err.errno not in (errno.ENOTEMPTY, errno.EEXIST, errno.EISDIR):
                        raise ResultWriteError(self.shown, err, f"nothing written to {self.shown}") from err
            self._move_in(names)

    def _move_in(self, names: list[str]) -> None:
        order = [n for n in names if n != METRICS_FILE] + [METRICS_FILE]
        current, removed = None, False
        try:
            self.real.mkdir(exist_ok=True)
            for stale in (METRICS_FILE, *(n for n in RESULT_FILES if n not in names)):
                (self.real / stale).unlink(missing_ok=True)
                removed = True
            for current in order:
                os.replace(self.staging / current, self.real / current)
        except OSError as err:
            self._keep_staging = True  # the only whole copy of the result
            earlier = f"{self.shown} holds no metrics.json" if removed else "an earlier result is as it was"
            raise ResultWriteError(
                self.shown / (current or ""), err, f"{earlier}; the whole result is in {self.staging}"
            ) from err
        self.committed = True

    def close(self) -> None:
        """Remove the staging directory (unless it holds the only whole copy of a result), release
        the lock, and remove the directories made here if nothing was committed. Never raises."""
        if self.staging is not None and not self._keep_staging:
            shutil.rmtree(self.staging, ignore_errors=True)
            self.staging = None
        if self._lock is not None:
            self._lock.release()
            self._lock = None
        if not self.committed:
            for d in reversed(self._made):
                try:
                    d.rmdir()
                except OSError:  # it holds something (another evaluation's): keep it
                    break
            self._made = []

    def __enter__(self) -> ResultDir:  # `with out:` closes a claimed ResultDir however the block ends
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def claim_out(args, root: Path, claimed: list) -> ResultDir:
    """--out (or the default under `root`) claimed: checked, locked and staged, before any work."""
    out = ResultDir(args.out if args.out is not None else default_out_dir(args, root), args.force)
    claimed.append(out)
    return out.claim()


def provenance(args, checkpoint: Path | None, bench_file: Path) -> dict:
    """What the result was measured with: the seed and the SHA-256 of the benchmark (or the suite's
    robots) file and of the checkpoint file, so a result can be tied to its inputs."""
    out = {"seed": args.seed, "benchmark_sha256": file_sha256(bench_file)}
    if getattr(args, "trajectories", None) is not None:
        out["trajectories_sha256"] = file_sha256(args.trajectories)
    out["checkpoint"] = None if checkpoint is None else str(checkpoint)
    out["checkpoint_sha256"] = None if checkpoint is None else file_sha256(checkpoint)
    return out


def result_writers(result: dict, render) -> list:
    """metrics.json and metrics.md, as publish's (name, writer) pairs."""
    return [
        ("metrics.json", lambda path: atomic_write_text(path, dumps(result))),
        ("metrics.md", lambda path: atomic_write_text(path, render(result))),
    ]


def publish(out: ResultDir, markdown: str, writers: list[tuple[str, object]]) -> int:
    """Write each (name, writer(path)) into `out`'s staging directory, commit them as one unit, and
    print `markdown` and, last, where the result went; return 0. When the file system refuses (a full
    disk), the work is not lost unsaid: `markdown` is printed all the same, then one error line naming
    the file that could not be written; return 1."""
    names = []
    try:
        for name, writer in writers:
            names.append(out.write(name, writer))
        out.commit(names)
    except ResultWriteError as err:
        print(markdown, flush=True)
        print(f"error: {err}; the metrics above are not saved", file=sys.stderr)
        return 1
    print(markdown)
    print(where_written(out.shown, names))
    return 0


def interrupted(out: ResultDir | None) -> str:
    """The one line evaluate.py prints on Ctrl-C: what was and was not written."""
    if out is not None and out.committed:
        return f"interrupted: the results were written to {out.shown} first"
    where = f" to {out.shown} (an earlier result there is as it was)" if out is not None else ""
    return f"interrupted: nothing written{where}; the output's lock is released"
