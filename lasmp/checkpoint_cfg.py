"""A checkpoint's training config, rebuilt as today's TrainCfg: what play, evaluation and the
benchmarks build a policy and an env from. It lives above `lasmp.algo`, which knows checkpoints but
not the training config."""

from __future__ import annotations

from omegaconf import OmegaConf

from lasmp.algo.checkpoint import CheckpointError
from lasmp.train_cfg import TrainCfg, to_train_cfg


def checkpoint_cfg(
    data: dict, num_envs: int, seed: int, trajectories: str | None = None, env_overrides: dict | None = None
) -> TrainCfg:
    """The TrainCfg saved in a checkpoint, with only num_envs, seed (and trajectory file, and the
    given nested env overrides) changed; CheckpointError if today's code cannot rebuild it."""
    if not data.get("config"):
        raise CheckpointError(f"checkpoint {data['path']} carries no config to rebuild the policy from")
    try:
        conf = OmegaConf.create(data["config"])
        conf.env.num_envs = int(num_envs)
        conf.seed = int(seed)
        conf.device = "cpu"
        conf.resume = None
        conf.runner.log_dir = None
        conf.runner.logger = (
            "tensorboard"  # it logs nothing: a W&B or Neptune run plays without their package
        )
        if trajectories is not None:
            conf.env.trajectory.file = str(trajectories)
        conf.env = OmegaConf.merge(conf.env, OmegaConf.create(env_overrides or {}))
        return to_train_cfg(conf)
    except Exception as err:  # unknown/removed keys, out-of-range values: the code moved on
        raise CheckpointError(
            f"checkpoint {data['path']} has a config this code cannot rebuild: {err}"
        ) from err
