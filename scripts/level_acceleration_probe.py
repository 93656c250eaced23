"""Does a policy fall under a steady level acceleration that it survives as the equivalent tilt?

    python scripts/level_acceleration_probe.py --checkpoint resources/policies/lasmp_a1.pt --out DIR
    python scripts/level_acceleration_probe.py --controller stand_still --out DIR

Two 20-s motions, played as the real-motion suite plays its scenarios (the benchmark's first 64
robots, the close platform drive; any `evaluate.py --suite` option passes through):
- `level_acceleration`: the platform speeds up along x at 1.5 m/s² (a city bus pulling away,
  lasmp.motions.bus), in full from 2 s to 6 s with a smooth 1-s ramp on either side, and nothing
  tilts;
- `equivalent_tilt`: the platform pitches by atan(1.5 / 9.81) = 0.152 rad on the same schedule and
  does not translate, so the apparent gravity in the platform frame turns by the same angle.
A robot standing rigidly on the platform meets the same load in both; the policy's observations
differ (its trunk's world roll and pitch stay level in the first). docs/real_motion.md, "The shipped
policy in the final world", reports what it found.
"""

from __future__ import annotations

import sys

import numpy as np

from lasmp.eval import cli
from lasmp.motions.motion import Motion, time_grid

ACCELERATION_MPS2 = 1.5
GRAVITY_MPS2 = 9.81
DURATION_S = 20.0


def smooth_step(t: np.ndarray, t0: float, t1: float) -> np.ndarray:
    """0 before t0, 1 after t1, a half cosine between."""
    u = np.clip((t - t0) / (t1 - t0), 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * u)


def integrate(y: np.ndarray, dt: float) -> np.ndarray:
    """The trapezoidal running integral of samples y from 0."""
    return np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * dt)])


def motions() -> list[Motion]:
    t = time_grid(DURATION_S)
    profile = smooth_step(t, 1.0, 2.0) - smooth_step(t, 6.0, 7.0)  # on from 2 s to 6 s
    dt = float(t[1] - t[0])
    level = np.zeros((len(t), 6))
    level[:, 0] = integrate(integrate(ACCELERATION_MPS2 * profile, dt), dt)
    tilt = np.zeros((len(t), 6))
    tilt[:, 4] = np.arctan(ACCELERATION_MPS2 / GRAVITY_MPS2) * profile  # pitch
    return [Motion("level_acceleration", t, level), Motion("equivalent_tilt", t, tilt)]


if __name__ == "__main__":
    sys.exit(cli.main([*sys.argv[1:], "--suite", "real_motion"], motions=motions()))
