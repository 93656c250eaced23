"""What a training needs to fit before anything is built or written: memory for its envs, disk for its
first checkpoints. Why up front: allocating 100,000 envs takes minutes before it fails, and a disk too
small fails at the first save, after the first iterations."""

from __future__ import annotations

import contextlib
import dataclasses
import os
import shutil
from pathlib import Path

from lasmp.algo.runner import LasmpRunner
from lasmp.config import ConfigError
from lasmp.envs import registry
from lasmp.inputs import size_in_words
from lasmp.rundir import RunDirError
from lasmp.train_cfg import TrainCfg

# no env needs more than this (a probe env measures the real figure only where this bound does not fit)
ENV_BYTES_BOUND = 1 << 20
FLOAT_BYTES = 4  # the rollout storage and the observations are float32


def available_memory() -> tuple[int, str] | None:
    """The memory a new allocation can get, in bytes, and where the figure comes from: the kernel's
    MemAvailable (/proc/meminfo), lowered to a cgroup's limit less its usage where one is set (a
    container); None where neither can be read."""
    found = None
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    found = (int(line.split()[1]) * 1024, "MemAvailable in /proc/meminfo")
    except (OSError, ValueError):
        with contextlib.suppress(ValueError, OSError, AttributeError):
            found = (os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"), "free physical pages")
    with contextlib.suppress(OSError, ValueError):
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        if limit != "max":
            left = int(limit) - int(Path("/sys/fs/cgroup/memory.current").read_text())
            if found is None or left < found[0]:
                found = (max(left, 0), "this cgroup's memory.max less its memory.current")
    return found


def env_bytes(cfg: TrainCfg) -> dict[str, int]:
    """A lower bound of the memory one env of `cfg` takes, in bytes by part, measured on a
    probe env of one: its MuJoCo data's buffer (MjData.nbuffer: state, positions, velocities,
    contacts' space; the arena MuJoCo reserves on top is not counted, as it is touched only as needed),
    its observation (every group, float32), and its share of the rollout storage the learner keeps
    (runner.num_steps_per_env steps of that observation, the actions' sample, mean and std, and six
    scalars: reward, done, value, log-probability, return, advantage). The learner's update copies
    and the networks are left out: the bound only refuses what cannot fit."""
    one = dataclasses.replace(cfg.env, num_envs=1)
    probe = registry.make_env(cfg.task, one, cfg.device)
    try:
        physics = 0
        batch = getattr(probe.sim, "batch", None)
        if batch is not None and hasattr(batch, "get_data"):
            physics = int(batch.get_data(0).nbuffer)
        obs = probe.get_observations()
        obs_floats = sum(v[0].numel() for v in obs.values())
        step_floats = obs_floats + 3 * probe.num_actions + 6
    finally:
        with contextlib.suppress(Exception):
            probe.close()
    return {
        "physics": physics,
        "observation": obs_floats * FLOAT_BYTES,
        "rollout storage": cfg.runner.num_steps_per_env * step_floats * FLOAT_BYTES,
    }


def check_memory(cfg: TrainCfg, processes: int = 1) -> None:
    """Refuse an env.num_envs whose envs cannot fit in memory before any env is built, with the
    estimate (`env_bytes`, a lower bound) and how it was computed: allocating them would take minutes
    before failing. `processes`: this machine's ranks of a torchrun job, each with its own envs. The
    cpu backend only (warp's envs live on the GPU)."""
    if getattr(cfg.env, "backend", "cpu") != "cpu":
        return
    found = available_memory()
    envs = cfg.env.num_envs * processes
    if found is None or envs * ENV_BYTES_BOUND <= found[0]:
        return  # certainly fits (or nothing to compare with): no probe env
    available, source = found
    measured = env_bytes(cfg)
    per_env = sum(measured.values())
    parts = ", ".join(f"{name} {size_in_words(n)}" for name, n in measured.items())
    if envs * per_env <= available:
        return
    ranks = f" x {processes} processes" if processes > 1 else ""
    raise ConfigError(
        f"env.num_envs={cfg.env.num_envs}{ranks} cannot fit in memory: it needs at least {size_in_words(envs * per_env)} "
        f"({size_in_words(per_env)} per env: {parts}; measured on one env), and {size_in_words(available)} is available "
        f"({source}). Give env.num_envs={max(available // (per_env * processes), 1):,} or fewer"
    )


def check_disk_space(runner: LasmpRunner, log_dir: Path) -> None:
    """Refuse a run directory whose disk cannot hold the run's first two checkpoints, before anything
    is written: else the run would fail at its first saves. Their size is a lower bound
    (`LasmpRunner.checkpoint_size`), so only a disk certain to fail is refused; space that runs out
    later is met by the saves' own errors, naming the file."""
    free = shutil.disk_usage(log_dir).free
    size = runner.checkpoint_size()
    if free < 2 * size + START_BYTES:
        raise RunDirError(
            f"runner.log_dir={log_dir}: its disk has {size_in_words(free)} free, and this run needs at least "
            f"{size_in_words(2 * size + START_BYTES)}: two checkpoints of at least {size_in_words(size)} each (a save is written "
            f"beside the previous one before it replaces or thins it) and about {size_in_words(START_BYTES)} of config "
            "and TensorBoard files. Free space there, or give another runner.log_dir"
        )


START_BYTES = 64 << 10
