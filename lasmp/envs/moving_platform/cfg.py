"""The moving-platform task's env config: `MovingPlatformCfg` and its parts (platform, trajectories,
curriculum, rewards, termination), on top of the shared `lasmp.config.base.BaseEnvCfg`.

Hydra registers it as the `env` option `moving_platform` (`lasmp/config/train.py`, from the task registry
`lasmp/envs/registry.py`). The rewards' entry, `RewardsCfg`, lives with the terms that read it
(`rewards.py`). This module imports those and the trajectory splines (to check kind and degree), never
the env: `lasmp.envs.moving_platform.env` imports this module.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from lasmp.config.base import MAX_JOINT_VEL, BaseEnvCfg
from lasmp.config.checks import Bound, ConfigError
from lasmp.envs import trajectories as trj
from lasmp.envs.moving_platform.rewards import RewardsCfg

PLATFORM_BOUNDS = {
    "size_m": Bound(0, 100, "m: up to a ship's deck", open_lo=True),
    "mass_kg": Bound(0, 1e7, "kg: 1e5 already makes the robot's push negligible", open_lo=True),
    "friction": Bound(
        0, 5, "as the feet's (domain_rand foot_friction <= 5); rubber on rubber is 1 to 2", open_lo=True
    ),
    "omega_n_rad_s": Bound(
        0, 100, "rad/s: stiffer, the drive rings faster than the physics step resolves", open_lo=True
    ),
    "damping_ratio": Bound(0, 10, "past 10 the drive is so overdamped it barely follows", open_lo=True),
    "kd_factor_ref": Bound(0, 100, "as domain_rand's platform_kd_factor, within [0, 100]", open_lo=True),
}


@dataclass
class PlatformCfg:
    # width, length, height (docs/environment.md#scene)
    size_m: list[float] = field(default_factory=lambda: [2.0, 2.0, 0.2])
    # (ours) so heavy that the robot does not disturb it at the soft gains below: kp = M omega_n^2, so
    # the robot's weight sags it only m_robot g / kp (docs/world.md#the-platform-drive)
    mass_kg: float = 1.0e5
    friction: float = 1.0  # surface friction; a contact uses the larger of foot and platform values
    # The paper's platform gains are unitless factors (Table B). We read the stiffness factor as
    # kp / M in s^-2 per axis (M the platform's mass or inertia about the axis): at factor 1 the axis
    # is a 2nd-order system of natural frequency omega_n_rad_s. The damping factor scales
    # kd = 2 zeta M omega_n / kd_factor_ref, so the paper's ~0.025 gives damping ratio zeta (its literal
    # reading, zeta ~ 0.01, would leave the platform ringing). omega_n is calibrated against the paper's
    # Stand Still row (bench/calibrate_world.py): docs/world.md#the-platform-drive
    omega_n_rad_s: float = 1.2
    damping_ratio: float = 0.7  # (ours) at kd factor == kd_factor_ref
    kd_factor_ref: float = 0.025  # midpoint of the paper's training damping factor range
    # False (ours, calibrated): a PD on the position target only, force = kp (x_ref - x) - kd v, as a
    # simulator's position drive (Isaac Gym's DOF targets) does; the platform then follows the
    # reference as a 2nd-order low-pass filter. True: force = kp (x_ref - x) + kd (v_ref - v).
    velocity_feedforward: bool = False

    BOUNDS = PLATFORM_BOUNDS

    def check_rules(self, p: str):
        if len(self.size_m) != 3:
            raise ConfigError(
                f"{p}.size_m must be three lengths (width, length, height), got {list(self.size_m)}"
            )


TRAJECTORY_BOUNDS = {
    "duration_s": Bound(0, 3600, "s: an episode of up to an hour", open_lo=True),
    "hold_s": Bound(0, 3600, "s: a hold of up to an hour"),
}


@dataclass
class TrajectoryCfg:
    split: str = "train"  # waypoint coordinate ranges: train | test (identical coordinates, N differs)
    duration_s: float = 10.0  # T, also the episode length
    # waypoints as control points of a B-spline (docs/trajectories.md#construction), or "interpolating"
    # (through them: harder)
    kind: str = "approximating"
    degree: int = 10  # approximating B-spline degree: calibrated to the paper's 7.12 m / 0.69 m/s (ours)
    file: str | None = None  # a trajectory file (lasmp-trajectories .npz): episodes replay its rows in order
    # (ours, LAS-MP+, training only) an episode runs this long past T while the reference holds its last
    # pose: the platform, steepest at T in most references, settles there, and a fall the time-out would
    # cut off counts. Evaluation and play set it to 0 (Xi_eval's episodes stay T long)
    hold_s: float = 0.0

    BOUNDS = TRAJECTORY_BOUNDS
    CHOICES = {"split": ("train", "test")}

    def check_rules(self, p: str):
        try:
            trj.SplineSpec(self.kind, self.degree)
        except ValueError as err:
            raise ConfigError(f"{p}.kind / {p}.degree: {err}") from None

    @property
    def spline(self) -> trj.SplineSpec:
        return trj.SplineSpec(self.kind, self.degree)


LEVELS = Bound(1, 50, "waypoints N over the trajectory: at 50 in 10 s the platform turns every 0.2 s")
CURRICULUM_BOUNDS = {
    "level_min": LEVELS,
    "level_max": LEVELS,
    "promote_success_rate": Bound(0, 1, "a success rate", open_lo=True),
    "window_episodes": Bound(
        1, 1_000_000, "episodes the success rate is measured over: a window a run never fills never promotes"
    ),
    "replay_lower_fraction": Bound(
        0, 1, "a share of episodes; at 1 the level would never be played", open_hi=True
    ),
}


@dataclass
class CurriculumCfg:
    enabled: bool = True  # False: N is drawn uniformly from the split's range every episode
    level_min: int = 5
    level_max: int = 15
    promote_success_rate: float = 0.8
    window_episodes: int = 200  # (ours) episodes at the current level over which success is measured
    replay_lower_fraction: float = 0.2  # (ours) share of episodes that replay mastered levels

    BOUNDS = CURRICULUM_BOUNDS

    def check_rules(self, p: str):
        if self.level_min > self.level_max:
            raise ConfigError(
                f"{p}: need level_min <= level_max, got {p}.level_min={self.level_min}, "
                f"{p}.level_max={self.level_max}"
            )


TERMINATION_BOUNDS = {
    "fall_below_top_m": Bound(
        -1, 0.5, "m above the top surface: the trunk stands 0.37 m up, higher every step is a fall"
    ),
    "footprint_margin_m": Bound(
        -1, 10, "m beyond the 2 m platform's edge: -1 shrinks it to nothing, 10 m off it the robot has fallen"
    ),
    "max_joint_vel_rad_s": MAX_JOINT_VEL,
}


@dataclass
class TerminationCfg:
    fall_below_top_m: float = 0.0  # a trunk CoM lower than the top surface + this counts as a fall
    footprint_margin_m: float = 0.0  # a trunk CoM beyond the platform's edge + this counts as off
    max_joint_vel_rad_s: float = 200.0  # beyond this the simulation is considered diverged (a fault)

    BOUNDS = TERMINATION_BOUNDS


@dataclass
class MovingPlatformCfg(BaseEnvCfg):
    platform: PlatformCfg = field(default_factory=PlatformCfg)
    trajectory: TrajectoryCfg = field(default_factory=TrajectoryCfg)
    curriculum: CurriculumCfg = field(default_factory=CurriculumCfg)
    rewards: RewardsCfg = field(default_factory=RewardsCfg)
    termination: TerminationCfg = field(default_factory=TerminationCfg)
