"""Resume policy: what a resumed run takes from its checkpoint and what from the command, what it
refuses, and the command that continues an interrupted run.

`resume=DIR` (its newest full checkpoint: a policy checkpoint holds no training state) or a full
checkpoint in DIR continues in DIR, unless runner.log_dir names another, empty directory (a branch);
runner.max_iterations then counts the iterations to add. A resume is checked whole (the checkpoint,
the config, the envs' count, the networks) before anything is written, so that a failed resume
leaves the run as it was. From the command line a resume runs the checkpoint's own config with the
keys the command sets on top (`explicit_keys`); every key the command changes is applied and said,
or refused where it cannot take effect (`RESUME_FIXED`).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from omegaconf import OmegaConf

from lasmp.algo.checkpoint import (
    CheckpointError,
    read_checkpoint,
    refuse_policy_only,
)
from lasmp.algo.checkpoint.sanity import check_state
from lasmp.config.base import flatten
from lasmp.config.checkpoint import rebuilding
from lasmp.config.train import TrainCfg, to_plain, to_train_cfg
from lasmp.envs.trajectories.splines import PADDING
from lasmp.io.rundir import RunDirError, describe, run_checkpoints, run_files

if TYPE_CHECKING:
    from lasmp.algo.runner import LasmpRunner

# keys a resume takes from the command, never from the checkpoint's config
FROM_COMMAND = ("resume", "resume_drop_env_state", "warm_start", "runner.log_dir")


# keys a resume may change freely: how long and where it runs, on what hardware, how it computes
RESUME_FREE = FROM_COMMAND + (
    "runner.",
    "device",
    "torch_threads",
    "env.seed",
    "env.sim.num_threads",
    "algo.precision",
    "algo.fused_adam",
    "algo.use_mixed_precision",
    "algo.compile_mlps",
)


# keys a resume cannot change: why, for the refusal
RESUME_FIXED = {
    "task": "the checkpoint's networks were trained on its task",
    "seed": "the random streams continue from the checkpoint's",
    "policy.": "the networks (their layers, inputs and action noise) are the checkpoint's",
}


# learning rates restored with the optimizers' states: a new value is applied after the load
LEARNING_RATES = {"algo.learning_rate": "optimizer", "algo.estimator_learning_rate": "estimator_optimizer"}


def _matches(key: str, patterns) -> bool:
    return any(key == p or (p.endswith(".") and key.startswith(p)) for p in patterns)


def resumed_cfg(cfg: TrainCfg, data: dict, explicit: set[str] | None) -> TrainCfg:
    """The config a resume runs: `cfg` as it is (explicit None: every key is the caller's), or the
    checkpoint's config with the keys in `explicit` (and FROM_COMMAND) taken from `cfg`."""
    if explicit is None:
        return cfg
    given, saved = flatten(to_plain(cfg)), flatten(data["config"])
    taken = {
        k: v
        for k, v in given.items()
        if _matches(k, FROM_COMMAND) or k in explicit or any(k.startswith(f"{e}.") for e in explicit)
    }
    _refuse_fixed({k: (saved[k], v) for k, v in taken.items() if k in saved and saved[k] != v})
    with rebuilding(data):
        merged = OmegaConf.create(data["config"])
        for key, value in taken.items():
            OmegaConf.update(merged, key, value, force_add=True)
        return to_train_cfg(merged)


def check_resume(cfg: TrainCfg, data: dict) -> dict[str, tuple]:
    """Refuse a resume that cannot go as `cfg` says, before anything is built or written; return
    the keys it changes from the checkpoint's config, {key: (saved, now)}."""
    path = data["path"]
    refuse_policy_only(data)
    check_state(data, "it cannot be resumed (give an earlier checkpoint)", PADDING)
    saved, now = flatten(data["config"]), flatten(to_plain(cfg))
    changed = {
        k: (saved[k], now[k])
        for k in now
        if k in saved and saved[k] != now[k] and not _matches(k, RESUME_FREE)
    }
    _refuse_fixed(changed)
    saved_run = (data.get("env_state") or {}).get("run")
    if (
        saved_run is not None
        and not cfg.resume_drop_env_state
        and saved_run.get("num_envs") != cfg.env.num_envs
    ):
        n = saved_run.get("num_envs")
        raise CheckpointError(
            f"resume: env.num_envs={cfg.env.num_envs}, but the checkpoint {path} holds the running state of "
            f"{n} envs. Give resume_drop_env_state=true to start every env's episode anew (the resume is then "
            f"not exact), or env.num_envs={n}"
        )
    changed.pop("env.num_envs", None)
    return changed


def _refuse_fixed(changed: dict[str, tuple]) -> None:
    """Refuse a change, {key: (saved, now)}, of a key a resume cannot change (RESUME_FIXED)."""
    for key, (old, new) in changed.items():
        for fixed, why in RESUME_FIXED.items():
            if _matches(key, (fixed,)):
                raise CheckpointError(
                    f"resume: {key}={new} differs from the run's {key}={old}, and a resume cannot change it ({why}): "
                    "drop the override, or start a new run in another runner.log_dir"
                )


def apply_learning_rates(runner: LasmpRunner, changed: dict[str, tuple]) -> None:
    """A learning rate given anew on resume replaces the one the optimizer's state brought back."""
    for key, attr in LEARNING_RATES.items():
        if key not in changed or getattr(runner.alg, attr, None) is None:
            continue
        optimizer, (old, new) = getattr(runner.alg, attr), changed[key]
        restored = optimizer.param_groups[0]["lr"]
        for group in optimizer.param_groups:
            group["lr"] = new
        if attr == "optimizer":
            runner.alg.learning_rate = new
        print(
            f"resume: {key}={new} (the run's was {old}): the learning rate restarts at {new}, not at the "
            f"checkpoint's {restored:.4g}",
            flush=True,
        )


@dataclass
class Resume:
    """A resume checked whole before anything is built or written: the config it runs, the
    checkpoint as read (once), and the keys it changes from the run's config, {key: (saved, now)}."""

    cfg: TrainCfg
    data: dict
    changed: dict[str, tuple]

    @classmethod
    def check(cls, cfg: TrainCfg, explicit: set[str] | None) -> Resume:
        """`cfg.resume` read and checked against `cfg` (`explicit`: as in `resumed_cfg`)."""
        data = read_checkpoint(cfg.resume, "cpu", full_only=True)
        cfg = resumed_cfg(cfg, data, explicit)
        return cls(cfg, data, check_resume(cfg, data))

    def restore(self, runner: LasmpRunner, say: Callable[..., None]) -> None:
        """Load the checkpoint into the runner built from `cfg`, apply the changed keys, and say
        what changed and where the run goes on."""
        keep = {
            "actor": True,
            "critic": True,
            "optimizer": True,
            "iteration": True,
            "env_run_state": not self.cfg.resume_drop_env_state,
        }
        runner.load(self.data, load_cfg=keep)
        apply_learning_rates(runner, self.changed)
        others = {k: v for k, v in self.changed.items() if k not in LEARNING_RATES}
        if others:
            say(
                "resume: in effect from now on, changed from the run's config: "
                + ", ".join(f"{k} {old} -> {new}" for k, (old, new) in others.items()),
                flush=True,
            )
        first = runner.current_learning_iteration
        last = first + self.cfg.runner.max_iterations - 1
        abandoned = self.data.get("abandoned_rollout")
        if abandoned and not self.cfg.resume_drop_env_state:
            say(
                f"resume: not exact: {self.data['path']} was saved when a signal stopped iteration "
                f"{abandoned['iteration']}'s rollout {abandoned['env_steps']} env-steps in; the envs go on from "
                "that moment, not from the end of the saved iteration",
                flush=True,
            )
        say(
            f"resumed from {self.data['path']} at iteration {first} (0\u2013{first - 1} done); runner.max_iterations "
            f"counts the iterations to add: {self.cfg.runner.max_iterations} more, to {last}",
            flush=True,
        )


def check_run_dir(log_dir: Path, data: dict | None):
    """The check `claim` makes once it holds the directory's lock."""

    def check(run_dir: Path) -> None:
        continuing = data is not None and Path(data["path"]).parent.resolve() == run_dir.resolve()
        if continuing:
            m = re.fullmatch(r"model_(\d+)\.pt", Path(data["path"]).name)
            position = int(m.group(1)) if m else data["iter"]  # where the resumed file sits in the run
            later = [p.name for n, p in run_checkpoints(run_dir).items() if n > position]
            if later:
                # only a full checkpoint can be resumed: never advise a policy checkpoint, whose refusal
                # would send the user back here
                full = [p.name for n, p in run_checkpoints(run_dir, full_only=True).items() if n > position]
                advice = (
                    f"Resume from {full[-1]}, the newest full checkpoint, or give"
                    if full
                    else "The later ones are policy checkpoints, which cannot resume: give"
                )
                raise RunDirError(
                    f"resume={data['path']} is not the latest checkpoint of {run_dir} ({describe(later)} came "
                    f"later): continuing there would overwrite them. {advice} runner.log_dir=NEW_DIR to branch "
                    "off into a new directory"
                )
            return
        held = run_files(run_dir)
        if held:
            saved = "" if run_checkpoints(run_dir) else " (no checkpoint: delete the directory to reuse it)"
            raise RunDirError(
                f"runner.log_dir={run_dir} already holds a run ({describe(held)}){saved}: give resume={run_dir} to "
                "continue it, or another runner.log_dir for a new run"
            )

    return check
