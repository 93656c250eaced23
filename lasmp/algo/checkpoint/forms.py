"""The forms of a checkpoint: full (a training's state), policy (no optimizers' or envs' running
state) and the run directory's rule of how many full ones it keeps."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

from lasmp.algo.checkpoint.format import (
    OPTIMIZER_KEYS,
    CheckpointError,
    _claim,
    _kind_of,
    _out_file,
    atomic_torch_save,
    check_finite,
    checkpoint_file,
    is_policy_only,
    read_checkpoint,
)
from lasmp.io.rundir import FULL, POLICY, run_checkpoints


def refuse_policy_only(data: dict) -> None:
    """A policy checkpoint cannot resume training: CheckpointError saying so, naming the newest full
    checkpoint of its directory where there is one."""
    if not is_policy_only(data):
        return
    path = Path(data["path"])
    full = run_checkpoints(path.parent, full_only=True)
    where = (
        f"give {full[max(full)]}, the newest full checkpoint of its run"
        if full
        else f"give a full checkpoint ({FULL}_<N>.pt): {path.parent} holds none, or start a new run from "
        f"its weights with warm_start={path} (fresh optimizers)"
    )
    raise CheckpointError(
        f"{path} is a policy checkpoint (it holds no training state: no optimizers, no envs' running "
        f"state). Play or evaluate it; to resume training, {where}"
    )


def policy_only(data: dict, source: str) -> dict:
    """A policy checkpoint's content from a checkpoint's `data`: without the optimizers' states and the
    envs' running state (the task's state, such as the curriculum, stays); `source` says where from.
    The learning rate each optimizer had reached stays (`learning_rates`, a few bytes): a warm start
    from the file goes on at it. Why: the adaptive schedule lowers it (7.6e-5 at iteration 550 of a
    default run), and restarting at algo.learning_rate (1e-3) with fresh Adam moments undoes the policy
    (docs/scaling.md, the warm start's shock)."""
    slim = {k: v for k, v in data.items() if k not in OPTIMIZER_KEYS and k != "path"}
    slim["env_state"] = {k: v for k, v in (data.get("env_state") or {}).items() if k != "run"}
    rates = learning_rates(data)
    if rates:
        slim["learning_rates"] = rates
    slim.update(kind="policy", source=source)
    return slim


def learning_rates(data: dict) -> dict[str, dict[str, float]]:
    """{optimizer: {"lr": its first group's learning rate}} of a checkpoint's `data`: read off its
    optimizers' states (a full checkpoint) or the `learning_rates` a policy checkpoint kept."""
    if "learning_rates" in data:
        return dict(data["learning_rates"])
    return {
        key.removesuffix("_state_dict"): {"lr": float(data[key]["param_groups"][0]["lr"])}
        for key in OPTIMIZER_KEYS
        if isinstance(data.get(key), dict) and data[key].get("param_groups")
    }


def policy_checkpoint(src: str | Path, dst: str | Path, force: bool = False, claim: bool = True) -> Path:
    """Write the policy checkpoint of `src` (a checkpoint or run directory) to `dst`: everything but
    the optimizers' states and the envs' running state (networks with their normalizers, config,
    layout, the task's env state such as the curriculum). An existing `dst` (`src` itself included)
    is overwritten only with `force`; `dst` is checked and claimed (`_claim`) before `src` is read.
    `claim=False` (with `force`) writes without the claim's placeholder: for `keep_newest_full`, inside a
    locked run directory, where a training killed mid-way must not leave an empty policy_<N>.pt."""
    src, dst = checkpoint_file(src), _out_file(dst)
    with _claim(dst, force, src) if claim else contextlib.nullcontext():
        data = read_checkpoint(src)
        slim = policy_only(data, f"{Path(data['path']).name} (iteration {data['iter']})")
        check_finite(slim, f"refusing to write {dst}")
        atomic_torch_save(slim, dst)
    return Path(dst)


def keep_newest_full(run_dir: str | Path, keep_full: int) -> tuple[list[str], list[str]]:
    """Keep the newest `keep_full` full checkpoints of `run_dir` and turn each older `model_<N>.pt`
    into its policy checkpoint `policy_<N>.pt` (a tenth of the size: a laptop keeps a long run).
    No step loses the only copy: the policy file is written atomically and read back, the directory
    synced, and only then the full one removed. Returns the conversions ("model_3.pt -> policy_3.pt")
    and the files left as they were, each with why (an unreadable checkpoint, a full disk, a
    `policy_<N>.pt` in the way that is not a policy checkpoint)."""
    full = run_checkpoints(run_dir, full_only=True)
    done, left = [], []
    for n in list(full)[: max(len(full) - keep_full, 0)]:
        src = full[n]
        dst = src.with_name(f"{POLICY}_{n}.pt")
        kind = _kind_of(dst) if dst.exists() else None
        try:
            if kind not in (None, "a policy checkpoint"):
                raise CheckpointError(f"{dst.name} exists and is {kind}")
            # force: a policy_<N>.pt of an earlier, cut-short conversion; no claim (an empty file) in a run
            policy_checkpoint(src, dst, force=True, claim=False)
            read_checkpoint(dst)
        except (CheckpointError, OSError) as err:  # OSError: a full disk; the full one stays
            left.append(f"{src.name} ({err})")
            continue
        _sync_directory(src.parent)
        src.unlink()
        done.append(f"{src.name} -> {dst.name}")
    return done, left


def _sync_directory(path: Path) -> None:
    """fsync a directory: the renames in it are on disk before what follows (a removal) is."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
