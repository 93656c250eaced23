"""The per-step quantities that rewards and terminations read.

The environment fills one `StepState` after every policy step; reward terms are pure
functions of it. All tensors are float32 (bool where noted) with a leading `num_envs`
dimension. Frames: `w` world, `p` platform (origin at the platform's centre of mass), `b` trunk
(as `lasmp.envs.robot` defines it: origin at the trunk link's origin). Units: SI (m, s, rad, N, N·m).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch


@dataclass
class StepState:
    dt_s: float  # policy step, s
    p_body_p: torch.Tensor  # (n, 3) trunk position in the platform frame, m
    phi_body_w: torch.Tensor  # (n, 3) trunk roll, pitch, yaw in the world (ZYX Euler), rad
    v_body_b: torch.Tensor  # (n, 3) trunk linear velocity, body frame, m/s
    omega_body_b: torch.Tensor  # (n, 3) trunk angular velocity, body frame, rad/s
    v_plf_b: torch.Tensor  # (n, 3) velocity of the platform point under the trunk origin, body frame, m/s
    omega_plf_b: torch.Tensor  # (n, 3) platform angular velocity, body frame, rad/s
    u_aln: torch.Tensor  # (n, 3) alignment command [v_plf_xy - v_body_xy, w_plf_z - w_body_z] in b
    action: torch.Tensor  # (n, 12) current action a_t
    action_prev: torch.Tensor  # (n, 12) a_{t-1}
    tau: torch.Tensor  # (n, 12) joint torques applied this step, N·m
    tau_prev: torch.Tensor  # (n, 12) joint torques of the previous step, N·m
    q_dot: torch.Tensor  # (n, 12) joint velocities, rad/s
    q_ddot: torch.Tensor  # (n, 12) joint accelerations (finite difference over dt_s), rad/s^2
    f_feet_w: torch.Tensor  # (n, 4, 3) net contact force on each foot, world frame, N
    contact: torch.Tensor  # (n, 4) bool, foot i touches something
    touchdown: torch.Tensor  # (n, 4) bool, foot i made contact this step (was in the air)
    liftoff: torch.Tensor  # (n, 4) bool, foot i left contact this step (was in contact)
    t_air_s: torch.Tensor  # (n, 4) length of the air phase that ended at touchdown, s
    t_contact_s: torch.Tensor  # (n, 4) length of the contact phase that ended at lift-off, s
    t_air_running_s: torch.Tensor  # (n, 4) how long foot i has been in the air so far (0 in contact), s
    at_time_limit: torch.Tensor  # (n,) bool, this step is the episode's last by its length (time-out)
    v_slip_p: torch.Tensor  # (n, 4, 2) foot velocity relative to the platform surface under it, xy in p, m/s
    p_feet_p: torch.Tensor  # (n, 4, 3) foot positions in the platform frame, m
    f_feet_p: torch.Tensor  # (n, 4, 3) net contact force on each foot, platform frame, N
    collision: torch.Tensor  # (n,) bool, trunk/hip/thigh/calf contact, or fell off the platform
