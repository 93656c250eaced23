"""Configuration schemas (dataclasses) for the environments.

A legged_gym-like hierarchy: `BaseEnvCfg` holds what every task shares (simulation, control,
observations); `MovingPlatformCfg` adds the platform, trajectories, randomization, curriculum
and rewards. YAML files and Hydra overrides fill these schemas; `build_env_cfg` merges a plain
dict onto the defaults (unknown keys are refused by OmegaConf, naming the key) and `validate`
checks every value range, naming the offending field. Units are in the field names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, is_dataclass
from typing import Any

from omegaconf import OmegaConf

from lasmp.envs import trajectories as trj
from lasmp.envs.moving_platform.rewards import DEFAULT_REWARD_WEIGHTS, REWARD_TERMS
from lasmp.envs.rough_static import rewards as rough_rewards


class ConfigError(ValueError):
    """A configuration value is out of range or inconsistent; the message names the field."""


def _range(name: str, lo_hi: tuple[float, float] | list[float], lo: float = -math.inf, hi: float = math.inf):
    if len(lo_hi) != 2:
        raise ConfigError(f"{name} must be a [low, high] pair, got {list(lo_hi)}")
    a, b = float(lo_hi[0]), float(lo_hi[1])
    if not (math.isfinite(a) and math.isfinite(b)) or a > b:
        raise ConfigError(f"{name} must be a finite [low, high] with low <= high, got {list(lo_hi)}")
    if a < lo or b > hi:
        raise ConfigError(f"{name} must lie within [{lo}, {hi}], got {list(lo_hi)}")


def _positive(name: str, value: float, allow_zero: bool = False):
    ok = value >= 0 if allow_zero else value > 0
    if not (math.isfinite(value) and ok):
        raise ConfigError(f"{name} must be {'>= 0' if allow_zero else '> 0'}, got {value}")


@dataclass
class SimCfg:
    dt_s: float = 0.005  # physics step (ours)
    decimation: int = 4  # physics steps per policy step -> policy dt 0.02 s (ours)
    num_threads: int = 0  # Batch worker threads; 0 = all cores
    solver_iterations: int = 20  # fewer than MuJoCo's 100: contacts converge well before (ours)
    cone: str = "pyramidal"  # MuJoCo friction cone: pyramidal (MuJoCo's default) | elliptic
    impratio: float = 1.0  # frictional-to-normal constraint impedance ratio (MuJoCo's default 1)
    noslip_iterations: int = 0  # MuJoCo's no-slip post-solver passes (0 = off): removes soft-contact creep

    def validate(self, p: str):
        _positive(f"{p}.dt_s", self.dt_s)
        if self.dt_s > 0.02:
            raise ConfigError(f"{p}.dt_s must be <= 0.02 s for stable contacts, got {self.dt_s}")
        if self.decimation < 1:
            raise ConfigError(f"{p}.decimation must be >= 1, got {self.decimation}")
        if self.num_threads < 0:
            raise ConfigError(f"{p}.num_threads must be >= 0 (0 = all cores), got {self.num_threads}")
        if self.solver_iterations < 1:
            raise ConfigError(f"{p}.solver_iterations must be >= 1, got {self.solver_iterations}")
        if self.cone not in ("pyramidal", "elliptic"):
            raise ConfigError(f"{p}.cone must be 'pyramidal' or 'elliptic', got {self.cone!r}")
        _positive(f"{p}.impratio", self.impratio)
        if self.noslip_iterations < 0:
            raise ConfigError(f"{p}.noslip_iterations must be >= 0, got {self.noslip_iterations}")


@dataclass
class ControlCfg:
    action_scale: float = 0.25  # q_target = q_nominal + action_scale * a (legged_gym's A1 value)
    action_clip: float = 100.0  # actions are clipped to +-action_clip before scaling (rsl_rl convention)

    def validate(self, p: str):
        _positive(f"{p}.action_scale", self.action_scale)
        _positive(f"{p}.action_clip", self.action_clip)


@dataclass
class ObservationsCfg:
    history_length: int = 20  # H, SPEC §7
    clip: float = 100.0  # every observation is clipped to +-clip (a NaN guard, not a normalizer)

    def validate(self, p: str):
        if self.history_length < 1:
            raise ConfigError(f"{p}.history_length must be >= 1, got {self.history_length}")
        _positive(f"{p}.clip", self.clip)


@dataclass
class DomainRandRanges:
    """Table B of the paper: one set for training, one for testing."""

    trunk_mass_kg: list[float] = field(default_factory=lambda: [4.0, 5.0])
    com_shift_m: list[float] = field(default_factory=lambda: [-0.2, 0.2])  # per axis x, y, z
    foot_friction: list[float] = field(default_factory=lambda: [0.8, 1.2])
    joint_kp: list[float] = field(default_factory=lambda: [36.0, 44.0])  # per joint
    joint_kd: list[float] = field(default_factory=lambda: [0.8, 1.2])  # per joint
    platform_kp_factor: list[float] = field(default_factory=lambda: [1.0, 1.5])  # per axis
    platform_kd_factor: list[float] = field(default_factory=lambda: [0.02, 0.03])  # per axis

    def validate(self, p: str):
        _range(f"{p}.trunk_mass_kg", self.trunk_mass_kg, 0.5, 50.0)
        _range(f"{p}.com_shift_m", self.com_shift_m, -0.5, 0.5)
        _range(f"{p}.foot_friction", self.foot_friction, 0.0, 5.0)
        _range(f"{p}.joint_kp", self.joint_kp, 0.0, 500.0)
        _range(f"{p}.joint_kd", self.joint_kd, 0.0, 50.0)
        _range(f"{p}.platform_kp_factor", self.platform_kp_factor, 0.0, 100.0)
        _range(f"{p}.platform_kd_factor", self.platform_kd_factor, 0.0, 100.0)


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
        _range(f"{p}.yaw_range_rad", self.yaw_range_rad, -math.pi, math.pi)
        _positive(f"{p}.foot_clearance_m", self.foot_clearance_m, allow_zero=True)
        if self.foot_clearance_m > 0.05:
            raise ConfigError(f"{p}.foot_clearance_m must be <= 0.05 m, got {self.foot_clearance_m}")
        _positive(f"{p}.xy_offset_max_m", self.xy_offset_max_m, allow_zero=True)
        if self.xy_offset_max_m > 0.7:
            raise ConfigError(f"{p}.xy_offset_max_m must be <= 0.7 m (the robot must fit), got {self.xy_offset_max_m}")


@dataclass
class PlatformCfg:
    size_m: list[float] = field(default_factory=lambda: [2.0, 2.0, 0.2])  # width, length, height, SPEC §3
    # (ours) so heavy that the robot does not disturb it at the soft gains below: kp = M omega_n^2, so
    # the robot's weight sags it m_robot g / kp = 1.2 mm at factor 1 (800 kg would sag 15 cm)
    mass_kg: float = 1.0e5
    friction: float = 1.0  # surface friction; a contact uses the larger of foot and platform values
    # The paper's platform gains are unitless factors (Table B). We read the stiffness factor as
    # kp / M in s^-2 per axis (M the platform's mass or inertia about the axis): at factor 1 the axis
    # is a 2nd-order system of natural frequency omega_n_rad_s = 1 rad/s, and the training range
    # 1.0-1.5 gives 1.0-1.22 rad/s. The damping factor scales kd = 2 zeta M omega_n / kd_factor_ref,
    # so the paper's ~0.025 gives damping ratio zeta (its literal reading, zeta ~ 0.01, would leave
    # the platform ringing). Calibrated against the paper's Stand Still row: README "The paper's world".
    omega_n_rad_s: float = 1.0
    damping_ratio: float = 0.7  # (ours) at kd factor == kd_factor_ref
    kd_factor_ref: float = 0.025  # midpoint of the paper's training damping factor range
    # False (ours, calibrated): a PD on the position target only, force = kp (x_ref - x) - kd v, as a
    # simulator's position drive (Isaac Gym's DOF targets) does; the platform then follows the
    # reference as a 2nd-order low-pass filter. True: force = kp (x_ref - x) + kd (v_ref - v).
    velocity_feedforward: bool = False

    def validate(self, p: str):
        if len(self.size_m) != 3 or min(self.size_m) <= 0:
            raise ConfigError(f"{p}.size_m must be three positive lengths, got {list(self.size_m)}")
        for name in ("mass_kg", "friction", "omega_n_rad_s", "damping_ratio", "kd_factor_ref"):
            _positive(f"{p}.{name}", getattr(self, name))


@dataclass
class TrajectoryCfg:
    split: str = "train"  # waypoint coordinate ranges: train | test (identical coordinates, N differs)
    duration_s: float = 10.0  # T, also the episode length
    # waypoints as control points of a B-spline (SPEC §4), or "interpolating" (through them: harder)
    kind: str = "approximating"
    degree: int = 10  # approximating B-spline degree: calibrated to the paper's 7.12 m / 0.69 m/s (ours)
    file: str | None = None  # a trajectory file (lasmp-trajectories .npz): episodes replay its rows in order

    def validate(self, p: str):
        if self.split not in ("train", "test"):
            raise ConfigError(f"{p}.split must be 'train' or 'test', got {self.split!r}")
        _positive(f"{p}.duration_s", self.duration_s)
        try:
            trj.SplineSpec(self.kind, self.degree)
        except ValueError as err:
            raise ConfigError(f"{p}.kind / {p}.degree: {err}") from None

    @property
    def spline(self) -> trj.SplineSpec:
        return trj.SplineSpec(self.kind, self.degree)


@dataclass
class CurriculumCfg:
    enabled: bool = True  # False: N is drawn uniformly from the split's range every episode
    level_min: int = 5
    level_max: int = 15
    promote_success_rate: float = 0.8
    window_episodes: int = 200  # (ours) episodes at the current level over which success is measured
    replay_lower_fraction: float = 0.2  # (ours) share of episodes that replay mastered levels

    def validate(self, p: str):
        if not 1 <= self.level_min <= self.level_max:
            raise ConfigError(
                f"{p}: need 1 <= level_min <= level_max, got {self.level_min}, {self.level_max}"
            )
        if not 0 < self.promote_success_rate <= 1:
            raise ConfigError(f"{p}.promote_success_rate must be in (0, 1], got {self.promote_success_rate}")
        if self.window_episodes < 1:
            raise ConfigError(f"{p}.window_episodes must be >= 1, got {self.window_episodes}")
        if not 0 <= self.replay_lower_fraction < 1:
            raise ConfigError(
                f"{p}.replay_lower_fraction must be in [0, 1), got {self.replay_lower_fraction}"
            )


@dataclass
class RewardsCfg:
    weights: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_REWARD_WEIGHTS))
    sigma_center_m: float = 1.2  # k2
    sigma_alignment: float = 0.3  # k4
    sigma_level_rad: float = 0.2  # k6
    sigma_height_m: float = 0.1  # k8
    h_des_m: float = 0.37  # desired trunk height, measured from `h_des_from`
    # where h_des is measured from (SPEC §13): "centre" = the platform frame's origin, its CoM 0.1 m
    # below the top (the trunk 0.27 m above the surface); "top" = the top surface (0.37 m above it).
    # "top" matches the paper's Stand Still height violation best but drives the policy to a tall,
    # tippy stance that never masters level 5; "centre" promotes (README "The paper's world").
    h_des_from: str = "centre"
    f_tol_n: float = 50.0
    t_swing_des_s: float = 0.1
    t_contact_des_s: float = 0.5

    def validate(self, p: str):
        unknown = sorted(set(self.weights) - set(REWARD_TERMS))
        if unknown:
            raise ConfigError(
                f"{p}.weights: unknown reward term(s) {unknown}; valid terms: {sorted(REWARD_TERMS)}"
            )
        for name, w in self.weights.items():
            if not math.isfinite(float(w)):
                raise ConfigError(f"{p}.weights.{name} must be finite, got {w}")
        if self.h_des_from not in ("top", "centre"):
            raise ConfigError(f"{p}.h_des_from must be 'top' or 'centre', got {self.h_des_from!r}")
        for f in fields(self):
            if f.name not in ("weights", "h_des_from"):
                _positive(f"{p}.{f.name}", getattr(self, f.name))

    def h_des_p_m(self, plf_top_m: float) -> float:
        """h_des in the platform frame (origin at its CoM), m: what rewards and metrics compare p_body_p,z to."""
        return self.h_des_m + (plf_top_m if self.h_des_from == "top" else 0.0)


@dataclass
class TerminationCfg:
    fall_below_top_m: float = 0.0  # a trunk CoM lower than the top surface + this counts as a fall
    footprint_margin_m: float = 0.0  # a trunk CoM beyond the platform's edge + this counts as off
    max_joint_vel_rad_s: float = 200.0  # beyond this the simulation is considered diverged (a fault)

    def validate(self, p: str):
        _positive(f"{p}.max_joint_vel_rad_s", self.max_joint_vel_rad_s)


@dataclass
class BaseEnvCfg:
    num_envs: int = 256
    seed: int = 0
    sim: SimCfg = field(default_factory=SimCfg)
    control: ControlCfg = field(default_factory=ControlCfg)
    observations: ObservationsCfg = field(default_factory=ObservationsCfg)

    def validate(self, p: str = "env"):
        if self.num_envs < 1:
            raise ConfigError(f"{p}.num_envs must be >= 1, got {self.num_envs}")
        for f in fields(self):
            value = getattr(self, f.name)
            if is_dataclass(value):
                value.validate(f"{p}.{f.name}")


@dataclass
class MovingPlatformCfg(BaseEnvCfg):
    init_state: InitStateCfg = field(default_factory=InitStateCfg)
    domain_rand: DomainRandCfg = field(default_factory=DomainRandCfg)
    platform: PlatformCfg = field(default_factory=PlatformCfg)
    trajectory: TrajectoryCfg = field(default_factory=TrajectoryCfg)
    curriculum: CurriculumCfg = field(default_factory=CurriculumCfg)
    rewards: RewardsCfg = field(default_factory=RewardsCfg)
    termination: TerminationCfg = field(default_factory=TerminationCfg)


def build_env_cfg(overrides: dict[str, Any] | None = None, schema: type = MovingPlatformCfg):
    """Defaults of `schema` merged with a (nested) dict of overrides, validated.

    Unknown keys raise `ConfigError` naming the key; values are type-checked by OmegaConf.
    """
    base = OmegaConf.structured(schema)
    try:
        merged = OmegaConf.merge(base, OmegaConf.create(overrides or {}))
    except Exception as err:  # omegaconf's ConfigKeyError / ValidationError carry the full key
        raise ConfigError(f"invalid environment config: {err}") from err
    cfg = OmegaConf.to_object(merged)
    cfg.validate()
    return cfg


# ---- the R-S baseline: locomotion on static rough terrain (lasmp.envs.rough_static) ----------


@dataclass
class TerrainCfg:
    size_m: list[float] = field(default_factory=lambda: [24.0, 24.0])  # x, y extent of the heightfield
    resolution_m: float = 0.1  # grid spacing
    seed: int = 0  # the terrain's own seed (the ground is the same for every env seed)
    roughness_m: float = 0.04  # amplitude of the smoothed uniform noise, +-m
    smoothing_cells: int = 3  # box-filter width of the noise, cells
    tile_m: float = 4.0  # side of the square tiles that carry a slope or step
    tile_kind_probs: list[float] = field(default_factory=lambda: [0.4, 0.3, 0.3])  # rough, slope, step
    feature_height_m: float = 0.08  # highest slope peak / step
    friction: float = 1.0
    spawn_margin_m: float = 2.0  # spawn points keep this far from the edges

    def validate(self, p: str):
        if len(self.size_m) != 2 or min(self.size_m) <= 2 * self.spawn_margin_m:
            raise ConfigError(f"{p}.size_m must be two lengths > 2 * spawn_margin_m, got {list(self.size_m)}")
        for name in ("resolution_m", "tile_m", "friction"):
            _positive(f"{p}.{name}", getattr(self, name))
        if self.resolution_m > 0.5:
            raise ConfigError(f"{p}.resolution_m must be <= 0.5 m, got {self.resolution_m}")
        for name in ("roughness_m", "feature_height_m", "spawn_margin_m"):
            _positive(f"{p}.{name}", getattr(self, name), allow_zero=True)
        if self.roughness_m > 0.2 or self.feature_height_m > 0.3:
            raise ConfigError(
                f"{p}: roughness_m <= 0.2 and feature_height_m <= 0.3 m, got "
                f"{self.roughness_m}, {self.feature_height_m}"
            )
        if self.smoothing_cells < 1:
            raise ConfigError(f"{p}.smoothing_cells must be >= 1, got {self.smoothing_cells}")
        probs = [float(x) for x in self.tile_kind_probs]
        if len(probs) != 3 or min(probs) < 0 or not math.isclose(sum(probs), 1.0):
            raise ConfigError(f"{p}.tile_kind_probs must be 3 probabilities summing to 1, got {probs}")


@dataclass
class CommandsCfg:
    resample_s: float = 5.0  # a new command every this many seconds (and at reset)
    zero_command_fraction: float = 0.2  # share of commands that are exactly zero (stand still)
    lin_vel_x_mps: list[float] = field(default_factory=lambda: [-1.0, 1.0])  # body frame
    lin_vel_y_mps: list[float] = field(default_factory=lambda: [-0.5, 0.5])
    ang_vel_z_rad_s: list[float] = field(default_factory=lambda: [-1.0, 1.0])

    def validate(self, p: str):
        _positive(f"{p}.resample_s", self.resample_s)
        if not 0.0 <= self.zero_command_fraction <= 1.0:
            raise ConfigError(
                f"{p}.zero_command_fraction must be in [0, 1], got {self.zero_command_fraction}"
            )
        _range(f"{p}.lin_vel_x_mps", self.lin_vel_x_mps, -5.0, 5.0)
        _range(f"{p}.lin_vel_y_mps", self.lin_vel_y_mps, -5.0, 5.0)
        _range(f"{p}.ang_vel_z_rad_s", self.ang_vel_z_rad_s, -5.0, 5.0)


@dataclass
class PushCfg:
    enabled: bool = True
    interval_s: list[float] = field(default_factory=lambda: [4.0, 8.0])  # drawn per env, per push
    max_mps: float = 1.0  # |added horizontal trunk velocity| <= this

    def validate(self, p: str):
        _range(f"{p}.interval_s", self.interval_s, 0.0)
        if self.interval_s[0] <= 0:
            raise ConfigError(f"{p}.interval_s must be > 0, got {list(self.interval_s)}")
        _positive(f"{p}.max_mps", self.max_mps, allow_zero=True)


@dataclass
class RoughRewardsCfg:
    weights: dict[str, float] = field(default_factory=lambda: dict(rough_rewards.DEFAULT_REWARD_WEIGHTS))
    tracking_sigma: float = 0.25
    air_time_target_s: float = 0.5

    def validate(self, p: str):
        terms = rough_rewards.REWARD_TERMS
        unknown = sorted(set(self.weights) - set(terms))
        if unknown:
            raise ConfigError(f"{p}.weights: unknown reward term(s) {unknown}; valid terms: {sorted(terms)}")
        for name, w in self.weights.items():
            if not math.isfinite(float(w)):
                raise ConfigError(f"{p}.weights.{name} must be finite, got {w}")
        _positive(f"{p}.tracking_sigma", self.tracking_sigma)
        _positive(f"{p}.air_time_target_s", self.air_time_target_s, allow_zero=True)


@dataclass
class RoughTerminationCfg:
    max_tilt_rad: float = 1.0  # |roll| or |pitch| beyond this ends the episode (a fall)
    max_joint_vel_rad_s: float = 200.0  # beyond this the simulation is considered diverged (a fault)

    def validate(self, p: str):
        _positive(f"{p}.max_tilt_rad", self.max_tilt_rad)
        _positive(f"{p}.max_joint_vel_rad_s", self.max_joint_vel_rad_s)


@dataclass
class RoughStaticCfg(BaseEnvCfg):
    episode_length_s: float = 20.0
    terrain: TerrainCfg = field(default_factory=TerrainCfg)
    commands: CommandsCfg = field(default_factory=CommandsCfg)
    pushes: PushCfg = field(default_factory=PushCfg)
    init_state: InitStateCfg = field(default_factory=InitStateCfg)
    domain_rand: DomainRandCfg = field(default_factory=DomainRandCfg)  # platform factors are unused
    rewards: RoughRewardsCfg = field(default_factory=RoughRewardsCfg)
    termination: RoughTerminationCfg = field(default_factory=RoughTerminationCfg)

    def validate(self, p: str = "env"):
        _positive(f"{p}.episode_length_s", self.episode_length_s)
        super().validate(p)
