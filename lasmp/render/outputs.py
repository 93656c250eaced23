"""The files a play run writes (video, snapshots, the exported policy): checked and claimed before
any work, written whole, and reported when the run is interrupted.

Why here and not in each writer: a run writes up to four files, and a user needs every one of them
checked before the env is built (a read-only directory found after a five-minute rollout is five
minutes lost), and, when the run fails or is interrupted, one line saying which were written.

Each file is claimed (`lasmp.io.atomic.claim_output`: created exclusively as an empty placeholder) before
the env is built, so a file the user already has is refused without --force, and a second run started
meanwhile cannot write the same name (no window between a check and the write). The export is claimed
file by file (policy.onnx and policy.json in --out), not as a folder: --out may well be a directory
that exists and holds other things (a run directory, a deploy folder), which an exclusive mkdir would
refuse for no reason, while the two files are exactly what the export replaces.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path

from lasmp.io.atomic import AtomicWriteError, claim_output
from lasmp.io.inputs import check_out_file, missing_dirs
from lasmp.modules.export import export_policy

EXPORT_FILES = ("policy.onnx", "policy.json")  # what --export onnx writes into --out


def output_files(args) -> list[tuple[Path, tuple[str, ...], str]]:
    """(file, known extensions, option naming it) of each file this run will write."""
    out = []
    if args.video:
        out.append((Path(args.video), (".mp4",), "--video"))
    if args.snapshots:
        out.append((Path(args.snapshots), (".png",), "--snapshots"))
    if args.export:
        out += [(Path(args.out) / name, (Path(name).suffix,), "--out") for name in EXPORT_FILES]
    return out


def check_outputs(args) -> list[Path]:
    """The files this run will write (video, snapshots, export), each checked by `check_out_file`
    before any work: a known extension, not a directory, a writable directory. InputError otherwise;
    nothing is created. A file already there is refused by `claim_outputs`, not here."""
    return [
        check_out_file(path, suffixes=suffixes, force=True, option=option)
        for path, suffixes, option in output_files(args)
    ]


def claim_outputs(args) -> contextlib.ExitStack:
    """Claim every file this run will write (`claim_output`), before the env is built; the returned
    stack holds the claims: `with claim_outputs(args): <the run>`. Leaving it removes each claim that
    was not written (and the directories the claims created). OutputExistsError (one line naming the
    file and --force) for a file already there without --force, AtomicWriteError for a failing file
    system; the claims already taken are released then."""
    with contextlib.ExitStack() as claims:
        for path, _, option in output_files(args):
            claims.enter_context(claim_output(path, force=args.force, option=option))
        return claims.pop_all()


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
