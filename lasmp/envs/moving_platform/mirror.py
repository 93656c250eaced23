"""The moving-platform task under the sagittal mirror (`lasmp.envs.mirror`): its observation groups and
actions, for rsl_rl's symmetry augmentation, and its world (trajectories, robots, initial poses), for the
mirror evaluation and the physics test of the maps (tests/envs/test_mirror.py).

The mirrored world negates the platform's y, roll and yaw, mirrors the trunk's total CoM, swaps the
left and right legs' Kp and Kd and negates the robot's initial heading. Stepped under mirrored
actions, it gives the mirrored observations: the maps below are checked against the physics.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from tensordict import TensorDict

from lasmp.envs import mirror as m
from lasmp.envs import trajectories as trj
from lasmp.envs.moving_platform.domain_rand import Intrinsics
from lasmp.robots import a1

# o: [accelerometer_b, gyro_b, roll & pitch, q - q_nominal, q_dot, a_{t-1}] (lasmp/envs/robot.py)
PROPRIOCEPTION = m.concat(
    m.VECTOR, m.PSEUDO_VECTOR, m.ROLL_PITCH, m.JOINT_ANGLES, m.JOINT_ANGLES, m.JOINT_ANGLES
)
# x_exp: [contacts (4), v_body_b, v_plf_b, omega_plf_b]
EXPLICIT = m.concat(m.LEGS, m.VECTOR, m.VECTOR, m.PSEUDO_VECTOR)
ALIGNMENT = m.PLANAR_TWIST
ACTIONS = m.JOINT_ANGLES
_POSE_FLIPS = [trj.POSE_NAMES.index(name) for name in ("y", "roll", "yaw")]


def implicit(nominal_com_y_m: float) -> m.Mirror:
    """x_imp: [trunk mass, CoM shift (3), foot friction, Kp (12), Kd (12)]."""
    return m.concat(m.keep(1), m.com_shift(nominal_com_y_m), m.keep(1), m.JOINT_GAINS, m.JOINT_GAINS)


class ObservationMirror:
    """Mirrors the task's observation groups (a TensorDict of the env's groups, any leading dims)."""

    def __init__(self, nominal_com_y_m: float):
        x_imp = implicit(nominal_com_y_m)
        # critic: [o, x_exp, x_imp, u_aln, p_body_p (3), phi_body_w (3)] (env.py)
        critic = m.concat(PROPRIOCEPTION, EXPLICIT, x_imp, ALIGNMENT, m.VECTOR, m.EULER_ZYX)
        self.groups: dict[str, m.Mirror] = {
            "policy": PROPRIOCEPTION,
            "history": PROPRIOCEPTION,  # (.., H, 44): o per time step
            "priv_explicit": EXPLICIT,
            "priv_implicit": x_imp,
            "alignment": ALIGNMENT,
            "critic": critic,
        }

    def __call__(self, obs: TensorDict) -> TensorDict:
        unknown = sorted(set(obs.keys()) - set(self.groups))
        if unknown:
            raise KeyError(f"no mirror map for observation group(s) {unknown}; mapped: {sorted(self.groups)}")
        return TensorDict(
            {key: self.groups[key](value) for key, value in obs.items()},
            batch_size=obs.batch_size,
            device=obs.device,
        )


# ---- the mirrored world --------------------------------------------------------------------------


def mirror_trajectories(traj: trj.PiecewisePoly) -> trj.PiecewisePoly:
    """The same trajectories with y, roll and yaw negated (the polynomials are linear in the poses)."""
    knot_poses, coeffs = traj.knot_poses.copy(), traj.coeffs.copy()
    knot_poses[..., _POSE_FLIPS] *= -1.0
    coeffs[..., _POSE_FLIPS] *= -1.0
    return dataclasses.replace(traj, knot_poses=knot_poses, coeffs=coeffs, meta=dict(traj.meta))


def mirror_intrinsics(p: Intrinsics, nominal_com_y_m: float) -> Intrinsics:
    """The robots' mirror images: CoM shift y mirrored about the trunk's x-z plane, the legs' gains
    swapped; mass, friction and the platform's per-axis gains are the mirror's own."""
    com = p.com_shift_m.copy()
    com[:, 1] = -com[:, 1] - 2.0 * nominal_com_y_m
    joints = list(a1.MIRROR_JOINTS)
    return dataclasses.replace(
        p, com_shift_m=com, joint_kp=p.joint_kp[:, joints], joint_kd=p.joint_kd[:, joints]
    )


def mirror_pose_uniforms(u: np.ndarray, init) -> np.ndarray:
    """The (n, 3) uniforms of `initial_pose` (env.py) that start the mirror image: the heading and the
    offset's angle negated. Needs the heading range symmetric about 0 (`init.yaw_range_rad`)."""
    lo, hi = init.yaw_range_rad
    if not np.isclose(lo, -hi):
        raise ValueError(f"the mirror needs init_state.yaw_range_rad symmetric about 0, got {[lo, hi]}")
    out = u.copy()
    out[:, 0] = 1.0 - u[:, 0]  # yaw = lo + (hi - lo) u
    out[:, 2] = 1.0 - u[:, 2]  # angle = -pi + 2 pi u
    return out


def nominal_com_y_m(model) -> float:
    """y of the trunk's nominal CoM in its frame, m (the published 2.2 mm)."""
    return float(model.body_ipos[model.body(a1.TRUNK_BODY_NAME).id][1])
