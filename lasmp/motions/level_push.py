"""The level-acceleration probe's three motions: does a policy fall under a steady level push that it
survives as the equivalent tilt? (scripts/level_acceleration_probe.py plays them; docs/real_motion.md,
"The shipped policy in the final world", reports what they found.)

- `level_acceleration`: the platform speeds up along x at 1.5 m/s² (a city bus pulling away,
  lasmp.motions.bus), in full from 2 s to 6 s with a smooth 1-s ramp on either side, and nothing
  tilts;
- `equivalent_tilt`: the platform pitches by atan(1.5 / 9.81) = 0.152 rad on the same schedule and
  does not translate, so the apparent gravity in the platform frame turns by the same angle;
- `slow_ramp`: the platform reaches the level push's final speed, 7.5 m/s, at 0.44 m/s² (from 2 s to
  18 s; its tilt equivalent 0.045 rad): the speed without the push.
A robot standing rigidly on the platform meets the same load in both; the policy's observations
differ (its trunk's world roll and pitch stay level in the first).
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import cumulative_trapezoid

from lasmp.motions.motion import GRAVITY_M_S2, Motion, time_grid

ACCELERATION_MPS2 = 1.5
DURATION_S = 20.0
PUSH_S = (1.0, 2.0, 6.0, 7.0)  # ramp up from 1 s to 2 s, in full until 6 s, ramp down to 7 s
SLOW_S = (1.0, 2.0, 18.0, 19.0)


def smooth_step(t: np.ndarray, t0: float, t1: float) -> np.ndarray:
    """0 before t0, 1 after t1, a half cosine between."""
    u = np.clip((t - t0) / (t1 - t0), 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * u)


def profile(t: np.ndarray, times: tuple[float, float, float, float]) -> np.ndarray:
    """0 -> 1 over times[0:2], 1 -> 0 over times[2:4], each a half cosine."""
    return smooth_step(t, *times[:2]) - smooth_step(t, *times[2:])


def surge(t: np.ndarray, acceleration_mps2: np.ndarray) -> np.ndarray:
    """The pose rows of a platform moving along x with this acceleration, from rest."""
    pose = np.zeros((len(t), 6))
    velocity_mps = cumulative_trapezoid(acceleration_mps2, t, initial=0.0)
    pose[:, 0] = cumulative_trapezoid(velocity_mps, t, initial=0.0)
    return pose


def motions() -> list[Motion]:
    """[level_acceleration, equivalent_tilt, slow_ramp], 20 s each."""
    t = time_grid(DURATION_S)
    push = profile(t, PUSH_S)
    tilt = np.zeros((len(t), 6))
    tilt[:, 4] = np.arctan(ACCELERATION_MPS2 / GRAVITY_M_S2) * push  # pitch
    final_speed = ACCELERATION_MPS2 * float(np.sum(push) * (t[1] - t[0]))
    slow = profile(t, SLOW_S)
    slow_acceleration = final_speed / float(np.sum(slow) * (t[1] - t[0]))
    return [
        Motion("level_acceleration", t, surge(t, ACCELERATION_MPS2 * push)),
        Motion("equivalent_tilt", t, tilt),
        Motion("slow_ramp", t, surge(t, slow_acceleration * slow)),
    ]
