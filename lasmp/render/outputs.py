"""The files a play run writes (video, snapshots, the exported policy): checked before any work,
written whole, and reported when the run is interrupted.

Why here and not in each writer: a run writes up to four files, and a user needs every one of them
checked before the env is built (a read-only directory found after a five-minute rollout is five
minutes lost), and, when the run fails or is interrupted, one line saying which were written.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

from lasmp.atomic import AtomicWriteError
from lasmp.inputs import check_out_file, missing_dirs
from lasmp.modules.export import export_policy

EXPORT_FILES = ("policy.onnx", "policy.json")  # what --export onnx writes into --out


def check_outputs(args) -> list[Path]:
    """The files this run will write (video, snapshots, export), each checked by `check_out_file`
    before any work: a known extension, no existing file without --force, a writable directory.
    InputError otherwise; nothing is created."""
    out = []
    if args.video:
        out.append(check_out_file(args.video, suffixes=(".mp4",), force=args.force, option="--video"))
    if args.snapshots:
        out.append(check_out_file(args.snapshots, suffixes=(".png",), force=args.force, option="--snapshots"))
    if args.export:
        for name in EXPORT_FILES:
            path = Path(args.out) / name
            out.append(check_out_file(path, suffixes=(path.suffix,), force=args.force, option="--out"))
    return out


class Outputs:
    """What a run has written so far, of the files it will write, and the directories it created.

    A run that fails or is interrupted removes the directories it created that are still empty (so
    a failed first write leaves nothing behind) and says in one line what it did and did not write."""

    def __init__(self, wanted: list[Path]):
        self.wanted = wanted
        self.written: list[Path] = []
        self.steps: int | None = None  # policy steps played (None: the rollout has not started)
        self.total_steps: int | None = None
        self.new_dirs = sorted(
            {d for p in wanted for d in missing_dirs(p.parent)}, key=lambda d: -len(d.parts)
        )

    def remove_new_empty_dirs(self) -> None:
        for d in self.new_dirs:  # deepest first
            try:
                d.rmdir()
            except OSError:  # not empty (something was written there), or gone
                pass

    def interrupted(self) -> str:
        if self.steps is None:
            when = "before the rollout"
        elif self.steps < self.total_steps:
            when = f"after {self.steps} of {self.total_steps} steps"
        else:
            when = f"after the rollout ({self.steps} steps)"
        if not self.written:
            return f"interrupted {when}: nothing written"
        line = f"interrupted {when}: wrote {', '.join(map(str, self.written))}"
        missing = [str(p) for p in self.wanted if p not in self.written]
        return line + (f"; not written: {', '.join(missing)}" if missing else "")


def export_into(policy, out_dir: Path, metadata: dict) -> list[Path]:
    """`export_policy` into `out_dir` as one unit: both files are written in a staging directory
    inside it, then renamed into place. A failure (a full disk) leaves the older export, or nothing,
    as it was; the AtomicWriteError names the file in `out_dir`, not the staging one."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=".export.", suffix=".tmp", dir=out_dir))
    except OSError as err:
        raise AtomicWriteError(out_dir / EXPORT_FILES[0], err) from err
    try:
        try:
            export_policy(policy, staging, metadata)
        except AtomicWriteError as err:
            raise AtomicWriteError(out_dir / Path(err.filename).name, err) from err
        names = [n for n in EXPORT_FILES if (staging / n).exists()]
        for name in names:
            try:
                os.replace(staging / name, out_dir / name)
            except OSError as err:
                raise AtomicWriteError(out_dir / name, err) from err
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return [out_dir / n for n in names]
