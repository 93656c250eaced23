"""The light form of a policy checkpoint: what play.py and evaluate.py run, and nothing else.

    python -m lasmp.algo.checkpoint.light SRC DST [--force]       # SRC: a checkpoint or run directory
    python -m lasmp.algo.checkpoint.light --in-place FILE [FILE ...]   # policy_<N>.pt files, each checked

A policy checkpoint (`python -m lasmp.algo.checkpoint policy`) still holds the critic, which only
training uses: 0.86 of its 1.83 MB. The light form keeps the actor (its MLP, normalizer, encoder and
estimators) in float32, bit for bit, and the config, layout, curriculum state, learner record and
random state: evaluate.py and play.py load it as they load any policy checkpoint, and its actions are
the full form's exactly, so a regeneration of an evaluation's records from it
(`python -m lasmp.eval.regenerate`) gives the same records. Half precision would halve it again but
change the actions, and with them every episode that is close to a fall.

The critic's entry stays, empty: every checkpoint reader requires the key (`REQUIRED_KEYS`), and an
empty critic cannot be mistaken for one (a resume refuses any policy checkpoint).
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

import torch

from lasmp.algo.checkpoint import (
    CheckpointError,
    atomic_torch_save,
    check_finite,
    checkpoint_file,
    is_policy_only,
    read_checkpoint,
)
from lasmp.io.atomic import OutputExistsError, claim_output
from lasmp.io.inputs import InputError, check_out_file

LIGHT_KIND = "actor"  # the `kind` of a light checkpoint (a policy checkpoint is "policy")
DROPPED = (
    "critic_state_dict",
    "episode_log_state",
    "path",
)  # what training alone reads (and the load's path)


def light(data: dict) -> dict:
    """Checkpoint `data` (as read) without what only training reads; refuses a full checkpoint, whose
    optimizer states would go unsaid."""
    if not is_policy_only(data):
        raise CheckpointError(
            f"{data['path']} is a full checkpoint: make its policy checkpoint first "
            "(python -m lasmp.algo.checkpoint policy SRC DST), so that the training state is dropped on purpose"
        )
    out = {k: v for k, v in data.items() if k not in DROPPED}
    out.update(
        critic_state_dict={},
        kind=LIGHT_KIND,
        source=f"{data.get('source') or Path(data['path']).name}, actor only (lasmp.algo.checkpoint.light)",
    )
    check_finite(out, f"refusing to write the light form of {data['path']}")
    return out


def same_actions(a: dict, b: dict) -> bool:
    """The two checkpoints' actors hold the same tensors, bit for bit (so the same actions)."""
    x, y = a["actor_state_dict"], b["actor_state_dict"]
    return x.keys() == y.keys() and all(x[k].dtype == y[k].dtype and torch.equal(x[k], y[k]) for k in x)


def write_light(src: str | Path, dst: str | Path, force: bool = False) -> Path:
    """The light form of `src` at `dst` (an existing `dst` only with `force`; `src` itself only through
    `convert_in_place`), read back and checked to hold `src`'s actor bit for bit. `dst` is claimed
    before `src` is read (`lasmp.io.atomic.claim_output`, create-exclusive): a file already there, or one
    another run claimed meanwhile, is refused without `force`, and a failed run leaves no empty file."""
    src = checkpoint_file(src)
    try:
        dst = check_out_file(dst, suffixes=(".pt", ".pth"), force=True, option="DST")
    except InputError as err:
        raise CheckpointError(str(err)) from None
    if Path(dst).resolve() == src.resolve():
        raise CheckpointError(f"{dst} is {src}: give another DST, or convert with --in-place")
    claims = contextlib.ExitStack()
    try:
        claims.enter_context(claim_output(dst, force=force, option="DST"))
    except OutputExistsError as err:
        raise CheckpointError(str(err)) from None
    with claims:
        data = read_checkpoint(src)
        atomic_torch_save(light(data), dst)
    if not same_actions(data, read_checkpoint(dst)):
        raise CheckpointError(f"{dst}: its actor differs from {src}'s after writing")
    return Path(dst)


def convert_in_place(path: str | Path) -> tuple[int, int]:
    """Replace a policy checkpoint by its light form, atomically (the file is either the old one or the
    checked new one); a light one is left as it is. Returns (bytes before, bytes after)."""
    path = checkpoint_file(path)
    before = path.stat().st_size
    data = read_checkpoint(path)
    if data.get("kind") == LIGHT_KIND:
        return before, before
    slim = light(data)
    atomic_torch_save(slim, path)
    if not same_actions(data, read_checkpoint(path)):  # never expected: torch.save keeps tensors exact
        raise CheckpointError(f"{path}: its actor changed in the light form; restore it with git checkout")
    return before, path.stat().st_size


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("paths", nargs="+", metavar="PATH", help="SRC DST, or with --in-place the files")
    p.add_argument("--in-place", action="store_true", help="replace each policy checkpoint by its light form")
    p.add_argument("--force", action="store_true", help="write over an existing DST")
    args = p.parse_args(argv)
    try:
        if args.in_place:
            total = [0, 0]
            for path in args.paths:
                before, after = convert_in_place(path)
                total[0], total[1] = total[0] + before, total[1] + after
                print(f"{path}: {before:,} -> {after:,} bytes")
            print(f"{len(args.paths)} files: {total[0]:,} -> {total[1]:,} bytes")
            return 0
        if len(args.paths) != 2:
            p.error("give SRC DST (or --in-place FILE ...)")
        dst = write_light(*args.paths, force=args.force)
        print(f"wrote {dst} ({dst.stat().st_size:,} bytes), actor only")
        return 0
    except (CheckpointError, OSError) as err:  # OSError: a full disk (AtomicWriteError names the file)
        print(f"error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
