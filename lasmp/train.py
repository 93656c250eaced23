"""Build the env, the runner and train: the logic behind `train.py`.

Run directories (`lasmp.rundir`): a training locks its directory; a new run is refused a directory
that holds a run. A resume (`resume=`) continues a run as `lasmp.resume` decides.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime
import os
import sys
from pathlib import Path

import torch
from omegaconf import OmegaConf

from lasmp.algo import distributed as dp
from lasmp.algo.checkpoint import CheckpointError
from lasmp.algo.runner import LasmpRunner, TrainingFaulted, TrainingInterrupted
from lasmp.atomic import atomic_open
from lasmp.config import ConfigError
from lasmp.envs import registry
from lasmp.envs.trajectories import TrajectoryFileError
from lasmp.resume import Resume, check_run_dir, explicit_keys, hydra_overrides, resume_command
from lasmp.rundir import RunDirError, claim
from lasmp.train_cfg import TrainCfg, rsl_rl_cfg, to_plain, to_train_cfg


def seed_everything(seed: int) -> None:
    torch.manual_seed(seed)


def make_env(cfg: TrainCfg):
    """The task's env (`lasmp.envs.registry`), its tensors where its physics runs (cpu backend: the CPU,
    even with the learner on a GPU; warp: `cfg.device`)."""
    return registry.make_env(cfg.task, cfg.env, cfg.device)


def make_runner(cfg: TrainCfg, log_dir: str | None, rank: int = 0) -> LasmpRunner:
    """The env and the runner of `cfg`; in a data-parallel job, rank k's envs and torch streams are
    seeded with seed + k (its own physics, trajectories and curriculum draws); the saved config keeps
    the job's seed."""
    if cfg.device.startswith("cuda") and not torch.cuda.is_available():
        raise ConfigError(
            f"device={cfg.device} but torch sees no CUDA device (install a CUDA build of torch)"
        )
    if cfg.torch_threads > 0:
        torch.set_num_threads(cfg.torch_threads)
    seed_everything(cfg.seed + rank)
    env = make_env(
        cfg if rank == 0 else dataclasses.replace(cfg, env=dataclasses.replace(cfg.env, seed=cfg.seed + rank))
    )
    return LasmpRunner(
        env,
        rsl_rl_cfg(cfg),
        log_dir=log_dir,
        device=cfg.device,
        full_config=to_plain(cfg),
        max_fault_fraction=cfg.runner.max_fault_fraction,
        keep_full=cfg.runner.keep_full,
    )


def default_log_dir(cfg: TrainCfg) -> str:
    stamp = datetime.datetime.now().strftime("%Y-%m-%d_%H-%M-%S")
    return os.path.join("logs", cfg.task, cfg.policy.name, stamp)


def train(cfg, explicit: set[str] | None = None) -> LasmpRunner:
    """Train as `cfg` says: build, resume (`lasmp.resume`), learn. `explicit`: on resume, the keys
    the command line set (None: every key of `cfg`)."""
    cfg = to_train_cfg(cfg)
    resume = Resume.check(cfg, explicit) if cfg.resume else None  # fails before anything is built
    cfg = resume.cfg if resume else cfg
    ranks = dp.ranks_from_env()  # torchrun: rank 0 alone holds the run directory, logs and saves
    if ranks.distributed:
        cfg.device = dp.rank_device(cfg.device, ranks)
        dp.setup(ranks, cfg.device)
    data = resume.data if resume else None
    log_dir = Path(cfg.runner.log_dir or (Path(data["path"]).parent if data else default_log_dir(cfg)))
    owner = claim(log_dir, check_run_dir(log_dir, data)) if ranks.is_main else contextlib.nullcontext()
    say = print if ranks.is_main else (lambda *a, **k: None)
    with owner:
        runner = make_runner(cfg, str(log_dir) if ranks.is_main else None, ranks.rank)
        if resume:
            resume.restore(runner, say)
        first = runner.current_learning_iteration
        last = first + cfg.runner.max_iterations - 1  # the iteration this command ends at
        if ranks.is_main:  # only now, with everything checked, the run directory's config
            with atomic_open(log_dir / "config.yaml", "w") as f:
                f.write(OmegaConf.to_yaml(to_plain(cfg)))
        processes = f" x {ranks.world_size} processes" if ranks.distributed else ""
        span = f" ({first}\u2013{last})" if cfg.runner.max_iterations else ""
        say(
            f"training {cfg.task} / {cfg.policy.name}: {cfg.env.num_envs} envs{processes}, {cfg.runner.max_iterations} "
            f"iterations{span}, logs in {log_dir}",
            flush=True,
        )
        try:
            runner.learn(cfg.runner.max_iterations)
        except TrainingInterrupted as stop:
            if stop.checkpoint:
                # on a resume, runner.max_iterations counts the iterations still to run: those left
                left = last - stop.iteration
                print(
                    f"{stop}\nresume with:\n  {resume_command(stop.checkpoint, str(log_dir), left)}",
                    flush=True,
                )
            raise
    return runner


# what a user can meet: bad input (exit 2) and a run that cannot go on (exit 1), each said in one line
BAD_INPUT = (CheckpointError, ConfigError, RunDirError, TrajectoryFileError)
CANNOT_GO_ON = (TrainingFaulted, FloatingPointError, OSError)


def main(cfg, overrides: list[str] | None = None) -> int:
    """train.py: train `cfg`, composed by Hydra from `overrides` (None: Hydra's own, when it runs);
    return the exit code. Failures a user can meet print one line, no traceback."""
    try:
        if overrides is None:
            overrides = hydra_overrides()
        resuming = getattr(cfg, "resume", None) and overrides is not None
        explicit = explicit_keys(overrides) if resuming else None
        train(cfg, explicit)
    except TrainingInterrupted as stop:  # checkpoint written and resume command printed
        return 128 + stop.signum
    except BAD_INPUT as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except CANNOT_GO_ON as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # Ctrl-C before training started (the runner handles it during training)
        print("interrupted before training started: nothing saved", file=sys.stderr)
        return 130
    finally:
        dp.teardown()
    return 0
