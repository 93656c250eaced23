"""What a training needs to fit before it is allocated or written: memory for its envs, rollouts and
networks (every size setting, against every memory limit: `lasmp.io.memory`), checked once the env's
model is built and before its envs' data are allocated; disk for its first checkpoints. Why up front:
allocating 100,000 envs takes minutes before it fails, and a disk too small fails at the first save,
after the first iterations."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import mujoco

from lasmp.algo.runner import LasmpRunner
from lasmp.config.checks import ConfigError
from lasmp.config.train import TrainCfg, validates
from lasmp.envs import registry
from lasmp.io.inputs import size_in_words
from lasmp.io.memory import available_memory
from lasmp.io.rundir import RunDirError

NUM_ACTIONS = 12  # the A1's joint targets, every task's action
FLOAT_BYTES = 4  # the rollout storage, the observations and the networks are float32
# a network's parameter is held four times over while learning: the weights, their gradient, Adam's two moments
PARAM_COPIES = 4
Built = tuple[mujoco.MjModel, dict[str, int]]  # an env's model and its observation groups' widths


def env_bytes(cfg: TrainCfg, built: Built | None = None) -> dict[str, int]:
    """A lower bound of the memory one env of `cfg` takes, in bytes by part, from the task's model and
    its declared observation widths (`built`: the env's, as its construction hands them to its
    `check_fit`; else made here, without an env): the MuJoCo data's buffer of one env
    (MjData.nbuffer: state, positions, velocities, contacts' space; the arena MuJoCo reserves on top is
    not counted, as it is touched only as needed), its observation (every group, float32;
    env.observations.history_length sets the history's), the two spare history buffers the env writes
    in turn, and its share of the rollout storage the learner keeps (runner.num_steps_per_env steps of
    that observation, the actions' sample, mean and std, and six scalars: reward, done, value,
    log-probability, return, advantage). The learner's update copies are left out: the bound only
    refuses what cannot fit."""
    if built is None:
        env_class = registry.env_class(cfg.task)
        built = env_class.build_model(cfg.env), env_class.observation_widths(cfg.env)
    model, widths = built
    physics = mujoco.MjData(model).nbuffer
    obs_floats = sum(widths.values())
    spares = 2 * widths["history"]
    step_floats = obs_floats + 3 * NUM_ACTIONS + 6
    return {
        "physics": physics,
        "observation": obs_floats * FLOAT_BYTES,
        "history buffers": spares * FLOAT_BYTES,
        "rollout storage": cfg.runner.num_steps_per_env * step_floats * FLOAT_BYTES,
    }


def network_bytes(cfg: TrainCfg) -> int:
    """A lower bound of the learner's networks, in bytes: the actor's, the critic's and the implicit
    encoder's hidden-to-hidden layers (their inputs and outputs, and the estimators, left out), each
    parameter held PARAM_COPIES times."""
    p = cfg.policy
    params = sum(
        a * b + b
        for dims in (p.actor_hidden_dims, p.critic_hidden_dims, p.encoder_hidden_dims)
        for a, b in zip(dims, dims[1:], strict=False)
    )
    return params * PARAM_COPIES * FLOAT_BYTES


@dataclasses.dataclass
class MemoryNeed:
    """A lower bound of what a training takes on this machine, in bytes, by what it scales with."""

    per_env: dict[str, int]  # one env's parts (`env_bytes`)
    envs: int  # every env of every process
    networks: int  # every process's networks (`network_bytes`)
    validation: int  # rank 0's validation env (lasmp.cli.build.make_validator: moving_platform, interval > 0)

    @property
    def total(self) -> int:
        return self.envs + self.networks + self.validation


def memory_need(cfg: TrainCfg, processes: int = 1, built: Built | None = None) -> MemoryNeed:
    """What a training of `cfg` takes at least: every size setting counts (env.num_envs,
    runner.num_steps_per_env, the observation history, the networks' widths, the validation env's
    runner.validation_episodes). `processes`: the machine's ranks, each with its own envs and networks."""
    networks = network_bytes(cfg)
    per_env = env_bytes(cfg, built)
    one = sum(per_env.values())
    validating = validates(cfg.task, cfg.runner.validation_interval)
    played = one - per_env["rollout storage"]  # the validation env keeps no rollout
    return MemoryNeed(
        per_env=per_env,
        envs=processes * cfg.env.num_envs * one,
        networks=processes * networks,
        validation=cfg.runner.validation_episodes * played if validating else 0,
    )


def check_memory(
    cfg: TrainCfg, processes: int = 1, *, built: Built | None = None, available: tuple[int, str] | None = None
) -> None:
    """Refuse a training whose envs, rollout storage and networks cannot fit in memory before any env's
    data is allocated (`built`: the model and observation widths of the env being built,
    `lasmp.cli.build.make_env`; else made here), with the estimate (`memory_need`, a lower bound) and the limit it meets
    (`lasmp.io.memory.available_memory`, or `available` where given): allocating them would take minutes
    before failing. `processes`: this machine's ranks of a torchrun job. The cpu backend only (warp's
    envs live on the GPU)."""
    if getattr(cfg.env, "backend", "cpu") != "cpu":
        return
    found = available or available_memory()
    if found is None:
        return  # nothing to compare with
    need = memory_need(cfg, processes, built)
    left, source = found
    if need.total <= left:
        return
    one = sum(need.per_env.values())
    terms = [f"{size_in_words(need.envs)} for the envs"]
    terms += [
        f"{size_in_words(n)} for the {k}"
        for k, n in (("networks", need.networks), ("validation", need.validation))
        if n
    ]
    parts = ", ".join(f"{name} {size_in_words(n)}" for name, n in need.per_env.items())
    fits = (left - need.networks - need.validation) // (processes * one)
    advice = (
        f"Give env.num_envs={fits:,} or fewer"
        if fits >= 1
        else "The networks and the validation env alone do not fit: give smaller policy.*_hidden_dims or "
        "runner.validation_episodes"
    )
    ranks = f" x {processes} processes" if processes > 1 else ""
    raise ConfigError(
        f"env.num_envs={cfg.env.num_envs}{ranks} cannot fit in memory: this training needs at least "
        f"{size_in_words(need.total)} ({' + '.join(terms)}; {size_in_words(one)} per env: {parts}; from one env's model "
        f"and observation widths), and {size_in_words(left)} is available ({source}). {advice}"
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
