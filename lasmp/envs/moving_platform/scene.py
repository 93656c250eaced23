"""The moving-platform world, built in code with `mujoco.MjSpec`.

World = our A1 (`lasmp.envs.robot_spec`: its MJCF, options, sensors) + a 2 x 2 x 0.2 m box platform on six actuated
joints. The platform chain is slide x, y, z (world axes), then hinge yaw (z), pitch (y),
roll (x), so its joint angles are ZYX Euler angles: R_wp = Rz(yaw) Ry(pitch) Rx(roll), the
convention of `lasmp.envs.trajectories`. Every platform joint is driven by a PD made of two
actuators: an `intvelocity` one (kp; its activation is the reference position, set at each
policy step and ramped by ctrl = the reference's mean velocity over the step, so it reaches the
next reference exactly) and a `velocity` one (kd, ctrl = reference velocity). Together,
force = kp (x_ref - x) + kd (v_ref - v) runs inside the physics substeps. The platform is gravity-compensated (`gravcomp`), so the z axis needs no bias force.

The platform is a real dynamic body, not a mocap body: MuJoCo gives mocap bodies zero contact
velocity, so friction would not carry the robot along.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from lasmp.config.base import SimCfg
from lasmp.envs.moving_platform.cfg import PlatformCfg
from lasmp.envs.robot_spec import add_robot_sensors, robot_spec
from lasmp.robots import a1

PLATFORM_JOINTS = ("plf_x", "plf_y", "plf_z", "plf_yaw", "plf_pitch", "plf_roll")
# For each platform joint (PLATFORM_JOINTS order): the index of its component in a trajectory
# pose [x, y, z, roll, pitch, yaw].
POSE_TO_JOINT = np.array([0, 1, 2, 5, 4, 3])
_JOINT_AXES = {
    "plf_x": [1, 0, 0],
    "plf_y": [0, 1, 0],
    "plf_z": [0, 0, 1],
    "plf_yaw": [0, 0, 1],
    "plf_pitch": [0, 1, 0],
    "plf_roll": [1, 0, 0],
}


@dataclass(frozen=True)
class PlatformGains:
    """Nominal per-axis PD gains in PLATFORM_JOINTS order (N/m, N·s/m; N·m/rad, N·m·s/rad)."""

    kp: np.ndarray  # (6,) gains at stiffness factor 1
    kd: np.ndarray  # (6,) gains at damping factor 1 (the paper's factors are ~0.025)


def platform_gains(cfg: PlatformCfg) -> PlatformGains:
    """Gains that make each axis a 2nd-order system of natural frequency `omega_n_rad_s` at factor 1."""
    w, l, h = cfg.size_m
    m = cfg.mass_kg
    # box inertias about the CoM; the hinges pass through it
    i_roll = m * (l**2 + h**2) / 12.0
    i_pitch = m * (w**2 + h**2) / 12.0
    i_yaw = m * (w**2 + l**2) / 12.0
    inertia = np.array([m, m, m, i_yaw, i_pitch, i_roll])
    omega = cfg.omega_n_rad_s
    kp = inertia * omega**2
    kd = 2.0 * cfg.damping_ratio * inertia * omega / cfg.kd_factor_ref
    return PlatformGains(kp=kp, kd=kd)


def platform_actuator_ids(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """Ids of the platform's position servos and of its velocity (damping) actuators, PLATFORM_JOINTS order."""
    return tuple(
        np.array([model.actuator(f"{j}_{kind}").id for j in PLATFORM_JOINTS]) for kind in ("pos", "vel")
    )


def platform_top_z_m(cfg: PlatformCfg) -> float:
    """Height of the platform's top surface above its centre, m."""
    return cfg.size_m[2] / 2.0


def build_spec(platform: PlatformCfg, sim: SimCfg) -> mujoco.MjSpec:
    gains = platform_gains(platform)
    spec = robot_spec(sim, "lasmp_moving_platform")
    spec.visual.global_.offwidth = 1280
    spec.visual.global_.offheight = 720

    body = spec.worldbody.add_body(name="platform", gravcomp=1.0)
    for name in PLATFORM_JOINTS:
        slide = name in ("plf_x", "plf_y", "plf_z")
        kind = mujoco.mjtJoint.mjJNT_SLIDE if slide else mujoco.mjtJoint.mjJNT_HINGE
        body.add_joint(name=name, type=kind, axis=_JOINT_AXES[name])
    half = [s / 2.0 for s in platform.size_m]
    body.add_geom(
        name="platform",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=half,
        mass=platform.mass_kg,
        contype=0,
        conaffinity=1,
        friction=[platform.friction, 0.005, 0.0001],
        rgba=[0.45, 0.5, 0.6, 1.0],
    )
    body.add_site(name="platform_centre")
    for j, name in enumerate(PLATFORM_JOINTS):
        kp, kd = float(gains.kp[j]), float(gains.kd[j])
        # integrated-velocity position servo: its target (the actuator's `act`) ramps at rate ctrl
        # within a policy step, so the reference moves smoothly instead of jumping every 20 ms
        pos = spec.add_actuator(name=f"{name}_pos", target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        pos.set_to_intvelocity(kp=kp)
        vel = spec.add_actuator(name=f"{name}_vel", target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        vel.set_to_velocity(kv=kd * platform.kd_factor_ref)  # nominal; the env writes per-env gains

    site, sensor = mujoco.mjtObj.mjOBJ_SITE, mujoco.mjtSensor
    linvel = sensor.mjSENS_FRAMELINVEL
    spec.add_sensor(name="plf_linvel", type=linvel, objtype=site, objname="platform_centre")
    spec.add_sensor(
        name="plf_angvel", type=sensor.mjSENS_FRAMEANGVEL, objtype=site, objname="platform_centre"
    )
    for leg in a1.LEG_NAMES:
        spec.add_sensor(name=f"{leg}_foot_linvel", type=linvel, objtype=site, objname=f"{leg}_foot")
    add_robot_sensors(spec)
    return spec


def build_model(platform: PlatformCfg, sim: SimCfg) -> mujoco.MjModel:
    return build_spec(platform, sim).compile()
