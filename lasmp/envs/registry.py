"""The one table of tasks: task name -> its env class, which names its config schema (`cfg_class`).

Everything that knows the tasks reads it: the Hydra `env` options and the check of `task=`
(`lasmp/config/train.py`), the env a run or a checkpoint builds (`make_env`); `cfg/task/<name>.yaml`
names a task of it. A new task is a line here. Not in `lasmp/envs/__init__.py`: the task envs
import modules of that package, which would then import them back.
"""

from __future__ import annotations

from lasmp.config.base import BaseEnvCfg
from lasmp.config.checks import ConfigError
from lasmp.envs.base_env import BaseEnv, CheckFit
from lasmp.envs.moving_platform.env import MovingPlatformEnv
from lasmp.envs.rough_static.env import RoughStaticEnv

TASKS: dict[str, type[BaseEnv]] = {
    "moving_platform": MovingPlatformEnv,
    "rough_static": RoughStaticEnv,
}


def env_class(task: str) -> type[BaseEnv]:
    """The env class of `task`; ConfigError naming the valid tasks for an unknown one."""
    if task not in TASKS:
        raise ConfigError(f"task must be one of {list(TASKS)}, got {task!r}")
    return TASKS[task]


def env_schema(task: str) -> type[BaseEnvCfg]:
    """The env config dataclass of `task`."""
    return env_class(task).cfg_class


def make_env(task: str, cfg: BaseEnvCfg, device: str = "cpu", check_fit: CheckFit | None = None) -> BaseEnv:
    """The env of `task` on its validated config `cfg`. `device` is where the learner runs: the env's
    tensors live where its physics runs, on the CPU with the cpu backend (the runner moves
    observations to the learner), on `device` with warp. `check_fit`: `BaseEnv`'s."""
    return env_class(task)(cfg, device=device if cfg.backend == "warp" else "cpu", check_fit=check_fit)
