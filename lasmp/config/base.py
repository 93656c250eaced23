"""Configuration schemas shared by every task, and `build_env_cfg`.

A legged_gym-like hierarchy: `BaseEnvCfg` holds what every task shares (simulation, control,
observations, the initial state and the domain randomization); each task's schema extends it next to
its task with what differs: `MovingPlatformCfg` in `lasmp/envs/moving_platform/cfg.py` (platform,
trajectories, curriculum, rewards) and `RoughStaticCfg` in `lasmp/envs/rough_static/cfg.py` (terrain,
commands, pushes). This module imports nothing from `lasmp.envs`: the envs import their schemas, never
the other way round.

YAML files and Hydra overrides fill these schemas (`lasmp/config/train.py` registers them);
`build_env_cfg` merges a plain dict onto a schema's defaults (unknown keys are refused by OmegaConf,
naming the key) and `lasmp.config.checks.check_config` checks every value, naming the offending field,
by the limits each class declares. Units are in the field names.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, TypeVar

from omegaconf import OmegaConf

from lasmp.config.checks import Bound, ConfigError, check_config, check_seed_key

MAX_POLICY_DT_S = 0.1
POLICY_DT_WHY = (
    f"the policy period dt_s x decimation at most {MAX_POLICY_DT_S} s: slower control cannot keep the balance, "
    "and a policy step's physics runs as one call that a signal cannot interrupt"
)
SIM_BOUNDS = {
    "dt_s": Bound(
        1e-4, 0.02, "the physics step, s: longer makes contacts unstable, shorter costs more than it resolves"
    ),
    "num_threads": Bound(0, 1024, "Batch worker threads, 0 = all cores; 1024 is more than any machine has"),
    "solver_iterations": Bound(1, 1000, "MuJoCo's default is 100; each costs a pass over every constraint"),
    "solver_tolerance": Bound(0, 1e-3, "above 1e-3 the solver stops before contacts converge", open_lo=True),
    "impratio": Bound(
        0, 100, "MuJoCo's friction-to-normal impedance ratio: useful values are 1 to tens", open_lo=True
    ),
    "noslip_iterations": Bound(
        0, 100, "no-slip passes, 0 = off: 2 remove the creep, each costs a solver pass"
    ),
    "warp_contacts_per_env": Bound(1, 4096, "contact slots MuJoCo Warp preallocates per env on the GPU"),
    "warp_constraints_per_env": Bound(
        1, 65536, "constraint rows MuJoCo Warp preallocates per env on the GPU"
    ),
}


@dataclass
class SimCfg:
    dt_s: float = 0.005  # physics step (ours)
    decimation: int = 4  # physics steps per policy step -> policy dt 0.02 s (ours)
    num_threads: int = 0  # Batch worker threads; 0 = all cores
    solver_iterations: int = 20  # fewer than MuJoCo's 100: contacts converge well before (ours)
    solver_tolerance: float = 1e-8  # MuJoCo's default; MuJoCo Warp raises it to at least 1e-6
    cone: str = "elliptic"  # pyramidal | elliptic; elliptic (ours): the same mu whichever way a foot slips
    impratio: float = 1.0  # friction/normal impedance ratio; 1 (ours): at 10 the stance jitters, slides early
    noslip_iterations: int = 2  # no-slip passes (0 = off); 2 (ours): without, feet creep at any tilt
    warp_contacts_per_env: int = 64  # warp only: contact slots per env (MuJoCo Warp preallocates)
    warp_constraints_per_env: int = 256  # warp only: constraint rows per env

    BOUNDS = SIM_BOUNDS
    CHOICES = {"cone": ("pyramidal", "elliptic")}

    def check_rules(self, p: str):
        longest = MAX_POLICY_DT_S / self.dt_s
        Bound(1, int(longest + 1e-9), POLICY_DT_WHY).check(f"{p}.decimation", self.decimation, integer=True)


CONTROL_BOUNDS = {
    "action_scale": Bound(
        0, 2, "rad of joint target per action unit: at 2 a unit action spans a joint's range", open_lo=True
    ),
    "action_clip": Bound(0, 1000, "action units: at 1000 it clips nothing a policy outputs", open_lo=True),
}


@dataclass
class ControlCfg:
    action_scale: float = 0.25  # q_target = q_nominal + action_scale * a (legged_gym's A1 value)
    action_clip: float = 100.0  # actions are clipped to +-action_clip before scaling (rsl_rl convention)

    BOUNDS = CONTROL_BOUNDS


# the history estimators' two convolutions (lasmp/modules/estimator.py: kernels 6 and 4, strides 2 and 2)
# need this many steps of history
MIN_HISTORY_LENGTH = 12


OBSERVATIONS_BOUNDS = {
    "history_length": Bound(
        MIN_HISTORY_LENGTH,
        500,
        f"policy steps of o^H: the estimators' convolutions need {MIN_HISTORY_LENGTH}; 500 is 10 s at 50 Hz, an episode",
    ),
    "clip": Bound(0, 1e4, "a NaN and runaway guard: no observation comes near 1e4", open_lo=True),
}


@dataclass
class ObservationsCfg:
    history_length: int = 20  # H (docs/method.md#inputs)
    clip: float = 100.0  # every observation is clipped to +-clip (a NaN guard, not a normalizer)

    BOUNDS = OBSERVATIONS_BOUNDS


DOMAIN_RAND_BOUNDS = {
    "trunk_mass_kg": Bound(0.5, 50, "kg: ten times the A1's trunk, 4.7"),
    "com_shift_m": Bound(-0.5, 0.5, "m per axis: beyond the trunk's half-length"),
    "foot_friction": Bound(0, 5, "rubber on rubber is 1 to 2"),
    "joint_kp": Bound(0, 500, "N m/rad: over ten times the A1's 40"),
    "joint_kd": Bound(0, 50, "N m s/rad: fifty times the A1's 1"),
    "platform_kp_factor": Bound(0, 100, "times the drive's stiffness"),
    "platform_kd_factor": Bound(0, 100, "times the drive's damping at kd_factor_ref"),
}


@dataclass
class DomainRandRanges:
    """Table B of the paper: one set for training, one for testing. The platform factors are the
    moving-platform task's (its `domain_rand.py`); they stay in the table both tasks share so that every
    saved config keeps its keys (the R-S baseline, which has no platform, never reads them)."""

    trunk_mass_kg: list[float] = field(default_factory=lambda: [4.0, 5.0])
    com_shift_m: list[float] = field(default_factory=lambda: [-0.2, 0.2])  # per axis x, y, z
    foot_friction: list[float] = field(default_factory=lambda: [0.8, 1.2])
    joint_kp: list[float] = field(default_factory=lambda: [36.0, 44.0])  # per joint
    joint_kd: list[float] = field(default_factory=lambda: [0.8, 1.2])  # per joint
    platform_kp_factor: list[float] = field(default_factory=lambda: [1.0, 1.5])  # per axis
    platform_kd_factor: list[float] = field(default_factory=lambda: [0.02, 0.03])  # per axis

    RANGES = DOMAIN_RAND_BOUNDS


def _test_ranges() -> DomainRandRanges:
    return DomainRandRanges(
        trunk_mass_kg=[3.5, 5.5],
        com_shift_m=[-0.25, 0.25],
        foot_friction=[0.7, 1.3],
        joint_kp=[32.0, 48.0],
        joint_kd=[0.6, 1.4],
        platform_kp_factor=[0.5, 2.0],
        platform_kd_factor=[0.01, 0.04],
    )


@dataclass
class DomainRandCfg:
    enabled: bool = True  # False: every env gets the nominal parameters
    split: str = "train"  # which of the two tables below is drawn from: train | test
    train: DomainRandRanges = field(default_factory=DomainRandRanges)
    test: DomainRandRanges = field(default_factory=_test_ranges)

    CHOICES = {"split": ("train", "test")}


INIT_STATE_BOUNDS = {
    "foot_clearance_m": Bound(
        0, 0.05, "m above the surface: touching, never inside; higher, the robot drops"
    ),
    "xy_offset_max_m": Bound(0, 0.7, "m from the centre: the robot must fit on the platform"),
}


@dataclass
class InitStateCfg:
    yaw_range_rad: list[float] = field(default_factory=lambda: [-math.pi, math.pi])
    foot_clearance_m: float = 0.001  # feet start this far above the surface: touching, never inside
    xy_offset_max_m: float = 0.0  # start uniformly in a disc of this radius around the centre (0: at it)

    BOUNDS = INIT_STATE_BOUNDS
    RANGES = {"yaw_range_rad": Bound(-math.pi, math.pi, "rad: a full turn")}


# a fault threshold of both tasks' termination
MAX_JOINT_VEL = Bound(
    0,
    1000,
    "rad/s: 1000 is 50 times the A1's motors' speed, a diverged state; tiny faults every step",
    open_lo=True,
)
# the physics backends, each made by lasmp.envs.backends.make_backend (`env.backend`)
BACKENDS = ("cpu", "warp")
# a million envs: about 100 GiB at their ~100 KiB each (the memory check refuses fewer that do not fit)
MAX_ENVS = 1 << 20


@dataclass
class BaseEnvCfg:
    num_envs: int = 256
    seed: int = 0
    backend: str = "cpu"  # physics: cpu (mujoco.batch) | warp (MuJoCo Warp; pip install -e ".[gpu]")
    sim: SimCfg = field(default_factory=SimCfg)
    control: ControlCfg = field(default_factory=ControlCfg)
    observations: ObservationsCfg = field(default_factory=ObservationsCfg)
    init_state: InitStateCfg = field(default_factory=InitStateCfg)
    domain_rand: DomainRandCfg = field(default_factory=DomainRandCfg)

    BOUNDS = {"num_envs": Bound(1, MAX_ENVS, "a million envs take ~100 GiB")}
    CHOICES = {"backend": BACKENDS}

    def check_rules(self, p: str):
        check_seed_key(f"{p}.seed", self.seed)


EnvCfgT = TypeVar("EnvCfgT", bound=BaseEnvCfg)


def build_env_cfg(overrides: Mapping[str, Any] | None = None, *, schema: type[EnvCfgT]) -> EnvCfgT:
    """Defaults of `schema` (a task's env config, e.g. `MovingPlatformCfg`) merged with a nested dict of
    overrides, validated.

    Unknown keys raise `ConfigError` naming the key; values are type-checked by OmegaConf. This is where
    an env config is validated: the envs take the dataclass only and do not validate it again.
    """
    cfg = merge_env_cfg(overrides, schema=schema)
    check_config(cfg, "env")
    return cfg


def merge_env_cfg(overrides: Mapping[str, Any] | None = None, *, schema: type[EnvCfgT]) -> EnvCfgT:
    """`build_env_cfg` less its validation: for `lasmp.config.train.to_train_cfg`, which validates the env
    with the rest of the training config (once)."""
    base = OmegaConf.structured(schema)
    try:
        merged = OmegaConf.merge(base, OmegaConf.create(overrides or {}))
    except Exception as err:  # omegaconf's ConfigKeyError / ValidationError carry the full key
        raise ConfigError(f"invalid environment config: {err}") from err
    return OmegaConf.to_object(merged)


def flatten(tree, prefix: str = "") -> dict:
    """{"a.b": leaf} of nested dicts (lists are leaves)."""
    if not isinstance(tree, dict):
        return {prefix: tree}
    out = {}
    for key, value in tree.items():
        out.update(flatten(value, f"{prefix}.{key}" if prefix else str(key)))
    return out
