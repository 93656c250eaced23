"""The moving-platform task's per-env intrinsic parameters (the paper's Table B:
docs/environment.md#domain-randomization-the-papers-table-b): the robot's
(`lasmp.envs.robot.RobotIntrinsics`) and the platform's per-axis PD gain factors, drawn at reset on
the host (numpy) and written into the physics backend's per-env model fields: the robot's, then the
platform's PD gains. The robot layer knows nothing of a platform: its part is drawn and written there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from lasmp.config.base import DomainRandRanges
from lasmp.envs.moving_platform.scene import PlatformGains
from lasmp.envs.robot import (
    RobotIntrinsics,
    RobotIntrinsicsWriter,
    nominal_robot_intrinsics,
    sample_robot_intrinsics,
)


@dataclass
class Intrinsics(RobotIntrinsics):
    """One draw of Table B per env: the robot's parameters and the platform's per-axis PD gain factors
    (unitless), which scale the gains of `PlatformGains`."""

    platform_kp_factor: np.ndarray  # (n, 6) per platform axis, PLATFORM_JOINTS order
    platform_kd_factor: np.ndarray  # (n, 6)


def nominal_intrinsics(n: int, kd_factor_ref: float) -> Intrinsics:
    """n robots as published on platforms at their reference gains (kp factor 1, kd factor
    `kd_factor_ref`)."""
    return Intrinsics(
        **vars(nominal_robot_intrinsics(n)),
        platform_kp_factor=np.ones((n, 6)),
        platform_kd_factor=np.full((n, 6), kd_factor_ref),
    )


def sample_intrinsics(n: int, r: DomainRandRanges, rng: np.random.Generator) -> Intrinsics:
    """n uniform draws from the ranges `r`, on the host: the robot's, then the platform's factors (the
    random stream's order)."""
    robot = sample_robot_intrinsics(n, r, rng)
    return Intrinsics(
        **vars(robot),
        platform_kp_factor=rng.uniform(r.platform_kp_factor[0], r.platform_kp_factor[1], size=(n, 6)),
        platform_kd_factor=rng.uniform(r.platform_kd_factor[0], r.platform_kd_factor[1], size=(n, 6)),
    )


class IntrinsicsWriter(RobotIntrinsicsWriter):
    """Writes `Intrinsics` of some envs into the batch's per-simulation model fields: the robot's,
    then the platform's PD gains."""

    def __init__(self, sim, gains: PlatformGains, plf_act_pos: torch.Tensor, plf_act_vel: torch.Tensor):
        super().__init__(sim)
        self._gains = gains
        self._plf_pos_act, self._plf_vel_act = plf_act_pos, plf_act_vel

    def write(self, ids: torch.Tensor, p: Intrinsics) -> None:
        super().write(ids, p)
        kp = self.tensor(self._gains.kp * p.platform_kp_factor)
        kd = self.tensor(self._gains.kd * p.platform_kd_factor)
        rows = ids[:, None]
        self._gainprm[rows, self._plf_pos_act, 0] = kp
        self._biasprm[rows, self._plf_pos_act, 1] = -kp
        # velocity actuator: force = kd * ctrl - kd * v
        self._gainprm[rows, self._plf_vel_act, 0] = kd
        self._biasprm[rows, self._plf_vel_act, 2] = -kd
