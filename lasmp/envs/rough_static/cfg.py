"""The R-S baseline's env config (locomotion on static rough terrain): `RoughStaticCfg` and its parts
(terrain, commands, pushes, rewards, termination), on top of the shared `lasmp.config.BaseEnvCfg`.

Hydra registers it as the `env` option `rough_static` (`lasmp/train_cfg.py`, from the task registry
`lasmp/envs/registry.py`). The rewards' entry, `RewardsCfg`, lives with the terms that read it
(`rewards.py`). This module never imports the env: `lasmp.envs.rough_static.env` imports it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from lasmp.config import BaseEnvCfg, ConfigError, check_positive, check_range
from lasmp.envs.rough_static.rewards import RewardsCfg


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
            check_positive(f"{p}.{name}", getattr(self, name))
        if self.resolution_m > 0.5:
            raise ConfigError(f"{p}.resolution_m must be <= 0.5 m, got {self.resolution_m}")
        for name in ("roughness_m", "feature_height_m", "spawn_margin_m"):
            check_positive(f"{p}.{name}", getattr(self, name), allow_zero=True)
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
        check_positive(f"{p}.resample_s", self.resample_s)
        if not 0.0 <= self.zero_command_fraction <= 1.0:
            raise ConfigError(
                f"{p}.zero_command_fraction must be in [0, 1], got {self.zero_command_fraction}"
            )
        check_range(f"{p}.lin_vel_x_mps", self.lin_vel_x_mps, -5.0, 5.0)
        check_range(f"{p}.lin_vel_y_mps", self.lin_vel_y_mps, -5.0, 5.0)
        check_range(f"{p}.ang_vel_z_rad_s", self.ang_vel_z_rad_s, -5.0, 5.0)


@dataclass
class PushCfg:
    enabled: bool = True
    interval_s: list[float] = field(default_factory=lambda: [4.0, 8.0])  # drawn per env, per push
    max_mps: float = 1.0  # |added horizontal trunk velocity| <= this

    def validate(self, p: str):
        check_range(f"{p}.interval_s", self.interval_s, 0.0)
        if self.interval_s[0] <= 0:
            raise ConfigError(f"{p}.interval_s must be > 0, got {list(self.interval_s)}")
        check_positive(f"{p}.max_mps", self.max_mps, allow_zero=True)


@dataclass
class TerminationCfg:
    max_tilt_rad: float = 1.0  # |roll| or |pitch| beyond this ends the episode (a fall)
    max_joint_vel_rad_s: float = 200.0  # beyond this the simulation is considered diverged (a fault)

    def validate(self, p: str):
        check_positive(f"{p}.max_tilt_rad", self.max_tilt_rad)
        check_positive(f"{p}.max_joint_vel_rad_s", self.max_joint_vel_rad_s)


@dataclass
class RoughStaticCfg(BaseEnvCfg):
    episode_length_s: float = 20.0
    terrain: TerrainCfg = field(default_factory=TerrainCfg)
    commands: CommandsCfg = field(default_factory=CommandsCfg)
    pushes: PushCfg = field(default_factory=PushCfg)
    rewards: RewardsCfg = field(default_factory=RewardsCfg)
    termination: TerminationCfg = field(default_factory=TerminationCfg)

    def validate(self, p: str = "env"):
        check_positive(f"{p}.episode_length_s", self.episode_length_s)
        super().validate(p)
