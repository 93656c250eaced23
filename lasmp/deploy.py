"""A deployable policy from a checkpoint: what `play.py`, `evaluate.py` and the benchmarks run.

A checkpoint is read once. The policy is the trained actor in deployment mode: its inputs are o_t
and the history o^H only (the estimators replace the privileged groups), its actions the mean. It is
built from the checkpoint's own config and observation layout, never from today's defaults and
without an env; `load_deploy_env` adds an env of the checkpoint's task for tools that step one.
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Callable
from dataclasses import dataclass

import torch
from rsl_rl.utils import resolve_class, resolve_obs_groups
from tensordict import TensorDict

from lasmp.algo.checkpoint import (
    CheckpointError,
    check_compatible,
    not_fitting,
    read_checkpoint,
    set_rng_state,
)
from lasmp.cli.preflight import backend_error
from lasmp.config.checkpoint import checkpoint_cfg
from lasmp.config.train import TrainCfg, rsl_rl_cfg
from lasmp.envs.registry import make_env


@dataclass
class Deployed:
    """A checkpoint's policy (deployment mode, eval), the config it was trained with, and the
    checkpoint as read (`read_checkpoint`), for what else a tool takes from it."""

    policy: torch.nn.Module
    cfg: TrainCfg
    checkpoint: dict


def obs_window(obs) -> torch.Tensor:
    """(n, H+1, D) = [o_t, o_{t-1}, ..., o_{t-H}]: the deployable policy's only input."""
    return torch.cat([obs["policy"].unsqueeze(1), obs["history"]], dim=1)


def build_policy(data: dict, cfg: TrainCfg, mixin: type | None = None) -> torch.nn.Module:
    """The actor of checkpoint `data` with its weights, in deployment mode; CheckpointError if the
    weights do not fit the actor its config describes. `mixin`: a class whose methods override the
    actor's (a subclass of both is built), for diagnostics that change what the actor reads."""
    rsl = rsl_rl_cfg(cfg)
    layout = data["obs_layout"]
    obs = TensorDict({g: torch.zeros(1, *shape) for g, shape in layout.items()}, batch_size=[1])
    actor_class, actor_cfg = resolve_class(dict(rsl["actor"]))
    if mixin is not None:
        actor_class = type(mixin.__name__ + actor_class.__name__, (mixin, actor_class), {})
    with contextlib.redirect_stdout(io.StringIO()):  # rsl_rl prints the observation sets and its models
        groups = resolve_obs_groups(obs, dict(rsl["obs_groups"]), ["actor", "critic"])
        with not_fitting(f"{data['path']} does not fit its own config"):  # a shape mismatch, a missing key
            policy = actor_class(obs, groups, "actor", int(data["num_actions"]), **actor_cfg)
            policy.load_state_dict(data["actor_state_dict"])
    policy.deploy = True
    policy.eval()
    return policy


def load_policy(
    path,
    seed: int | None = 0,
    num_envs: int = 1,
    trajectories: str | None = None,
    env_overrides: dict | Callable[[str], dict] | None = None,
    mixin: type | None = None,
) -> Deployed:
    """The deployable policy of `path`, a checkpoint file or a run directory (its latest
    model_<N>.pt), with its config for `num_envs` envs and `seed` (None: the run's own), and a
    trajectory file, and nested env overrides, or a function of the checkpoint's task that gives
    them (a setting one task's env has and another's lacks) (`mixin`: `build_policy`'s).
    CheckpointError for a missing, unreadable, hostile or mismatched checkpoint."""
    data = read_checkpoint(path)
    config = data.get("config") or {}
    if seed is None:
        seed = config.get("seed", 0)
    if callable(env_overrides):
        env_overrides = env_overrides(config.get("task"))
    cfg = checkpoint_cfg(data, num_envs, seed, trajectories, env_overrides)
    return Deployed(build_policy(data, cfg, mixin), cfg, data)


def check_backend(deployed: Deployed) -> None:
    """CheckpointError where the physics backend the checkpoint was trained on (env.backend, which its
    env keeps) cannot run here: a warp checkpoint without MuJoCo Warp, said before the env is built."""
    path = deployed.checkpoint["path"]
    error = backend_error(
        deployed.cfg.env.backend, f"checkpoint {path} was trained with env.backend=warp; its env needs"
    )
    if error:
        raise CheckpointError(error)


def load_deploy_env(
    path,
    num_envs: int = 1,
    seed: int | None = None,
    trajectories: str | None = None,
    env_overrides: dict | Callable[[str], dict] | None = None,
    mixin: type | None = None,
):
    """(env, policy, cfg, checkpoint): `load_policy` plus an env of the checkpoint's task with
    `num_envs` envs. The env takes the checkpoint's curriculum state (not its envs' running state:
    its size may differ) and is reset, so its first episodes already use the checkpoint's
    curriculum. Its random streams: with `seed` None, the checkpoint's own at the save (its run's
    seed, continued); with a seed, fresh streams from that seed, so that seeds give other episodes."""
    deployed = load_policy(path, seed, num_envs, trajectories, env_overrides, mixin)
    check_backend(deployed)
    cfg, data = deployed.cfg, deployed.checkpoint
    torch.manual_seed(cfg.seed)
    env = make_env(cfg.task, cfg.env, cfg.device)
    check_compatible(data, env)
    with not_fitting(f"{data['path']}: its env or random state does not fit this env"):
        if data.get("env_state"):
            env.load_state_dict(data["env_state"], run=False)
        if seed is None and data.get("rng_state"):
            set_rng_state(data["rng_state"], env.rng)
    env.reset()
    return env, deployed.policy, cfg, data
