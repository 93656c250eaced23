"""Per-env intrinsic parameters (SPEC §6, Table B): drawn at reset, written into the Batch.

The robot's parameters are also the implicit privileged state x_imp = [trunk mass (1), CoM
shift (3), foot friction (1), Kp (12), Kd (12)] (29 numbers, SI units).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from lasmp.config import DomainRandRanges
from lasmp.envs.backends.cpu import CpuBatchSim
from lasmp.envs.scene import PLATFORM_JOINTS, PlatformGains
from lasmp.robots import a1


@dataclass
class Intrinsics:
    trunk_mass_kg: np.ndarray  # (n,)
    com_shift_m: np.ndarray  # (n, 3) shift of the trunk CoM from its nominal place, trunk frame
    foot_friction: np.ndarray  # (n,) sliding friction coefficient of all four feet
    joint_kp: np.ndarray  # (n, 12) N·m/rad
    joint_kd: np.ndarray  # (n, 12) N·m·s/rad
    platform_kp_factor: np.ndarray  # (n, 6) per platform axis, PLATFORM_JOINTS order
    platform_kd_factor: np.ndarray  # (n, 6)

    def x_imp(self) -> np.ndarray:
        """(n, 29) implicit privileged state."""
        return np.concatenate(
            [
                self.trunk_mass_kg[:, None],
                self.com_shift_m,
                self.foot_friction[:, None],
                self.joint_kp,
                self.joint_kd,
            ],
            axis=1,
        )


def nominal_intrinsics(n: int, kd_factor_ref: float) -> Intrinsics:
    return Intrinsics(
        trunk_mass_kg=np.full(n, a1.TRUNK_MASS_KG),
        com_shift_m=np.zeros((n, 3)),
        foot_friction=np.ones(n),
        joint_kp=np.full((n, 12), a1.KP_NOMINAL),
        joint_kd=np.full((n, 12), a1.KD_NOMINAL),
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


class IntrinsicsWriter:
    """Writes `Intrinsics` of some envs into the batch's per-simulation model fields."""

    def __init__(self, sim: CpuBatchSim, gains: PlatformGains):
        m = sim.model
        self._gains = gains
        self._trunk = m.body(a1.TRUNK_BODY_NAME).id
        self._trunk_ipos0 = m.body_ipos[self._trunk].copy()
        self._feet = np.array([m.geom(name).id for name in a1.FOOT_NAMES])
        self._joint_act = np.array([m.actuator(name).id for name in a1.JOINT_NAMES])
        self._plf_pos_act = np.array([m.actuator(f"{j}_pos").id for j in PLATFORM_JOINTS])
        self._plf_vel_act = np.array([m.actuator(f"{j}_vel").id for j in PLATFORM_JOINTS])
        self._body_mass = sim.expand("body_mass")
        self._body_ipos = sim.expand("body_ipos")
        self._geom_friction = sim.expand("geom_friction")
        self._gainprm = sim.expand("actuator_gainprm")
        self._biasprm = sim.expand("actuator_biasprm")
        assert m.actuator_biastype[self._joint_act[0]] == mujoco.mjtBias.mjBIAS_AFFINE

    def write(self, ids: np.ndarray, p: Intrinsics) -> None:
        ix = np.ix_(ids, self._joint_act)
        self._body_mass[ids, self._trunk] = p.trunk_mass_kg
        self._body_ipos[ids, self._trunk] = self._trunk_ipos0 + p.com_shift_m
        self._geom_friction[np.ix_(ids, self._feet, [0])] = p.foot_friction[:, None, None]
        # MuJoCo position actuator: force = kp * ctrl - kp * q - kd * q_dot
        self._gainprm[ix + (0,)] = p.joint_kp
        self._biasprm[ix + (1,)] = -p.joint_kp
        self._biasprm[ix + (2,)] = -p.joint_kd
        kp = self._gains.kp * p.platform_kp_factor
        kd = self._gains.kd * p.platform_kd_factor
        pos = np.ix_(ids, self._plf_pos_act)
        self._gainprm[pos + (0,)] = kp
        self._biasprm[pos + (1,)] = -kp
        vel = np.ix_(ids, self._plf_vel_act)  # velocity actuator: force = kd * ctrl - kd * v
        self._gainprm[vel + (0,)] = kd
        self._biasprm[vel + (2,)] = -kd
