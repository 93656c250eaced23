"""Warm start (ours): a new run that goes on from a checkpoint's weights, where a resume cannot.

    python train.py warm_start=results/ladder/base/seed10/in_progress/policy_364.pt \
        runner.log_dir=runs/ladder/base/seed10 runner.max_iterations=1435

A resume needs the run's full checkpoint (optimizers, the envs' running state), which stays on the
machine that trained: a run whose machine was lost has only what was committed, a policy checkpoint
(`policy_<N>.pt`) or its light form (actor only, `lasmp.light_checkpoint`). A warm start takes from it
what it holds: the actor (MLP, normalizer, encoder, estimators), the critic where the file has one,
the curriculum, the random streams, the validation curve and best score, and the iteration, so the
estimate schedule and the curve go on where they were. It starts anew what the file lacks: the
optimizers (Adam's moments, and the learning rate at algo.learning_rate, not the schedule's last
value), the critic of a light file, and every env's episode. So it is not exact, and it says so;
the run's config.yaml records `warm_start=`, and its resume command (after a stop) is a plain resume.

The config is the checkpoint's, with the command's keys on top, as a resume's (`lasmp.resume`): a key
a resume cannot change (task, seed, the networks) is refused the same way.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from lasmp.algo.checkpoint import CheckpointError, check_finite, read_checkpoint
from lasmp.config import ConfigError
from lasmp.resume import insane_entry, resumed_cfg
from lasmp.train_cfg import TrainCfg

if TYPE_CHECKING:
    from lasmp.algo.runner import LasmpRunner


@dataclass
class WarmStart:
    """A warm start checked whole before anything is built or written: the config it runs and the
    checkpoint as read (once)."""

    cfg: TrainCfg
    data: dict

    @classmethod
    def check(cls, cfg: TrainCfg, explicit: set[str] | None) -> WarmStart:
        """`cfg.warm_start` read (a checkpoint of any form, or a run directory: its newest) and checked
        (`explicit`: the keys the command set, as for a resume; None: every key is the caller's)."""
        if cfg.resume:
            raise ConfigError(
                f"resume={cfg.resume} and warm_start={cfg.warm_start} both given: resume continues a run "
                "exactly from its full checkpoint, warm_start starts a new run from a checkpoint's weights; give one"
            )
        data = read_checkpoint(cfg.warm_start, "cpu")
        path = data["path"]
        try:
            check_finite({k: data[k] for k in data if k.endswith("state_dict")}, f"checkpoint {path}")
        except FloatingPointError as err:
            raise CheckpointError(f"{err}: no run can start from it") from None
        insane = insane_entry(data)
        if insane:
            raise CheckpointError(f"checkpoint {path}: {insane}: no run can start from it")
        return cls(resumed_cfg(cfg, data, explicit), data)

    @property
    def has_critic(self) -> bool:
        return bool(self.data.get("critic_state_dict"))

    def restore(self, runner: LasmpRunner, say: Callable[..., None]) -> None:
        """Load what the checkpoint holds into the runner built from `cfg`; say what starts anew."""
        keep = {
            "actor": True,
            "critic": self.has_critic,
            "optimizer": False,
            "iteration": True,
            "env_run_state": False,
        }
        runner.load(self.data, load_cfg=keep)
        first = runner.current_learning_iteration
        fresh = "the optimizers" + ("" if self.has_critic else " and the critic (the file holds none)")
        say(
            f"warm start from {self.data['path']} at iteration {first}: its actor"
            + (", critic" if self.has_critic else "")
            + f", curriculum and validation curve; {fresh} start anew, the learning rate at "
            f"{self.cfg.algo.learning_rate}, and every env's episode; {self.cfg.runner.max_iterations} "
            f"iterations, to {first + self.cfg.runner.max_iterations - 1}",
            flush=True,
        )
