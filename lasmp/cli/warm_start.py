"""Warm start (ours): a new run that goes on from a checkpoint's weights, where a resume cannot.

    python train.py warm_start=results/ladder/base/seed10/in_progress/policy_364.pt \
        runner.log_dir=runs/ladder/base/seed10 runner.max_iterations=1435

A resume needs the run's full checkpoint (optimizers, the envs' running state), which stays on the
machine that trained: a run whose machine was lost has only what was committed, a policy checkpoint
(`policy_<N>.pt`) or its light form (actor only, `lasmp.algo.checkpoint.light`). A warm start takes from it
what it holds: the actor (MLP, normalizer, encoder, estimators), the critic where the file has one,
the curriculum, the random streams, the validation curve and best score, and the iteration, so the
estimate schedule and the curve go on where they were, and the learning rate the adaptive schedule
had reached (a policy checkpoint keeps it: `learning_rates`). It starts anew what the file lacks:
Adam's moments, the critic of a light file, and every env's episode. So it is not exact, and it says
so; the run's config.yaml records `warm_start=`, and its resume command (after a stop) is a plain
resume. Measured (docs/scaling.md): restarting at algo.learning_rate instead, 13 times the schedule's
rate at iteration 550, undid a trained policy within 25 iterations; so did a new critic (a light file).

The config is the checkpoint's, with the command's keys on top, as a resume's (`lasmp.cli.resume`): a key
a resume cannot change (task, seed, the networks) is refused the same way.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from lasmp.algo.checkpoint import learning_rates, read_checkpoint
from lasmp.algo.checkpoint.sanity import check_state
from lasmp.cli.resume import resumed_cfg
from lasmp.config.checks import ConfigError
from lasmp.config.train import TrainCfg
from lasmp.envs.trajectories.splines import PADDING

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
        check_state(data, "no run can start from it", PADDING)
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
        rate = self._restore_learning_rates(runner)
        first = runner.current_learning_iteration
        fresh = "the optimizers' moments" + (
            ""
            if self.has_critic
            else " and the critic (the file holds none: a new critic's first advantages undo a trained "
            "policy for dozens of iterations, docs/scaling.md; warm-start from a policy checkpoint)"
        )
        say(
            f"warm start from {self.data['path']} at iteration {first}: its actor"
            + (", critic" if self.has_critic else "")
            + f", curriculum and validation curve; {fresh} start anew, and every env's episode; {rate}; "
            f"{self.cfg.runner.max_iterations} iterations, to {first + self.cfg.runner.max_iterations - 1}",
            flush=True,
        )

    def _restore_learning_rates(self, runner: LasmpRunner) -> str:
        """Set each optimizer's learning rate to the one the file kept (the adaptive schedule's last);
        say which rate the run goes on at."""
        rates = learning_rates(self.data)
        for name, saved in rates.items():
            optimizer = getattr(runner.alg, name, None)
            if optimizer is None:
                continue
            for group in optimizer.param_groups:
                group["lr"] = saved["lr"]
            if name == "optimizer":
                runner.alg.learning_rate = saved["lr"]
        if "optimizer" in rates:
            return f"the learning rate goes on at the file's {rates['optimizer']['lr']:.4g}"
        return (
            f"the file keeps no learning rate (written before they were kept): it restarts at algo.learning_rate="
            f"{self.cfg.algo.learning_rate}, which can undo a trained policy in its first iterations"
        )
