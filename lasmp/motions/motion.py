"""The common currency of the motion models: a platform motion sampled on a uniform grid.

A :class:`Motion` is the pose of the platform over time in the convention of
:mod:`lasmp.envs.trajectories` (``[x, y, z, roll, pitch, yaw]``, m and rad, relative to the initial
pose, ``R = Rz(yaw) Ry(pitch) Rx(roll)``). :func:`deck_pose` carries a vehicle's centre-of-gravity
motion to a deck point away from it (the lever arm), :func:`to_trajectories` writes motions as one
"samples" trajectory set, and the small checks here give every generator the same error messages.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from lasmp.envs import trajectories as trj

DEFAULT_DT_S = 0.01  # 100 Hz samples: content up to ~20 Hz survives the cubic spline through them
DEFAULT_DURATION_S = 20.0  # every scenario of the suite lasts this long (at least a training episode's 10 s)
GRAVITY_M_S2 = 9.81
# the training trajectories' ranges: the generators report, and never clip, motion beyond them
TRAINING_RANGES = trj.TRAIN_RANGES
MAX_YAW_RAD = TRAINING_RANGES.high[5]


@dataclass
class Motion:
    """One platform motion: ``t_s`` (K,) uniform from 0, ``pose`` (K, 6) with ``pose[0] == 0``.

    ``params`` holds the parameters that made it (JSON-serialisable; stored in the file's meta),
    ``notes`` says how the real motion was fitted to the platform world, if it was.
    """

    name: str
    t_s: np.ndarray
    pose: np.ndarray
    params: dict = field(default_factory=dict)
    notes: str = ""

    def __post_init__(self):
        self.t_s = np.asarray(self.t_s, dtype=np.float64)
        self.pose = np.asarray(self.pose, dtype=np.float64)
        if self.t_s.ndim != 1 or self.pose.shape != (len(self.t_s), 6):
            raise ValueError(
                f"{self.name}: t_s must be (K,) and pose (K, 6), got {self.t_s.shape}, {self.pose.shape}"
            )
        if not np.all(np.isfinite(self.pose)):
            raise ValueError(f"{self.name}: non-finite pose")
        if np.any(np.abs(self.pose[0]) > 1e-9):
            raise ValueError(
                f"{self.name}: pose[0] must be the initial pose (zeros), got {self.pose[0].tolist()}"
            )

    @property
    def dt_s(self) -> float:
        return float(self.t_s[1] - self.t_s[0])

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1])


def _number(where: str, name: str, value, ok, wanted: str) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: {name} must be {wanted}, got {value!r}") from None
    if not (math.isfinite(x) and ok(x)):
        raise ValueError(f"{where}: {name} must be {wanted}, got {value!r}")
    return x


def positive(where: str, name: str, value) -> float:
    """`value` as a float; ValueError naming `where` and `name` unless it is finite and > 0."""
    return _number(where, name, value, lambda x: x > 0, "a positive finite number")


def non_negative(where: str, name: str, value) -> float:
    """`value` as a float; ValueError naming `where` and `name` unless it is finite and >= 0."""
    return _number(where, name, value, lambda x: x >= 0, "a finite number >= 0")


def finite(where: str, name: str, value) -> float:
    """`value` as a float; ValueError naming `where` and `name` unless it is finite."""
    return _number(where, name, value, lambda x: True, "a finite number")


def choice(where: str, name: str, value, valid):
    """`value` unchanged; ValueError naming `where`, `name` and the valid values unless it is one of them."""
    if value not in valid:
        raise ValueError(f"{where}: unknown {name} {value!r}; valid: {list(valid)}")
    return value


def point(where: str, name: str, value, axes: str) -> np.ndarray:
    """`value` as a (3,) float array (a point in a vehicle's frame, m); ValueError unless 3 finite numbers."""
    p = np.asarray(value, dtype=np.float64)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"{where}: {name} must be 3 finite numbers ({axes}) m, got {value!r}")
    return p


def time_grid(duration_s: float, dt_s: float = DEFAULT_DT_S) -> np.ndarray:
    """Uniform times 0, dt, ..., duration (inclusive), s."""
    if duration_s <= 0 or dt_s <= 0:
        raise ValueError(f"duration_s and dt_s must be positive, got {duration_s}, {dt_s}")
    n = int(round(duration_s / dt_s))
    return np.arange(n + 1) * dt_s


def deck_pose(p_cg_w: np.ndarray, euler_zyx: np.ndarray, r_deck_b: np.ndarray) -> np.ndarray:
    """Pose (K, 6) of a deck point rigidly attached to a vehicle, relative to its initial pose.

    p_cg_w (K, 3): the vehicle's centre of gravity in the world, m; euler_zyx (K, 3): the vehicle's
    [roll, pitch, yaw], rad (R = Rz Ry Rx); r_deck_b (3,): the deck point in the vehicle's body
    frame, m (e.g. 30 m forward of a ship's CG). Rotation about the CG moves the deck point by
    R r - R0 r: that lever arm is why a point away from the CG heaves more than the CG does.
    Assumes the vehicle's initial attitude is level (euler_zyx[0] == 0), so the platform's initial
    pose is the zero pose.
    """
    p = np.asarray(p_cg_w, dtype=np.float64)
    e = np.asarray(euler_zyx, dtype=np.float64)
    r = np.asarray(r_deck_b, dtype=np.float64)
    if np.any(np.abs(e[0]) > 1e-9):
        raise ValueError(f"deck_pose: the initial attitude must be level, got {e[0].tolist()}")
    rot = Rotation.from_euler("ZYX", e[:, ::-1])  # intrinsic z-y-x: Rz(yaw) Ry(pitch) Rx(roll)
    p_deck = p + rot.apply(r)
    out = np.empty((len(p), 6))
    out[:, :3] = p_deck - p_deck[0]
    out[:, 3:] = e
    return out


def to_trajectories(motions: list[Motion]) -> trj.PiecewisePoly:
    """The motions as one "samples" trajectory set (rows in order; NaN-padded if lengths differ)."""
    if not motions:
        raise ValueError("to_trajectories: no motions")
    k = max(len(m.t_s) for m in motions)
    t = np.full((len(motions), k), np.nan)
    p = np.full((len(motions), k, 6), np.nan)
    for i, m in enumerate(motions):
        t[i, : len(m.t_s)] = m.t_s
        p[i, : len(m.t_s)] = m.pose
    nk = np.array([len(m.t_s) for m in motions])
    if np.all(nk == k):
        traj = trj.from_samples(t[0], p, where="real-motion suite")
    else:
        traj = trj.PiecewisePoly.from_knots(t, p, nk, trj.SAMPLES, 3, np.full(len(motions), -1))
    traj.meta = {"scenarios": [{"name": m.name, "params": m.params, "notes": m.notes} for m in motions]}
    return traj


def derivatives(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """(velocity, acceleration) (K, 6) of a motion by central differences on its grid."""
    v = np.gradient(motion.pose, motion.t_s, axis=0)
    a = np.gradient(v, motion.t_s, axis=0)
    return v, a
