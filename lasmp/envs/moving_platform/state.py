"""The per-step quantities that rewards and terminations read.

The environment fills one `StepState` after every policy step; reward terms are pure
functions of it. All tensors are float32 (bool where noted) with a leading `num_envs`
dimension. Frames: `w` world, `p` platform (origin at the platform's centre of mass),
`b` trunk body (origin at the trunk's centre of mass). Units: SI (m, s, rad, N, N·m).
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
    v_slip_p: torch.Tensor  # (n, 4, 2) foot velocity relative to the platform surface under it, xy in p, m/s
    collision: torch.Tensor  # (n,) bool, trunk/hip/thigh/calf contact, or fell off the platform


def step_state(
    r,
    fell: torch.Tensor,
    action: torch.Tensor,
    action_prev: torch.Tensor,
    tau_prev: torch.Tensor,
    q_dot_prev: torch.Tensor,
    contact_prev: torch.Tensor,
    t_air_s: torch.Tensor,
    t_contact_s: torch.Tensor,
    dt_s: float,
) -> tuple[StepState, torch.Tensor, torch.Tensor]:
    """(the StepState of this step, from its readout `r` (a moving-platform `Readout`), whether the
    robot fell, and the previous step's buffers; the running air and contact times (n, 4) after this
    step, 0 for a foot in the other phase)."""
    contact = r.foot_contact
    touchdown = contact & ~contact_prev
    liftoff = ~contact & contact_prev
    t_air_s = t_air_s + dt_s * (~contact).to(t_air_s.dtype)
    t_contact_s = t_contact_s + dt_s * contact.to(t_contact_s.dtype)
    f32 = torch.float32  # rewards are computed in float32 on every backend
    state = StepState(
        dt_s=dt_s,
        p_body_p=r.p_body_p.to(f32),
        phi_body_w=r.phi_body_w.to(f32),
        v_body_b=r.v_body_b.to(f32),
        omega_body_b=r.omega_body_b.to(f32),
        v_plf_b=r.v_plf_b.to(f32),
        omega_plf_b=r.omega_plf_b.to(f32),
        u_aln=r.u_aln.to(f32),
        action=action.to(f32),
        action_prev=action_prev.to(f32),
        tau=r.tau.to(f32),
        tau_prev=tau_prev.to(f32),
        q_dot=r.q_dot.to(f32),
        q_ddot=((r.q_dot - q_dot_prev) / dt_s).to(f32),
        f_feet_w=r.f_feet_w.to(f32),
        contact=contact,
        touchdown=touchdown,
        liftoff=liftoff,
        t_air_s=torch.where(touchdown, t_air_s, 0.0).to(f32),
        t_contact_s=torch.where(liftoff, t_contact_s, 0.0).to(f32),
        v_slip_p=r.v_slip_p.to(f32),
        collision=r.body_collision | fell,
    )
    return state, t_air_s.masked_fill(contact, 0.0), t_contact_s.masked_fill(~contact, 0.0)
