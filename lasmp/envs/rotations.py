"""Batched rotation helpers (numpy, float64). Quaternions are MuJoCo's (w, x, y, z).

`R_ab` maps vectors from frame b to frame a: v_a = R_ab @ v_b.
"""

from __future__ import annotations

import numpy as np


def quat_to_mat(q: np.ndarray) -> np.ndarray:
    """(n, 4) unit quaternions -> (n, 3, 3) rotation matrices."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    out = np.empty((q.shape[0], 3, 3))
    out[:, 0, 0] = 1 - 2 * (y * y + z * z)
    out[:, 0, 1] = 2 * (x * y - w * z)
    out[:, 0, 2] = 2 * (x * z + w * y)
    out[:, 1, 0] = 2 * (x * y + w * z)
    out[:, 1, 1] = 1 - 2 * (x * x + z * z)
    out[:, 1, 2] = 2 * (y * z - w * x)
    out[:, 2, 0] = 2 * (x * z - w * y)
    out[:, 2, 1] = 2 * (y * z + w * x)
    out[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return out


def mat_from_euler_zyx(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), (n, 3, 3)."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    out = np.empty((np.shape(roll)[0], 3, 3))
    out[:, 0, 0] = cy * cp
    out[:, 0, 1] = cy * sp * sr - sy * cr
    out[:, 0, 2] = cy * sp * cr + sy * sr
    out[:, 1, 0] = sy * cp
    out[:, 1, 1] = sy * sp * sr + cy * cr
    out[:, 1, 2] = sy * sp * cr - cy * sr
    out[:, 2, 0] = -sp
    out[:, 2, 1] = cp * sr
    out[:, 2, 2] = cp * cr
    return out


def euler_zyx_from_mat(r: np.ndarray) -> np.ndarray:
    """(n, 3, 3) -> (n, 3) [roll, pitch, yaw] with R = Rz(yaw) Ry(pitch) Rx(roll)."""
    roll = np.arctan2(r[:, 2, 1], r[:, 2, 2])
    pitch = np.arcsin(np.clip(-r[:, 2, 0], -1.0, 1.0))
    yaw = np.arctan2(r[:, 1, 0], r[:, 0, 0])
    return np.stack([roll, pitch, yaw], axis=1)


def yaw_quat(yaw: np.ndarray) -> np.ndarray:
    """(n,) yaw angles -> (n, 4) quaternions of a rotation about world z."""
    out = np.zeros((yaw.shape[0], 4))
    out[:, 0] = np.cos(yaw / 2)
    out[:, 3] = np.sin(yaw / 2)
    return out


def rotate_inv(r_ab: np.ndarray, v_a: np.ndarray) -> np.ndarray:
    """v_b = R_ab^T v_a for (n, 3, 3) and (n, 3) or (n, k, 3)."""
    if v_a.ndim == 2:
        return np.einsum("nji,nj->ni", r_ab, v_a)
    return np.einsum("nji,nkj->nki", r_ab, v_a)
