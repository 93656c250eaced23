"""Reward terms of the R-S baseline (locomotion on static rough terrain), legged_gym-style.

A registry of small pure functions and their config entry `RewardsCfg` (the weights and
the terms' shape parameters, declared once: the terms read it), summed and logged per episode
by the shared `lasmp.envs.rewards.RewardManager`. Each term returns its UNWEIGHTED value
(num_envs,); the sign lives in the weight; every weighted term is multiplied by dt_s in the
manager.

    track_lin_vel_xy   exp(-‖v_cmd,xy - v_b,xy‖² / sigma)          +1.0
    track_ang_vel_z    exp(-(w_cmd - w_b,z)² / sigma)              +0.5
    lin_vel_z          v_b,z²                                      -2.0
    ang_vel_xy         ‖w_b,xy‖²                                   -0.05
    torques            ‖tau‖²                                      -1e-4
    joint_acc          ‖q_ddot‖²                                   -2.5e-7
    action_rate        ‖a - a_prev‖²                               -0.01
    body_contact       1 if trunk/hip/thigh/calf touches the ground -1.0
    orientation        ‖g_xy in b‖² (unit gravity, = sin² of the tilt) -1.0
    feet_air_time      Σ_i touchdown_i (t_air_i - 0.5 s), command != 0   +1.0
    stand_still        ‖q - q_nominal‖₁, command == 0              -0.1

Our choices: sigma = 0.25 (legged_gym's tracking_sigma); velocities are the trunk's (link
origin) in its own frame; feet_air_time is the one signed term (as legged_gym: short steps
cost, long swings pay) and is paid only while the command is non-zero (legged_gym uses
‖v_cmd,xy‖ > 0.1; ours: any non-zero command, since zero commands are exactly zero).
body_contact also terminates the episode, so it fires on the fall's last step only.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch

from lasmp.config.checks import Bound
from lasmp.envs import rewards as shared
from lasmp.envs.rough_static.state import StepState

REWARD_TERMS, reward_term = shared.make_registry()  # name -> fn(StepState, RewardsCfg)


_sq = shared.squared_norm


def _moving(s: StepState) -> torch.Tensor:
    return torch.any(s.command != 0, dim=-1).to(s.v_body_b.dtype)


@reward_term
def track_lin_vel_xy(s: StepState, c: RewardsCfg) -> torch.Tensor:
    return torch.exp(-_sq(s.command[:, :2] - s.v_body_b[:, :2]) / c.tracking_sigma)


@reward_term
def track_ang_vel_z(s: StepState, c: RewardsCfg) -> torch.Tensor:
    return torch.exp(-torch.square(s.command[:, 2] - s.omega_body_b[:, 2]) / c.tracking_sigma)


@reward_term
def lin_vel_z(s: StepState, c: RewardsCfg) -> torch.Tensor:
    return torch.square(s.v_body_b[:, 2])


@reward_term
def ang_vel_xy(s: StepState, c: RewardsCfg) -> torch.Tensor:
    return _sq(s.omega_body_b[:, :2])


torques = reward_term(shared.torque_sq, "torques")
joint_acc = reward_term(shared.joint_acc_sq, "joint_acc")
action_rate = reward_term(shared.action_rate_sq, "action_rate")


@reward_term
def body_contact(s: StepState, c: RewardsCfg) -> torch.Tensor:
    return s.collision.to(s.v_body_b.dtype)


@reward_term
def orientation(s: StepState, c: RewardsCfg) -> torch.Tensor:
    return _sq(s.gravity_b[:, :2])


@reward_term
def feet_air_time(s: StepState, c: RewardsCfg) -> torch.Tensor:
    paid = s.touchdown.to(s.t_air_s.dtype) * (s.t_air_s - c.air_time_target_s)
    return torch.sum(paid, dim=-1) * _moving(s)


@reward_term
def stand_still(s: StepState, c: RewardsCfg) -> torch.Tensor:
    return torch.sum(torch.abs(s.q_dev), dim=-1) * (1.0 - _moving(s))


DEFAULT_REWARD_WEIGHTS: dict[str, float] = {
    "track_lin_vel_xy": 1.0,
    "track_ang_vel_z": 0.5,
    "lin_vel_z": -2.0,
    "ang_vel_xy": -0.05,
    "torques": -1e-4,
    "joint_acc": -2.5e-7,
    "action_rate": -0.01,
    "body_contact": -1.0,
    "orientation": -1.0,
    "feet_air_time": 1.0,
    "stand_still": -0.1,
}


REWARD_BOUNDS = {
    "tracking_sigma": Bound(0, 25, "(m/s)^2 and (rad/s)^2: the commands span +-5", open_lo=True),
    "air_time_target_s": Bound(0, 10, "s: half the default episode"),
}


@dataclass
class RewardsCfg:
    """`env.rewards`: a weight per term (0 skips it) and the terms' shape parameters."""

    weights: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_REWARD_WEIGHTS))
    tracking_sigma: float = 0.25  # (m/s)² and (rad/s)²
    air_time_target_s: float = 0.5

    BOUNDS = REWARD_BOUNDS
    NAMED = shared.weights_of(REWARD_TERMS)
