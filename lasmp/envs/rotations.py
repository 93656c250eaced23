"""Batched rotation helpers on torch tensors (any device, float32 or float64). Quaternions are
MuJoCo's (w, x, y, z).

`R_ab` maps vectors from frame b to frame a: v_a = R_ab @ v_b.
"""

from __future__ import annotations

import torch


def quat_to_mat(q: torch.Tensor) -> torch.Tensor:
    """(n, 4) unit quaternions -> (n, 3, 3) rotation matrices."""
    w, x, y, z = q.unbind(-1)
    rows = (
        1 - 2 * (y * y + z * z),
        2 * (x * y - w * z),
        2 * (x * z + w * y),
        2 * (x * y + w * z),
        1 - 2 * (x * x + z * z),
        2 * (y * z - w * x),
        2 * (x * z - w * y),
        2 * (y * z + w * x),
        1 - 2 * (x * x + y * y),
    )
    return torch.stack(rows, dim=-1).reshape(q.shape[:-1] + (3, 3))


def mat_from_euler_zyx(roll: torch.Tensor, pitch: torch.Tensor, yaw: torch.Tensor) -> torch.Tensor:
    """R = Rz(yaw) Ry(pitch) Rx(roll), (n, 3, 3)."""
    cr, sr = torch.cos(roll), torch.sin(roll)
    cp, sp = torch.cos(pitch), torch.sin(pitch)
    cy, sy = torch.cos(yaw), torch.sin(yaw)
    rows = (
        cy * cp,
        cy * sp * sr - sy * cr,
        cy * sp * cr + sy * sr,
        sy * cp,
        sy * sp * sr + cy * cr,
        sy * sp * cr - cy * sr,
        -sp,
        cp * sr,
        cp * cr,
    )
    return torch.stack(rows, dim=-1).reshape(roll.shape + (3, 3))


def euler_zyx_from_mat(r: torch.Tensor) -> torch.Tensor:
    """(n, 3, 3) -> (n, 3) [roll, pitch, yaw] with R = Rz(yaw) Ry(pitch) Rx(roll)."""
    roll = torch.atan2(r[:, 2, 1], r[:, 2, 2])
    pitch = torch.asin(torch.clamp(-r[:, 2, 0], -1.0, 1.0))
    yaw = torch.atan2(r[:, 1, 0], r[:, 0, 0])
    return torch.stack([roll, pitch, yaw], dim=1)


def yaw_quat(yaw: torch.Tensor) -> torch.Tensor:
    """(n,) yaw angles -> (n, 4) quaternions of a rotation about world z."""
    zero = torch.zeros_like(yaw)
    return torch.stack([torch.cos(yaw / 2), zero, zero, torch.sin(yaw / 2)], dim=1)


def rotate_inv(r_ab: torch.Tensor, v_a: torch.Tensor) -> torch.Tensor:
    """v_b = R_ab^T v_a for (n, 3, 3) and (n, 3) or (n, k, 3). As row vectors, v_b^T = v_a^T R_ab."""
    if v_a.ndim == 2:
        return torch.matmul(v_a.unsqueeze(1), r_ab).squeeze(1)
    return torch.matmul(v_a, r_ab)
