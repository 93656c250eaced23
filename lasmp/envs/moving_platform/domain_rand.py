"""The platform's part of the per-env intrinsic parameters (SPEC §6, Table B): drawn at reset on the
host (numpy) with the robot's (`lasmp.envs.robot.Intrinsics`), written into the physics backend's
per-env model fields here: the robot's, then the platform's per-axis PD gains.
"""

from __future__ import annotations

import torch

from lasmp.envs.moving_platform.scene import PlatformGains
from lasmp.envs.robot import Intrinsics, RobotIntrinsicsWriter


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
