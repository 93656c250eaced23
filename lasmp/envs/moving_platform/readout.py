"""Turns the batch's raw arrays into the named physical quantities of SPEC §1 and §7.

Everything here is numpy float64, (num_envs, ...). Frames: `w` world, `p` platform (origin at
the platform's CoM = its geometric centre), `b` trunk (origin at the trunk link origin, the
IMU site; x forward, y left, z up). We put B at the link origin rather than at the randomized
CoM so that its velocities are what an IMU on the real trunk measures.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from lasmp.envs.backends.cpu import CpuBatchSim
from lasmp.envs.rotations import euler_zyx_from_mat, mat_from_euler_zyx, quat_to_mat, rotate_inv
from lasmp.envs.scene import NON_FOOT_BODIES, PLATFORM_JOINTS
from lasmp.robots import a1


@dataclass
class Readout:
    p_body_w: np.ndarray  # (n, 3) trunk position, m
    r_wb: np.ndarray  # (n, 3, 3) trunk orientation
    phi_body_w: np.ndarray  # (n, 3) roll, pitch, yaw (ZYX), rad
    v_body_b: np.ndarray  # (n, 3) m/s
    omega_body_b: np.ndarray  # (n, 3) rad/s, true (the gyro reads the same, noise-free)
    acc_imu_b: np.ndarray  # (n, 3) accelerometer (specific force), m/s^2: +g on body z at rest
    gyro_b: np.ndarray  # (n, 3) rad/s
    q: np.ndarray  # (n, 12) rad
    q_dot: np.ndarray  # (n, 12) rad/s
    tau: np.ndarray  # (n, 12) N·m
    p_plf_w: np.ndarray  # (n, 3)
    r_wp: np.ndarray  # (n, 3, 3)
    v_plf_w: np.ndarray  # (n, 3) platform CoM velocity
    omega_plf_w: np.ndarray  # (n, 3)
    p_body_p: np.ndarray  # (n, 3) trunk position in the platform frame
    v_plf_b: np.ndarray  # (n, 3) velocity of the platform point under the trunk origin, in b
    omega_plf_b: np.ndarray  # (n, 3)
    u_aln: np.ndarray  # (n, 3)
    foot_contact: np.ndarray  # (n, 4) bool
    f_feet_w: np.ndarray  # (n, 4, 3) contact force ON each foot, world frame, N
    v_slip_p: np.ndarray  # (n, 4, 2) foot velocity relative to the platform surface point under it, xy in p
    body_collision: np.ndarray  # (n,) bool, a trunk/hip/thigh/calf geom touches anything


class ReadoutIndex:
    """Addresses of every quantity in qpos, qvel, sensordata and site_xpos (computed once)."""

    def __init__(self, model: mujoco.MjModel):
        root = model.joint(a1.ROOT_JOINT_NAME)
        self.root_qpos = int(root.qposadr[0])
        self.root_qvel = int(root.dofadr[0])
        self.joint_qpos = np.array([model.joint(j).qposadr[0] for j in a1.JOINT_NAMES])
        self.joint_qvel = np.array([model.joint(j).dofadr[0] for j in a1.JOINT_NAMES])
        self.joint_act = np.array([model.actuator(j).id for j in a1.JOINT_NAMES])
        self.plf_qpos = np.array([model.joint(j).qposadr[0] for j in PLATFORM_JOINTS])

        def sens(name):
            s = model.sensor(name)
            return slice(int(s.adr[0]), int(s.adr[0] + s.dim[0]))

        self.acc = sens("imu_acc")
        self.gyro = sens("imu_gyro")
        self.plf_linvel = sens("plf_linvel")
        self.plf_angvel = sens("plf_angvel")
        self.foot_linvel = [sens(f"{leg}_foot_linvel") for leg in a1.LEG_NAMES]
        self.foot_contact = [sens(f"{leg}_foot_contact") for leg in a1.LEG_NAMES]  # found (1) + force (3)
        self.collision = np.array([model.sensor(f"{b}_collision").adr[0] for b in NON_FOOT_BODIES])
        self.foot_site = np.array([model.site(f).id for f in a1.FOOT_NAMES])


def read(sim: CpuBatchSim, ix: ReadoutIndex, rows: np.ndarray | None = None) -> Readout:
    """The quantities of all envs, or of envs `rows` only (in that order)."""
    qpos, qvel, sd = sim.qpos, sim.qvel, sim.sensordata
    site_xpos, actuator_force = sim.site_xpos, sim.actuator_force
    if rows is not None:
        qpos, qvel, sd, site_xpos, actuator_force = (
            x[rows] for x in (qpos, qvel, sd, site_xpos, actuator_force)
        )
    p_body_w = qpos[:, ix.root_qpos : ix.root_qpos + 3].copy()
    quat = qpos[:, ix.root_qpos + 3 : ix.root_qpos + 7]
    r_wb = quat_to_mat(quat / np.linalg.norm(quat, axis=1, keepdims=True))
    # free joint: linear velocity in the world frame, angular velocity in the body frame
    v_body_b = rotate_inv(r_wb, qvel[:, ix.root_qvel : ix.root_qvel + 3])
    omega_body_b = qvel[:, ix.root_qvel + 3 : ix.root_qvel + 6].copy()

    plf = qpos[:, ix.plf_qpos]  # x, y, z, yaw, pitch, roll
    p_plf_w = plf[:, :3].copy()
    r_wp = mat_from_euler_zyx(plf[:, 5], plf[:, 4], plf[:, 3])
    v_plf_w = sd[:, ix.plf_linvel].copy()
    omega_plf_w = sd[:, ix.plf_angvel].copy()

    r_body = p_body_w - p_plf_w  # lever arm platform CoM -> trunk origin, world
    v_plf_at_body_w = v_plf_w + np.cross(omega_plf_w, r_body)
    v_plf_b = rotate_inv(r_wb, v_plf_at_body_w)
    omega_plf_b = rotate_inv(r_wb, omega_plf_w)
    u_aln = np.concatenate(
        [v_plf_b[:, :2] - v_body_b[:, :2], omega_plf_b[:, 2:] - omega_body_b[:, 2:]], axis=1
    )

    contact = np.stack([sd[:, s] for s in ix.foot_contact], axis=1)  # (n, 4, 4)
    foot_contact = contact[:, :, 0] > 0
    # the sensor reports the force of the foot on the other body; the force on the foot is its negative
    f_feet_w = -contact[:, :, 1:4] * foot_contact[:, :, None]
    p_feet_w = site_xpos[:, ix.foot_site]
    v_feet_w = np.stack([sd[:, s] for s in ix.foot_linvel], axis=1)
    v_surface_w = v_plf_w[:, None, :] + np.cross(omega_plf_w[:, None, :], p_feet_w - p_plf_w[:, None, :])
    v_slip_p = rotate_inv(r_wp, v_feet_w - v_surface_w)[:, :, :2]

    return Readout(
        p_body_w=p_body_w,
        r_wb=r_wb,
        phi_body_w=euler_zyx_from_mat(r_wb),
        v_body_b=v_body_b,
        omega_body_b=omega_body_b,
        acc_imu_b=sd[:, ix.acc].copy(),
        gyro_b=sd[:, ix.gyro].copy(),
        q=qpos[:, ix.joint_qpos],
        q_dot=qvel[:, ix.joint_qvel],
        tau=actuator_force[:, ix.joint_act].copy(),
        p_plf_w=p_plf_w,
        r_wp=r_wp,
        v_plf_w=v_plf_w,
        omega_plf_w=omega_plf_w,
        p_body_p=rotate_inv(r_wp, r_body),
        v_plf_b=v_plf_b,
        omega_plf_b=omega_plf_b,
        u_aln=u_aln,
        foot_contact=foot_contact,
        f_feet_w=f_feet_w,
        v_slip_p=v_slip_p,
        body_collision=(sd[:, ix.collision] > 0).any(axis=1),
    )


def update_rows(readout: Readout, rows: np.ndarray, sub: Readout) -> None:
    """In place: the rows `rows` of `readout` take the values of `sub` (a readout of those rows)."""
    for name, value in vars(sub).items():
        getattr(readout, name)[rows] = value
