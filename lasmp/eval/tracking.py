"""Record how the platform follows its reference while a controller plays (Stand Still by default).

Used by `bench/platform_tracking.py` (Xi_eval) and the real-motion suite. Every policy step until an
env's first episode ends, the platform's joint positions and the reference pose are recorded; after
that the env is frozen at its last recorded values (an ended episode restarts the platform at rest).
"""

from __future__ import annotations

import numpy as np
import torch

from lasmp.envs.moving_platform.scene import POSE_TO_JOINT


def record_platform(env, steps: int | None = None) -> dict[str, np.ndarray]:
    """Step `env` (already reset into its episodes) with zero actions for `steps` (default: one
    episode) and return ``q`` and ``ref`` (steps + 1, n, 6) in joint order (x, y, z, yaw, pitch, roll
    as POSE_TO_JOINT orders them), ``live`` (steps + 1, n) the recorded mask, and ``timed_out`` (n,)
    whether the first episode reached its end."""
    n = env.num_envs
    steps = env.max_episode_length if steps is None else steps
    q = np.zeros((steps + 1, n, 6))
    ref = np.zeros((steps + 1, n, 6))
    live_mask = np.zeros((steps + 1, n), bool)
    q[0] = env.sim.qpos[:, env.index.plf_qpos].cpu().numpy()
    live_mask[0] = True
    live = np.ones(n, bool)
    timed_out = np.zeros(n, bool)
    zeros = torch.zeros(n, env.num_actions)
    for k in range(1, steps + 1):
        _, _, done, extras = env.step(zeros)
        done = done.cpu().numpy()
        now = env.sim.qpos[:, env.index.plf_qpos].cpu().numpy()
        want = env.traj.evaluate(np.full(n, k * env.dt_s))[0][:, POSE_TO_JOINT]
        record = live & ~done  # the done step's state is already the reset one
        q[k] = np.where(record[:, None], now, q[k - 1])
        ref[k] = np.where(record[:, None], want, ref[k - 1])
        live_mask[k] = record
        timed_out |= live & done & extras["time_outs"].cpu().numpy()
        live &= ~done
    return {"q": q, "ref": ref, "live": live_mask, "timed_out": timed_out}
