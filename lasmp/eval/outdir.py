"""Where evaluate.py writes: the default --out directory of a checkpoint or baseline, the check that
it can take a result before any episode is played, and the line that says where the result went."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from lasmp.algo.checkpoint import latest_checkpoint


def where_written(out_dir: Path, names: list[str]) -> str:
    """The last line evaluate.py prints: where its results are, for a reader who did not pass --out."""
    return f"results in {out_dir}: {', '.join(names)}"


class OutDirError(ValueError):
    """--out cannot take a result: it already holds one, or it cannot be written."""


def default_out_dir(args, root: Path = Path("eval")) -> Path:
    """eval/stand_still; else eval/<run directory>/<checkpoint stem>[_<controller>], from the checkpoint
    file (a run directory's latest model_<N>.pt), so `model_449.pt` of two runs land apart."""
    if args.checkpoint is None:
        return root / args.controller
    path = Path(args.checkpoint)
    if path.is_dir():
        path = latest_checkpoint(path)
    path = path.resolve()
    suffix = f"_{args.controller}" if args.controller else ""
    return root / path.parent.name / f"{path.stem}{suffix}"


def prepare_out_dir(out_dir: Path, force: bool) -> Path:
    """Create `out_dir` and prove it writable (a temporary file), before any episode is played;
    refuse one that already holds a metrics.json unless `force`."""
    existing = out_dir / "metrics.json"
    if existing.exists() and not force:
        raise OutDirError(
            f"{existing} already exists (an earlier result): choose another --out, or pass --force "
            "to overwrite it"
        )
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out_dir, prefix=".write-test-"):
            pass
    except OSError as err:
        raise OutDirError(f"cannot write results to {out_dir}: {err.strerror or err}") from None
    if not os.access(out_dir, os.W_OK):
        raise OutDirError(f"cannot write results to {out_dir}: not writable")
    return out_dir
