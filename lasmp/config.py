"""Configuration schemas shared by every task, their validation helpers and `build_env_cfg`.

A legged_gym-like hierarchy: `BaseEnvCfg` holds what every task shares (simulation, control,
observations, the initial state and the domain randomization); each task's schema extends it next to
its task with what differs: `MovingPlatformCfg` in `lasmp/envs/moving_platform/cfg.py` (platform,
trajectories, curriculum, rewards) and `RoughStaticCfg` in `lasmp/envs/rough_static/cfg.py` (terrain,
commands, pushes). This module imports nothing from `lasmp.envs`: the envs import their schemas, never
the other way round.

YAML files and Hydra overrides fill these schemas (`lasmp/train_cfg.py` registers them);
`build_env_cfg` merges a plain dict onto a schema's defaults (unknown keys are refused by OmegaConf,
naming the key) and `validate` checks every value range, naming the offending field. Units are in the
field names.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, is_dataclass
from typing import Any, TypeVar

from omegaconf import OmegaConf


class ConfigError(ValueError):
    """A configuration value is out of range or inconsistent; the message names the field."""


def check_range(
    name: str, lo_hi: tuple[float, float] | list[float], lo: float = -math.inf, hi: float = math.inf
):
    """Refuse a `[low, high]` pair that is not finite, not ordered or not within [lo, hi]."""
    if len(lo_hi) != 2:
        raise ConfigError(f"{name} must be a [low, high] pair, got {list(lo_hi)}")
    a, b = float(lo_hi[0]), float(lo_hi[1])
    if not (math.isfinite(a) and math.isfinite(b)) or a > b:
        raise ConfigError(f"{name} must be a finite [low, high] with low <= high, got {list(lo_hi)}")
    if a < lo or b > hi:
        raise ConfigError(f"{name} must lie within [{lo}, {hi}], got {list(lo_hi)}")


def check_positive(name: str, value: float, allow_zero: bool = False):
    """Refuse a non-finite value or one <= 0 (< 0 with `allow_zero`)."""
    ok = value >= 0 if allow_zero else value > 0
    if not (math.isfinite(value) and ok):
        raise ConfigError(f"{name} must be {'>= 0' if allow_zero else '> 0'}, got {value}")


def check_known_keys(cfg: Any, p: str = "") -> None:
    """Refuse an attribute that `cfg`'s dataclass (or a nested one) does not declare, naming it.

    Hydra's `+key=value` appends to a config in open-dict mode, and `OmegaConf.to_object` then sets
    the extra key as a plain attribute: a `+env.trajectory.fiel=x` typo would otherwise be ignored.
    The same catches `cfg.env.num_env = 8` in code.
    """
    declared = [f.name for f in fields(cfg)]
    unknown = sorted(set(vars(cfg)) - set(declared))
    if unknown:
        keys = [f"{p}.{name}" if p else name for name in unknown]
        raise ConfigError(
            f"unknown config key(s) {keys}; valid keys{f' of {p}' if p else ''}: {sorted(declared)}"
        )
    for name in declared:
        value = getattr(cfg, name)
        if is_dataclass(value):
            check_known_keys(value, f"{p}.{name}" if p else name)


def check_finite_values(cfg: Any, p: str = "") -> None:
    """Refuse NaN or an infinity in any number of `cfg` (nested dataclasses, lists, dicts), naming its
    key: a range check such as `learning_rate <= 0` lets NaN through, and no setting here means
    anything by an infinity."""
    for f in fields(cfg):
        _check_finite(getattr(cfg, f.name), f"{p}.{f.name}" if p else f.name)


def _check_finite(value: Any, key: str) -> None:
    if is_dataclass(value):
        check_finite_values(value, key)
    elif isinstance(value, Mapping):
        for k, v in value.items():
            _check_finite(v, f"{key}.{k}")
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            _check_finite(v, f"{key}[{i}]")
    elif isinstance(value, float) and not math.isfinite(value):
        raise ConfigError(f"{key} must be a finite number, got {value}")


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

    def validate(self, p: str):
        check_positive(f"{p}.dt_s", self.dt_s)
        if self.dt_s > 0.02:
            raise ConfigError(f"{p}.dt_s must be <= 0.02 s for stable contacts, got {self.dt_s}")
        if self.decimation < 1:
            raise ConfigError(f"{p}.decimation must be >= 1, got {self.decimation}")
        if self.num_threads < 0:
            raise ConfigError(f"{p}.num_threads must be >= 0 (0 = all cores), got {self.num_threads}")
        if self.solver_iterations < 1:
            raise ConfigError(f"{p}.solver_iterations must be >= 1, got {self.solver_iterations}")
        check_positive(f"{p}.solver_tolerance", self.solver_tolerance)
        if self.cone not in ("pyramidal", "elliptic"):
            raise ConfigError(f"{p}.cone must be 'pyramidal' or 'elliptic', got {self.cone!r}")
        check_positive(f"{p}.impratio", self.impratio)
        if self.noslip_iterations < 0:
            raise ConfigError(f"{p}.noslip_iterations must be >= 0, got {self.noslip_iterations}")
        if self.warp_contacts_per_env < 1 or self.warp_constraints_per_env < 1:
            raise ConfigError(f"{p}.warp_contacts_per_env and warp_constraints_per_env must be >= 1")


@dataclass
class ControlCfg:
    action_scale: float = 0.25  # q_target = q_nominal + action_scale * a (legged_gym's A1 value)
    action_clip: float = 100.0  # actions are clipped to +-action_clip before scaling (rsl_rl convention)

    def validate(self, p: str):
        check_positive(f"{p}.action_scale", self.action_scale)
        check_positive(f"{p}.action_clip", self.action_clip)


@dataclass
class ObservationsCfg:
    history_length: int = 20  # H (docs/method.md#inputs)
    clip: float = 100.0  # every observation is clipped to +-clip (a NaN guard, not a normalizer)

    def validate(self, p: str):
        if self.history_length < 1:
            raise ConfigError(f"{p}.history_length must be >= 1, got {self.history_length}")
        check_positive(f"{p}.clip", self.clip)


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

    def validate(self, p: str):
        check_range(f"{p}.trunk_mass_kg", self.trunk_mass_kg, 0.5, 50.0)
        check_range(f"{p}.com_shift_m", self.com_shift_m, -0.5, 0.5)
        check_range(f"{p}.foot_friction", self.foot_friction, 0.0, 5.0)
        check_range(f"{p}.joint_kp", self.joint_kp, 0.0, 500.0)
        check_range(f"{p}.joint_kd", self.joint_kd, 0.0, 50.0)
        check_range(f"{p}.platform_kp_factor", self.platform_kp_factor, 0.0, 100.0)
        check_range(f"{p}.platform_kd_factor", self.platform_kd_factor, 0.0, 100.0)


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

    @property
    def ranges(self) -> DomainRandRanges:
        return self.train if self.split == "train" else self.test

    def validate(self, p: str):
        if self.split not in ("train", "test"):
            raise ConfigError(f"{p}.split must be 'train' or 'test', got {self.split!r}")
        self.train.validate(f"{p}.train")
        self.test.validate(f"{p}.test")


@dataclass
class InitStateCfg:
    yaw_range_rad: list[float] = field(default_factory=lambda: [-math.pi, math.pi])
    foot_clearance_m: float = 0.001  # feet start this far above the surface: touching, never inside
    xy_offset_max_m: float = 0.0  # start uniformly in a disc of this radius around the centre (0: at it)

    def validate(self, p: str):
        check_range(f"{p}.yaw_range_rad", self.yaw_range_rad, -math.pi, math.pi)
        check_positive(f"{p}.foot_clearance_m", self.foot_clearance_m, allow_zero=True)
        if self.foot_clearance_m > 0.05:
            raise ConfigError(f"{p}.foot_clearance_m must be <= 0.05 m, got {self.foot_clearance_m}")
        check_positive(f"{p}.xy_offset_max_m", self.xy_offset_max_m, allow_zero=True)
        if self.xy_offset_max_m > 0.7:
            raise ConfigError(
                f"{p}.xy_offset_max_m must be <= 0.7 m (the robot must fit), got {self.xy_offset_max_m}"
            )


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

    def validate(self, p: str = "env"):
        check_known_keys(self, p)
        check_finite_values(self, p)
        if self.num_envs < 1:
            raise ConfigError(f"{p}.num_envs must be >= 1, got {self.num_envs}")
        if self.backend not in ("cpu", "warp"):
            raise ConfigError(f"{p}.backend must be 'cpu' or 'warp', got {self.backend!r}")
        for f in fields(self):
            value = getattr(self, f.name)
            if is_dataclass(value):
                value.validate(f"{p}.{f.name}")


EnvCfgT = TypeVar("EnvCfgT", bound=BaseEnvCfg)


def build_env_cfg(overrides: Mapping[str, Any] | None = None, *, schema: type[EnvCfgT]) -> EnvCfgT:
    """Defaults of `schema` (a task's env config, e.g. `MovingPlatformCfg`) merged with a nested dict of
    overrides, validated.

    Unknown keys raise `ConfigError` naming the key; values are type-checked by OmegaConf. This is where
    an env config is validated: the envs take the dataclass only and do not validate it again.
    """
    base = OmegaConf.structured(schema)
    try:
        merged = OmegaConf.merge(base, OmegaConf.create(overrides or {}))
    except Exception as err:  # omegaconf's ConfigKeyError / ValidationError carry the full key
        raise ConfigError(f"invalid environment config: {err}") from err
    cfg = OmegaConf.to_object(merged)
    cfg.validate()
    return cfg
