"""A checkpoint's training config, rebuilt as today's TrainCfg: what play, evaluation and the
benchmarks build a policy and an env from (`checkpoint_cfg`), and what a resume runs, with the
command's keys on top (`lasmp.cli.resume`). It lives above `lasmp.algo`, which knows checkpoints but not
the training config."""

from __future__ import annotations

from contextlib import contextmanager

from omegaconf import OmegaConf

from lasmp.algo.checkpoint import CheckpointError
from lasmp.config.train import TrainCfg, to_train_cfg


def checkpoint_cfg(
    data: dict, num_envs: int, seed: int, trajectories: str | None = None, env_overrides: dict | None = None
) -> TrainCfg:
    """The TrainCfg saved in a checkpoint, with only num_envs, seed (and trajectory file, and the
    given nested env overrides) changed; CheckpointError if today's code cannot rebuild it."""
    if not data.get("config"):
        raise CheckpointError(f"checkpoint {data['path']} carries no config to rebuild the policy from")
    with rebuilding(data):
        conf = OmegaConf.create(data["config"])
        conf.env.num_envs = int(num_envs)
        conf.seed = int(seed)
        conf.device = "cpu"
        conf.resume = None
        conf.warm_start = None
        conf.runner.log_dir = None
        # it logs nothing: a W&B or Neptune run plays without their package
        conf.runner.logger = "tensorboard"
        if trajectories is not None:
            conf.env.trajectory.file = str(trajectories)
        conf.env = OmegaConf.merge(conf.env, OmegaConf.create(env_overrides or {}))
        return to_train_cfg(conf)


@contextmanager
def rebuilding(data: dict):
    """Any failure of rebuilding the config of checkpoint `data` (a key since removed or renamed, a
    value now out of range: the code moved on) as one CheckpointError naming the checkpoint."""
    try:
        yield
    except Exception as err:
        raise CheckpointError(
            f"checkpoint {data['path']} has a config this code cannot rebuild: {err}"
        ) from err
