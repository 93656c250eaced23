"""What a training runs, built from its checked config: the env (its memory checked once its model is
built, before its envs' data are allocated), the runner, and rank 0's in-training validator."""

from __future__ import annotations

import dataclasses

import torch

from lasmp.algo.runner import LasmpRunner
from lasmp.cli.resources import check_memory
from lasmp.config.checks import ConfigError
from lasmp.config.train import TrainCfg, rsl_rl_cfg, to_plain, validates
from lasmp.envs import registry
from lasmp.io.inputs import SEED_MAX


def seed_everything(seed: int) -> None:
    torch.manual_seed(seed)


def make_env(cfg: TrainCfg, processes: int = 1):
    """The task's env (`lasmp.envs.registry`), its tensors where its physics runs (cpu backend: the CPU,
    even with the learner on a GPU; warp: `cfg.device`). Its model built, an env.num_envs that cannot
    fit with the rollouts and networks of `processes` ranks on this machine is refused
    (`lasmp.cli.resources.check_memory`) before any env's data is allocated."""
    return registry.make_env(
        cfg.task,
        cfg.env,
        cfg.device,
        check_fit=lambda model, widths: check_memory(cfg, processes, built=(model, widths)),
    )


def make_runner(cfg: TrainCfg, log_dir: str | None, rank: int = 0, processes: int = 1) -> LasmpRunner:
    """The env and the runner of `cfg`; in a data-parallel job, rank k's envs and torch streams are
    seeded with seed + k (its own physics, trajectories and curriculum draws); the saved config keeps
    the job's seed. `processes`: this machine's ranks (the memory check counts each one's envs)."""
    if cfg.device.startswith("cuda") and not torch.cuda.is_available():
        raise ConfigError(
            f"device={cfg.device} but torch sees no CUDA device (install a CUDA build of torch)"
        )
    if cfg.torch_threads > 0:
        torch.set_num_threads(cfg.torch_threads)
    seed = (cfg.seed + rank) % (SEED_MAX + 1)  # a seed near 2**32 - 1 stays a valid seed on every rank
    seed_everything(seed)
    env = make_env(
        cfg if rank == 0 else dataclasses.replace(cfg, env=dataclasses.replace(cfg.env, seed=seed)), processes
    )
    full_config = to_plain(cfg)
    return LasmpRunner(
        env,
        rsl_rl_cfg(cfg),
        log_dir=log_dir,
        device=cfg.device,
        full_config=full_config,
        max_fault_fraction=cfg.runner.max_fault_fraction,
        keep_full=cfg.runner.keep_full,
        validator=make_validator(full_config) if rank == 0 else None,
        validation_interval=cfg.runner.validation_interval,
    )


def make_validator(full_config: dict):
    """The in-training validator of a moving-platform run, from its resolved config (`to_plain`, what
    its checkpoints keep): None when validation is off, or for another task (the validation benchmark
    is the moving platform's)."""
    runner = full_config.get("runner", {})
    if not validates(full_config.get("task"), runner.get("validation_interval") or 0):
        return None
    from lasmp.eval.validation import Validator

    return Validator(full_config, runner["validation_episodes"])
