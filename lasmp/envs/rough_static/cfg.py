"""The R-S baseline's env config (locomotion on static rough terrain): `RoughStaticCfg` and its parts
(terrain, commands, pushes, rewards, termination), on top of the shared `lasmp.config.base.BaseEnvCfg`.

Hydra registers it as the `env` option `rough_static` (`lasmp/config/train.py`, from the task registry
`lasmp/envs/registry.py`). The rewards' entry, `RewardsCfg`, lives with the terms that read it
(`rewards.py`). This module never imports the env: `lasmp.envs.rough_static.env` imports it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from lasmp.config.base import MAX_JOINT_VEL, BaseEnvCfg
from lasmp.config.checks import Bound, ConfigError, check_seed_key
from lasmp.envs.rough_static.rewards import RewardsCfg

TERRAIN_BOUNDS = {
    "spawn_margin_m": Bound(0, 50, "m from the edges: half the largest terrain"),
    "size_m": Bound(0, 200, "m: ten 20 s episodes' walk at 1 m/s", open_lo=True),
    "resolution_m": Bound(
        0.01, 0.5, "m: finer than 1 cm is below a foot's 2 cm radius, coarser than 0.5 m flattens every step"
    ),
    "roughness_m": Bound(0, 0.2, "m: more than half the A1's leg length is no ground it can walk"),
    "feature_height_m": Bound(0, 0.3, "m: a step higher than 0.3 m is beyond the A1's legs"),
    "smoothing_cells": Bound(
        1, 100, "cells of the box filter: wider smooths the noise flat at any resolution"
    ),
    "tile_m": Bound(0, 200, "m: no wider than the terrain", open_lo=True),
    "friction": Bound(0, 5, "as the feet's (domain_rand foot_friction <= 5)", open_lo=True),
}
MAX_TERRAIN_CELLS = 1 << 22  # 2048 x 2048


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

    BOUNDS = TERRAIN_BOUNDS

    def check_rules(self, p: str):
        check_seed_key(f"{p}.seed", self.seed)
        if len(self.size_m) != 2 or min(self.size_m) <= 2 * self.spawn_margin_m:
            raise ConfigError(f"{p}.size_m must be two lengths > 2 * spawn_margin_m, got {list(self.size_m)}")
        cells = math.prod(round(x / self.resolution_m) + 1 for x in self.size_m)
        if cells > MAX_TERRAIN_CELLS:
            raise ConfigError(
                f"{p}.size_m / {p}.resolution_m give a heightfield of {cells:,} cells; at most "
                f"{MAX_TERRAIN_CELLS:,} (it is built and handed to MuJoCo cell by cell)"
            )
        probs = [float(x) for x in self.tile_kind_probs]
        if len(probs) != 3 or min(probs) < 0 or not math.isclose(sum(probs), 1.0):
            raise ConfigError(
                f"{p}.tile_kind_probs must be 3 probabilities in [0, 1] summing to 1, got {probs}"
            )


COMMAND_RANGE = Bound(-5, 5, "m/s and rad/s: beyond the A1's top speed of about 3 m/s")
COMMANDS_BOUNDS = {
    "resample_s": Bound(0, 3600, "s: up to an hour, the longest episode", open_lo=True),
    "zero_command_fraction": Bound(0, 1, "a share of commands"),
}


@dataclass
class CommandsCfg:
    resample_s: float = 5.0  # a new command every this many seconds (and at reset)
    zero_command_fraction: float = 0.2  # share of commands that are exactly zero (stand still)
    lin_vel_x_mps: list[float] = field(default_factory=lambda: [-1.0, 1.0])  # body frame
    lin_vel_y_mps: list[float] = field(default_factory=lambda: [-0.5, 0.5])
    ang_vel_z_rad_s: list[float] = field(default_factory=lambda: [-1.0, 1.0])

    BOUNDS = COMMANDS_BOUNDS
    RANGES = dict.fromkeys(("lin_vel_x_mps", "lin_vel_y_mps", "ang_vel_z_rad_s"), COMMAND_RANGE)


@dataclass
class PushCfg:
    enabled: bool = True
    interval_s: list[float] = field(default_factory=lambda: [4.0, 8.0])  # drawn per env, per push
    max_mps: float = 1.0  # |added horizontal trunk velocity| <= this

    BOUNDS = {"max_mps": Bound(0, 5, "m/s added to the trunk: 5 throws the A1 off its feet")}
    RANGES = {"interval_s": Bound(0, 3600, "s between pushes", open_lo=True)}


TERMINATION_BOUNDS = {
    "max_tilt_rad": Bound(0, 3.15, "rad of roll or pitch: a half turn", open_lo=True),
    "max_joint_vel_rad_s": MAX_JOINT_VEL,
}


@dataclass
class TerminationCfg:
    max_tilt_rad: float = 1.0  # |roll| or |pitch| beyond this ends the episode (a fall)
    max_joint_vel_rad_s: float = 200.0  # beyond this the simulation is considered diverged (a fault)

    BOUNDS = TERMINATION_BOUNDS


@dataclass
class RoughStaticCfg(BaseEnvCfg):
    episode_length_s: float = 20.0
    terrain: TerrainCfg = field(default_factory=TerrainCfg)
    commands: CommandsCfg = field(default_factory=CommandsCfg)
    pushes: PushCfg = field(default_factory=PushCfg)
    rewards: RewardsCfg = field(default_factory=RewardsCfg)
    termination: TerminationCfg = field(default_factory=TerminationCfg)
    # A compatibility switch that keeps the study's R-S rows (results/study/rs) reproducible: with
    # domain randomization on, each reset also draws and discards the 12 uniforms per env that the
    # moving platform's gain factors take, so that a seed gives the random stream those runs were
    # trained with. False skips the draws: the same distributions, another stream for each seed.
    study_rng_stream: bool = True

    BOUNDS = {
        **BaseEnvCfg.BOUNDS,
        "episode_length_s": Bound(0, 3600, "s: an episode of up to an hour", open_lo=True),
    }
