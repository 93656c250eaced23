"""Per-env intrinsic parameters (SPEC §6, Table B): drawn at reset on the host (numpy), written
into the physics backend's per-env model fields.

The robot's part (and the implicit privileged state x_imp it makes) is `lasmp.envs.robot`'s
`RobotIntrinsics`; this task adds the platform's per-axis PD gain factors.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from lasmp.config import DomainRandRanges
from lasmp.envs.robot import RobotIntrinsics, RobotIntrinsicsWriter
from lasmp.envs.scene import PlatformGains
from lasmp.robots import a1


@dataclass
class Intrinsics(RobotIntrinsics):
    """The robot's parameters and the platform's per-axis PD gain factors (unitless)."""

    platform_kp_factor: np.ndarray  # (n, 6) per platform axis, PLATFORM_JOINTS order
    platform_kd_factor: np.ndarray  # (n, 6)


def nominal_intrinsics(n: int, kd_factor_ref: float) -> Intrinsics:
    return Intrinsics(
        trunk_mass_kg=np.full(n, a1.TRUNK_MASS_KG),
        com_shift_m=np.zeros((n, 3)),
        foot_friction=np.ones(n),
        joint_kp=np.full((n, 12), a1.KP_NOMINAL_NM_PER_RAD),
        joint_kd=np.full((n, 12), a1.KD_NOMINAL_NM_S_PER_RAD),
        platform_kp_factor=np.ones((n, 6)),
        platform_kd_factor=np.full((n, 6), kd_factor_ref),
    )


def sample_intrinsics(n: int, r: DomainRandRanges, rng: np.random.Generator) -> Intrinsics:
    def u(lo_hi, *shape):
        return rng.uniform(lo_hi[0], lo_hi[1], size=(n, *shape))

    return Intrinsics(
        trunk_mass_kg=u(r.trunk_mass_kg),
        com_shift_m=u(r.com_shift_m, 3),
        foot_friction=u(r.foot_friction),
        joint_kp=u(r.joint_kp, 12),
        joint_kd=u(r.joint_kd, 12),
        platform_kp_factor=u(r.platform_kp_factor, 6),
        platform_kd_factor=u(r.platform_kd_factor, 6),
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
