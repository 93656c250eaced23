"""Reads the task's scene (`scene.py`: the robot on its platform) from the batch's raw arrays into the
named physical quantities of docs/environment.md#frames and docs/method.md#inputs: `read_scene` ->
`SceneReadout`, the robot's (`read_robot` -> `RobotReadout` of `lasmp.envs.robot`) and the platform's,
relative to each other, at the addresses of `SceneIndex` (the robot's `RobotIndex` and the platform's).

Everything here is torch, on the backend's device and dtype, (num_envs, ...). Frames: `w` world, `p` platform (origin at
the platform's CoM = its geometric centre), `b` trunk (as `lasmp.envs.robot` defines it: origin at the
trunk link's origin).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import torch

from lasmp.envs.moving_platform.scene import PLATFORM_JOINTS
from lasmp.envs.robot import (
    RobotIndex,
    RobotReadout,
    as_slice,
    read_robot,
    sensor_columns,
    sensor_index,
    take_columns,
)
from lasmp.envs.rotations import mat_from_euler_zyx, rotate_inv
from lasmp.robots import a1


@dataclass
class SceneReadout(RobotReadout):
    p_plf_w: torch.Tensor  # (n, 3)
    r_wp: torch.Tensor  # (n, 3, 3)
    v_plf_w: torch.Tensor  # (n, 3) platform CoM velocity
    omega_plf_w: torch.Tensor  # (n, 3)
    p_body_p: torch.Tensor  # (n, 3) trunk position in the platform frame
    v_plf_b: torch.Tensor  # (n, 3) velocity of the platform point under the trunk origin, in b
    omega_plf_b: torch.Tensor  # (n, 3)
    u_aln: torch.Tensor  # (n, 3)
    v_slip_p: torch.Tensor  # (n, 4, 2) foot velocity relative to the platform surface point under it, xy in p
    p_feet_p: torch.Tensor  # (n, 4, 3) foot sites in the platform frame, m
    f_feet_p: torch.Tensor  # (n, 4, 3) contact force ON each foot, platform frame, N


class SceneIndex(RobotIndex):
    """The robot's addresses and the platform's, in qpos and sensordata (computed once)."""

    def __init__(self, model: mujoco.MjModel, device: torch.device | str = "cpu"):
        super().__init__(model, device)
        self.plf_qpos = torch.as_tensor(
            [int(model.joint(j).qposadr[0]) for j in PLATFORM_JOINTS], device=device
        )
        self.plf_linvel = sensor_columns(model, "plf_linvel")
        self.plf_angvel = sensor_columns(model, "plf_angvel")
        # (4, 3): per leg, the columns of its foot's linear-velocity sensor
        self.foot_linvel = sensor_index(model, [f"{leg}_foot_linvel" for leg in a1.LEG_NAMES], device)
        self.plf_qpos_cols = as_slice(self.plf_qpos)
        self.foot_linvel_cols = as_slice(self.foot_linvel.flatten())


def read_scene(sim, ix: SceneIndex, rows: torch.Tensor | None = None) -> SceneReadout:
    """The quantities of all envs, or of envs `rows` only (in that order)."""
    robot = read_robot(sim, ix, rows)
    qpos, sd, site_xpos = sim.qpos, sim.sensordata, sim.site_xpos
    if rows is not None:
        qpos, sd, site_xpos = (x[rows] for x in (qpos, sd, site_xpos))
    plf = take_columns(qpos, ix.plf_qpos_cols)  # x, y, z, yaw, pitch, roll
    p_plf_w = plf[:, :3]
    r_wp = mat_from_euler_zyx(plf[:, 5], plf[:, 4], plf[:, 3])
    v_plf_w = sd[:, ix.plf_linvel].clone()
    omega_plf_w = sd[:, ix.plf_angvel].clone()

    r_wb = robot.r_wb
    r_body = robot.p_body_w - p_plf_w  # lever arm platform CoM -> trunk origin, world
    v_plf_at_body_w = v_plf_w + torch.linalg.cross(omega_plf_w, r_body)
    v_plf_b = rotate_inv(r_wb, v_plf_at_body_w)
    omega_plf_b = rotate_inv(r_wb, omega_plf_w)
    u_aln = torch.cat(
        [v_plf_b[:, :2] - robot.v_body_b[:, :2], omega_plf_b[:, 2:] - robot.omega_body_b[:, 2:]], dim=1
    )

    p_feet_w = take_columns(site_xpos, ix.foot_site_cols)
    v_feet_w = take_columns(sd, ix.foot_linvel_cols).view(-1, 4, 3)
    v_surface_w = v_plf_w[:, None, :] + torch.linalg.cross(
        omega_plf_w[:, None, :].expand_as(p_feet_w), p_feet_w - p_plf_w[:, None, :]
    )
    v_slip_p = rotate_inv(r_wp, v_feet_w - v_surface_w)[:, :, :2]

    return SceneReadout(
        **vars(robot),
        p_plf_w=p_plf_w,
        r_wp=r_wp,
        v_plf_w=v_plf_w,
        omega_plf_w=omega_plf_w,
        p_body_p=rotate_inv(r_wp, r_body),
        v_plf_b=v_plf_b,
        omega_plf_b=omega_plf_b,
        u_aln=u_aln,
        v_slip_p=v_slip_p,
        p_feet_p=rotate_inv(r_wp, p_feet_w - p_plf_w[:, None, :]),
        f_feet_p=rotate_inv(r_wp, robot.f_feet_w),
    )
