"""Build the env, the runner and train: the logic behind `train.py`."""

from __future__ import annotations

import datetime
import os
from dataclasses import is_dataclass
from pathlib import Path

import torch
from omegaconf import OmegaConf

from lasmp.algo.checkpoint import read_checkpoint
from lasmp.algo.runner import LasmpRunner, TrainingInterrupted
from lasmp.config import ConfigError, build_env_cfg
from lasmp.train_cfg import TrainCfg, env_schema, rsl_rl_cfg, validate_train_cfg


def seed_everything(seed: int) -> None:
    torch.manual_seed(seed)


def make_env(cfg: TrainCfg):
    """The task's env. Its tensors live where its physics runs: on the CPU with the cpu backend (the
    learner may still be on a GPU: the runner moves observations), on `cfg.device` with warp."""
    device = cfg.device if cfg.env.backend == "warp" else "cpu"
    if cfg.task == "rough_static":
        from lasmp.envs.rough_static.env import RoughStaticEnv

        return RoughStaticEnv(cfg.env, device=device)
    from lasmp.envs.moving_platform.env import MovingPlatformEnv

    return MovingPlatformEnv(cfg.env, device=device)


def to_train_cfg(cfg) -> TrainCfg:
    """An OmegaConf/Hydra config (or a TrainCfg) as a validated TrainCfg, its env built with the
    task's schema and env.seed = seed."""
    if not isinstance(cfg, TrainCfg):
        cfg = OmegaConf.to_object(OmegaConf.merge(OmegaConf.structured(TrainCfg), cfg))
    if not is_dataclass(cfg.env):
        cfg.env = build_env_cfg(dict(cfg.env or {}), schema=env_schema(cfg.task))
    cfg.env.seed = cfg.seed
    validate_train_cfg(cfg)
    return cfg


def make_runner(cfg: TrainCfg, log_dir: str | None) -> LasmpRunner:
    if cfg.device.startswith("cuda") and not torch.cuda.is_available():
        raise ConfigError(
            f"device={cfg.device} but torch sees no CUDA device (install a CUDA build of torch)"
        )
    if cfg.torch_threads > 0:
        torch.set_num_threads(cfg.torch_threads)
    seed_everything(cfg.seed)
    env = make_env(cfg)
    return LasmpRunner(env, rsl_rl_cfg(cfg), log_dir=log_dir, device=cfg.device, full_config=to_plain(cfg))


def to_plain(cfg: TrainCfg) -> dict:
    return OmegaConf.to_container(OmegaConf.structured(cfg))


def default_log_dir(cfg: TrainCfg) -> str:
    stamp = datetime.datetime.now().strftime("%Y-%m-%d_%H-%M-%S")
    return os.path.join("logs", cfg.task, cfg.policy.name, stamp)


def train(cfg) -> LasmpRunner:
    cfg = to_train_cfg(cfg)
    checkpoint = None
    if cfg.resume:  # fail before building anything if the checkpoint is unusable; read it once
        checkpoint = read_checkpoint(cfg.resume, "cpu")
    log_dir = cfg.runner.log_dir or default_log_dir(cfg)
    Path(log_dir).mkdir(parents=True, exist_ok=True)
    OmegaConf.save(OmegaConf.structured(cfg), os.path.join(log_dir, "config.yaml"))
    runner = make_runner(cfg, log_dir)
    if cfg.resume:
        runner.load(checkpoint)
        print(f"resumed from {cfg.resume} at iteration {runner.current_learning_iteration}", flush=True)
    print(f"training {cfg.task} / {cfg.policy.name}: {cfg.env.num_envs} envs, {cfg.runner.max_iterations} "
          f"iterations, logs in {log_dir}", flush=True)  # fmt: skip
    last = runner.current_learning_iteration + cfg.runner.max_iterations - 1  # the iteration this command ends at
    try:
        runner.learn(cfg.runner.max_iterations)
    except TrainingInterrupted as stop:
        if stop.checkpoint:
            # on a resume, runner.max_iterations counts the iterations still to run: those left
            left = last - stop.iteration
            print(f"{stop}\nresume with:\n  {resume_command(stop.checkpoint, log_dir, left)}", flush=True)
        raise
    return runner


def resume_command(checkpoint: str, log_dir: str, iterations_left: int | None = None) -> str:
    """The train.py command line that continues a run: this run's own overrides (from Hydra, when
    it composed the config) with resume= and runner.log_dir= set, and runner.max_iterations= the
    iterations left to the end the interrupted command set (a resume runs that many more)."""
    overrides: list[str] = []
    try:
        from hydra.core.hydra_config import HydraConfig

        if HydraConfig.initialized():
            overrides = list(HydraConfig.get().overrides.task)
    except ImportError:  # pragma: no cover - hydra is a dependency
        pass
    # a `+key=` that composed names a key of the schema (validation refuses others), and Hydra now
    # refuses `+` on an existing key: repeat it without the `+`
    drop = ("resume=", "runner.log_dir=") + (("runner.max_iterations=",) if iterations_left is not None else ())
    keep = [o.removeprefix("+") for o in overrides if not o.lstrip("+~").startswith(drop)]
    if iterations_left is not None:
        keep.append(f"runner.max_iterations={max(iterations_left, 1)}")
    return " ".join(["python train.py", *keep, f"resume={checkpoint}", f"runner.log_dir={log_dir}"])
