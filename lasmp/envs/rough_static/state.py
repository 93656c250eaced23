"""The per-step quantities that the R-S baseline's rewards read.

The environment fills one `StepState` after every policy step; reward terms are pure functions of it
(as `lasmp.envs.moving_platform.state` for the moving-platform task). All tensors are float32 (bool
where noted) with a leading `num_envs` dimension. Frames: `b` trunk (as `lasmp.envs.robot` defines
it: origin at the trunk link's origin). Units: SI (m, s, rad, N, N·m).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch


@dataclass
class StepState:
    dt_s: float  # policy step, s
    v_body_b: torch.Tensor  # (n, 3) trunk velocity, body frame, m/s
    omega_body_b: torch.Tensor  # (n, 3) trunk angular velocity, body frame, rad/s
    command: torch.Tensor  # (n, 3) [v_x, v_y, w_z] command, body frame
    gravity_b: torch.Tensor  # (n, 3) unit gravity direction in the body frame
    q_dev: torch.Tensor  # (n, 12) q - q_nominal, rad
    tau: torch.Tensor  # (n, 12) N·m
    q_ddot: torch.Tensor  # (n, 12) rad/s²
    action: torch.Tensor  # (n, 12)
    action_prev: torch.Tensor  # (n, 12)
    collision: torch.Tensor  # (n,) bool, a trunk/hip/thigh/calf geom touches anything (a fall)
    touchdown: torch.Tensor  # (n, 4) bool, foot made contact this step
    t_air_s: torch.Tensor  # (n, 4) length of the air phase that ended at touchdown, s
