"""The A1 inside a batch of simulations, shared by every task.

- where its state lives: `RobotIndex` (addresses in qpos, qvel, ctrl, sensordata, site_xpos);
- what it reads: `read_robot` -> `RobotReadout` (trunk pose and velocities, IMU, joints, feet);
- what it is: `RobotIntrinsics` (the randomized trunk mass, CoM shift, foot friction, PD gains),
  the robot's part of the paper's Table B (`nominal_robot_intrinsics`, `sample_robot_intrinsics`),
  written into the batch's per-env model by `RobotIntrinsicsWriter`;
- how its feet step: `step_gait_phase` (touchdown, lift-off, the air and contact phases that end);
- what the policy sees of it: `proprioception`, o_t (`OBS_DIM` numbers, sensors only);
- which envs diverged: `screen_faults`, so that NaNs stay out of rewards, logs and observations.

A task adds its world on top (`moving_platform/readout.py` extends the index and the readout with
the platform's quantities, `moving_platform/domain_rand.py` the intrinsics with the platform's gains). The scene holds the A1 of `lasmp.robots.a1` with its names and the
sensors `imu_acc`, `imu_gyro`, `<leg>_foot_contact` (found + net force, world frame) and
`<body>_collision` (found) for every body of `a1.NON_FOOT_COLLISION_GEOMS`.

torch tensors on the backend's device and dtype (float64 on the CPU backend), (num_envs, ...).
Frames (the one definition; the tasks' modules and docs/environment.md#frames point here): `w` world;
`b` trunk: the trunk body's frame, x forward, y left, z up, with its origin at the trunk link's
origin (where the `imu` site sits), not at its centre of mass: `p_body_w` is the free joint's
position (MuJoCo's `xpos` of the trunk, never `xipos`), `v_body_b` that point's velocity. b stays at
the link origin when domain randomization shifts the CoM, so that its velocities are what an IMU on
the real trunk measures.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TypeVar

import mujoco
import numpy as np
import torch

from lasmp.config.base import DomainRandRanges
from lasmp.envs.rotations import euler_zyx_from_mat, quat_to_mat, rotate_inv
from lasmp.robots import a1

OBS_DIM = 44  # o: accelerometer (3), gyro (3), roll & pitch (2), q - q_nominal (12), q_dot (12), a_{t-1} (12)
X_IMP_DIM = (
    29  # x_imp (`RobotIntrinsics.x_imp`): trunk mass (1), CoM shift (3), foot friction (1), Kp (12), Kd (12)
)


def sensor_columns(model: mujoco.MjModel, name: str) -> slice:
    """The columns of sensor `name` in sensordata."""
    s = model.sensor(name)
    return slice(int(s.adr[0]), int(s.adr[0] + s.dim[0]))


def sensor_index(model: mujoco.MjModel, names, device) -> torch.Tensor:
    """(len(names), dim): the sensordata columns of each sensor (all of one dimension), on `device`."""
    cols = [np.arange(c.start, c.stop) for c in (sensor_columns(model, name) for name in names)]
    return torch.as_tensor(np.stack(cols), device=device)


def take_columns(x: torch.Tensor, cols: slice | torch.Tensor) -> torch.Tensor:
    """Columns `cols` (an `as_slice` result) of x (n, m, ...), as a copy (never a view of live memory)."""
    return x[:, cols].clone() if isinstance(cols, slice) else x.index_select(1, cols)


def as_slice(index: torch.Tensor) -> slice | torch.Tensor:
    """`index` as a slice where it is an evenly spaced increasing run (a write through a slice is a
    strided copy; through an index tensor, a slower scatter), else unchanged."""
    values = index.tolist()
    step = values[1] - values[0] if len(values) > 1 else 1
    if step > 0 and values == list(range(values[0], values[0] + step * len(values), step)):
        return slice(values[0], values[0] + step * (len(values) - 1) + 1, step)
    return index


class RobotIndex:
    """Addresses of the A1's state, actuators and sensors in a scene's model (computed once), as
    index tensors on `device` (gathers then stay on the device)."""

    def __init__(self, model: mujoco.MjModel, device: torch.device | str = "cpu"):
        def ix(values) -> torch.Tensor:
            return torch.as_tensor(np.asarray(values, dtype=np.int64), device=device)

        root = model.joint(a1.ROOT_JOINT_NAME)
        self.root_qpos = int(root.qposadr[0])  # free joint: position (3), then quaternion (w, x, y, z)
        self.root_qvel = int(root.dofadr[0])  # free joint: linear velocity (3, in w), angular (3, in b)
        self.joint_qpos = ix([model.joint(j).qposadr[0] for j in a1.JOINT_NAMES])
        self.joint_qvel = ix([model.joint(j).dofadr[0] for j in a1.JOINT_NAMES])
        self.joint_act = ix([model.actuator(j).id for j in a1.JOINT_NAMES])
        self.acc = sensor_columns(model, "imu_acc")
        self.gyro = sensor_columns(model, "imu_gyro")
        # (4, 4): per leg, the columns [found, force x, y, z] of its contact sensor
        self.foot_contact = sensor_index(model, [f"{leg}_foot_contact" for leg in a1.LEG_NAMES], device)
        self.collision = ix([model.sensor(f"{b}_collision").adr[0] for b in a1.NON_FOOT_COLLISION_GEOMS])
        self.foot_site = ix([model.site(f).id for f in a1.FOOT_NAMES])
        # the same columns as the readout gathers them: slices where they are even runs (a strided
        # copy is faster than index_select's gather on a CPU, to the same values:
        # docs/performance.md#the-environment)
        self.joint_qpos_cols, self.joint_qvel_cols, self.joint_act_cols, self.collision_cols = (
            as_slice(i) for i in (self.joint_qpos, self.joint_qvel, self.joint_act, self.collision)
        )
        self.foot_contact_cols = as_slice(self.foot_contact.flatten())
        self.foot_site_cols = as_slice(self.foot_site)


@dataclass
class RobotReadout:
    p_body_w: torch.Tensor  # (n, 3) trunk origin, m
    r_wb: torch.Tensor  # (n, 3, 3) trunk orientation
    phi_body_w: torch.Tensor  # (n, 3) roll, pitch, yaw (ZYX), rad
    gravity_b: torch.Tensor  # (n, 3) unit gravity direction, body frame
    v_body_b: torch.Tensor  # (n, 3) m/s
    omega_body_b: torch.Tensor  # (n, 3) rad/s, true (the gyro reads the same, noise-free)
    acc_imu_b: torch.Tensor  # (n, 3) accelerometer (specific force), m/s^2: +g on body z at rest
    gyro_b: torch.Tensor  # (n, 3) rad/s
    q: torch.Tensor  # (n, 12) rad
    q_dot: torch.Tensor  # (n, 12) rad/s
    tau: torch.Tensor  # (n, 12) N·m
    foot_contact: torch.Tensor  # (n, 4) bool
    f_feet_w: torch.Tensor  # (n, 4, 3) contact force ON each foot, world frame, N
    body_collision: torch.Tensor  # (n,) bool, a trunk/hip/thigh/calf geom touches anything


AnyReadout = TypeVar("AnyReadout", bound=RobotReadout)  # a task's readout extends the robot's


def read_robot(sim, ix: RobotIndex, rows: torch.Tensor | None = None) -> RobotReadout:
    """The robot's quantities in all envs, or in envs `rows` only (in that order); tensors of their
    own (never views of the backend's state)."""
    qpos, qvel, sd, actuator_force = sim.qpos, sim.qvel, sim.sensordata, sim.actuator_force
    if rows is not None:
        qpos, qvel, sd, actuator_force = (x[rows] for x in (qpos, qvel, sd, actuator_force))
    quat = qpos[:, ix.root_qpos + 3 : ix.root_qpos + 7]
    r_wb = quat_to_mat(quat / torch.linalg.vector_norm(quat, dim=1, keepdim=True))
    contact = take_columns(sd, ix.foot_contact_cols).view(-1, 4, 4)  # (n, 4, 4): found, force (3)
    foot_contact = contact[:, :, 0] > 0
    return RobotReadout(
        p_body_w=qpos[:, ix.root_qpos : ix.root_qpos + 3].clone(),
        r_wb=r_wb,
        phi_body_w=euler_zyx_from_mat(r_wb),
        gravity_b=-r_wb[:, 2, :],  # world -z in the body frame: R^T (0, 0, -1)
        v_body_b=rotate_inv(r_wb, qvel[:, ix.root_qvel : ix.root_qvel + 3]),
        omega_body_b=qvel[:, ix.root_qvel + 3 : ix.root_qvel + 6].clone(),
        acc_imu_b=sd[:, ix.acc].clone(),
        gyro_b=sd[:, ix.gyro].clone(),
        q=take_columns(qpos, ix.joint_qpos_cols),
        q_dot=take_columns(qvel, ix.joint_qvel_cols),
        tau=take_columns(actuator_force, ix.joint_act_cols),
        foot_contact=foot_contact,
        # the sensor reports the force of the foot on the other body; the force on the foot is its negative
        f_feet_w=-contact[:, :, 1:4] * foot_contact[:, :, None],
        body_collision=(sd[:, ix.collision_cols] > 0).any(dim=1),
    )


def as_numpy(r: AnyReadout) -> AnyReadout:
    """The same readout as host numpy copies (for evaluation code that works on the host). Copies, not
    views: the env resets an ended episode's rows of its readout in place at the end of the step, so a
    view taken at the step (`on_step`) would read the reset state, not the state the episode ended in."""
    return dataclasses.replace(
        r, **{name: value.detach().cpu().numpy().copy() for name, value in vars(r).items()}
    )


def update_rows(target, rows: torch.Tensor, sub) -> None:
    """In place: rows `rows` of every array field of dataclass `target` (a readout, intrinsics) take
    the values of `sub`, the same kind of dataclass holding those rows only."""
    for name, value in vars(sub).items():
        getattr(target, name)[rows] = value


def proprioception(r: RobotReadout, last_action: torch.Tensor, q_nominal: torch.Tensor) -> torch.Tensor:
    """o_t (n, OBS_DIM) = [acc_imu_b (3) m/s^2, gyro_b (3) rad/s, roll & pitch (2) rad,
    q - q_nominal (12) rad, q_dot (12) rad/s, a_{t-1} (12)]: what the real robot's sensors give.
    q is centred at the nominal stance (ours, as legged_gym)."""
    return torch.cat(
        [r.acc_imu_b, r.gyro_b, r.phi_body_w[:, :2], r.q - q_nominal, r.q_dot, last_action], dim=1
    )


def screen_faults(r: AnyReadout, max_joint_vel_rad_s: float) -> tuple[AnyReadout, torch.Tensor]:
    """(the readout, with every non-finite value replaced by 0 if it holds any; the (n,) mask of the
    envs it shows faulted: a non-finite value in any field, or a joint faster than
    max_joint_vel_rad_s, a simulation running away before its state turns non-finite).

    `r` may be a task's extension of `RobotReadout`; it is not modified (the clean one is a copy).
    The physics backend flags its own faults (MuJoCo errors, warnings); the caller combines both.
    """
    floats = {name: value for name, value in vars(r).items() if value.is_floating_point()}
    faulted = (torch.abs(r.q_dot) > max_joint_vel_rad_s).any(dim=1)
    # a non-finite value makes its field's sum non-finite: one reduction per field, one host sync, and
    # the per-env search only when a sum is not finite
    if not bool(torch.isfinite(torch.stack([value.sum() for value in floats.values()])).all()):
        for value in floats.values():
            faulted |= ~torch.isfinite(value.reshape(len(value), -1)).all(dim=1)
    if faulted.any():
        zeroed = {name: torch.nan_to_num(x, nan=0.0, posinf=0.0, neginf=0.0) for name, x in floats.items()}
        r = dataclasses.replace(r, **zeroed)
    return r, faulted


@dataclass
class RobotIntrinsics:
    """The robot's randomized parameters; also the implicit privileged state x_imp."""

    trunk_mass_kg: np.ndarray  # (n,)
    com_shift_m: np.ndarray  # (n, 3) shift of the trunk CoM from its nominal place, trunk frame
    foot_friction: np.ndarray  # (n,) sliding friction coefficient of all four feet
    joint_kp: np.ndarray  # (n, 12) N·m/rad
    joint_kd: np.ndarray  # (n, 12) N·m·s/rad

    def x_imp(self) -> np.ndarray:
        """(n, 29) implicit privileged state [trunk mass (1), CoM shift (3), foot friction (1),
        Kp (12), Kd (12)], SI units."""
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


def nominal_robot_intrinsics(n: int) -> RobotIntrinsics:
    """n robots as published: the A1's trunk mass, no CoM shift, friction 1, the nominal PD gains."""
    return RobotIntrinsics(
        trunk_mass_kg=np.full(n, a1.TRUNK_MASS_KG),
        com_shift_m=np.zeros((n, 3)),
        foot_friction=np.ones(n),
        joint_kp=np.full((n, 12), a1.KP_NOMINAL_NM_PER_RAD),
        joint_kd=np.full((n, 12), a1.KD_NOMINAL_NM_S_PER_RAD),
    )


def sample_robot_intrinsics(n: int, r: DomainRandRanges, rng: np.random.Generator) -> RobotIntrinsics:
    """n uniform draws from the robot's ranges of `r`, on the host (in field order: the random
    stream's order)."""

    def u(lo_hi, *shape):
        return rng.uniform(lo_hi[0], lo_hi[1], size=(n, *shape))

    return RobotIntrinsics(
        trunk_mass_kg=u(r.trunk_mass_kg),
        com_shift_m=u(r.com_shift_m, 3),
        foot_friction=u(r.foot_friction),
        joint_kp=u(r.joint_kp, 12),
        joint_kd=u(r.joint_kd, 12),
    )


class RobotIntrinsicsWriter:
    """Writes the `RobotIntrinsics` of some envs (host arrays, drawn at reset) into the backend's
    per-env model fields (a task with actuators of its own extends it)."""

    def __init__(self, sim):
        m = sim.model
        self._sim = sim
        trunk = m.body(a1.TRUNK_BODY_NAME).id
        self._trunk = trunk
        self._trunk_ipos0 = torch.as_tensor(m.body_ipos[trunk], dtype=sim.dtype, device=sim.device)
        self._feet = torch.as_tensor([m.geom(name).id for name in a1.FOOT_NAMES], device=sim.device)
        self._joint_act = torch.as_tensor([m.actuator(name).id for name in a1.JOINT_NAMES], device=sim.device)
        self._body_mass = sim.expand("body_mass")
        self._body_ipos = sim.expand("body_ipos")
        self._geom_friction = sim.expand("geom_friction")
        self._gainprm = sim.expand("actuator_gainprm")
        self._biasprm = sim.expand("actuator_biasprm")
        assert m.actuator_biastype[self._joint_act[0]] == mujoco.mjtBias.mjBIAS_AFFINE

    def tensor(self, x: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(x, dtype=self._sim.dtype, device=self._sim.device)

    def write(self, ids: torch.Tensor, p: RobotIntrinsics) -> None:
        t = self.tensor
        rows = ids[:, None]
        self._body_mass[ids, self._trunk] = t(p.trunk_mass_kg)
        self._body_ipos[ids, self._trunk] = self._trunk_ipos0 + t(p.com_shift_m)
        self._geom_friction[rows, self._feet, 0] = t(p.foot_friction)[:, None]
        # MuJoCo position actuator: force = kp * ctrl - kp * q - kd * q_dot
        kp, kd = t(p.joint_kp), t(p.joint_kd)
        self._gainprm[rows, self._joint_act, 0] = kp
        self._biasprm[rows, self._joint_act, 1] = -kp
        self._biasprm[rows, self._joint_act, 2] = -kd


@dataclass
class GaitEvents:
    """A step's gait-phase events per foot, (n, 4) tensors."""

    touchdown: torch.Tensor  # bool, the foot made contact this step (it was in the air)
    liftoff: torch.Tensor  # bool, the foot left contact this step (it was in contact)
    t_air_s: torch.Tensor  # length of the air phase that ended at touchdown (0 elsewhere), s
    t_contact_s: torch.Tensor | None  # length of the contact phase that ended at lift-off (0 elsewhere), s


def step_gait_phase(
    contact: torch.Tensor,
    contact_prev: torch.Tensor,
    t_air_s: torch.Tensor,
    t_contact_s: torch.Tensor | None,
    dt_s: float,
) -> GaitEvents:
    """This step's events from the feet's `contact` (n, 4) bool; updates, in place, the task's
    running buffers: `contact_prev` (n, 4) bool, the time each foot has been in the air `t_air_s`
    and in contact `t_contact_s` (n, 4), s (None: a task that does not track contact phases).

    `contact_prev` takes a copy of `contact`, never becomes it: the readout that `contact` belongs to
    is updated in place where envs are reset (their rows read anew), and a reset sets the buffer's
    rows to False, which must not reach the readout either.
    """
    touchdown = contact & ~contact_prev
    liftoff = ~contact & contact_prev
    t_air_s += dt_s * (~contact).to(t_air_s.dtype)
    t_air_ended = torch.where(touchdown, t_air_s, 0.0)
    t_air_s.masked_fill_(contact, 0.0)
    t_contact_ended = None
    if t_contact_s is not None:
        t_contact_s += dt_s * contact.to(t_contact_s.dtype)
        t_contact_ended = torch.where(liftoff, t_contact_s, 0.0)
        t_contact_s.masked_fill_(~contact, 0.0)
    contact_prev.copy_(contact)
    return GaitEvents(touchdown, liftoff, t_air_ended, t_contact_ended)
