"""At what platform tilt does the standing robot (Stand Still, nominal parameters) fall, and how far
does it creep down the slope before? One env per case: the reference's roll or pitch ramps at
0.08 rad/s from 0, with the robot at yaw 0 or 90 deg, in the given contact settings; the tilt
reported is the platform's own (its last value before the fall), which lags the reference.

    python bench/tipping_angle.py --json                        # MuJoCo's default contacts
    python bench/tipping_angle.py --noslip 4 --json             # with a no-slip pass
    python bench/tipping_angle.py --cone elliptic --impratio 10 --json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile

import numpy as np
import torch

from lasmp.config.base import build_env_cfg
from lasmp.envs import trajectories as T
from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
from lasmp.envs.moving_platform.env import MovingPlatformEnv

RATE_RAD_S = 0.08
CREEP_AT_RAD = 0.32  # report the trunk's drift in the platform frame when the tilt reaches this


def fall_tilt(axis: str, yaw: float, sim: dict, path: str) -> dict:
    t = np.linspace(0.0, 10.0, 101)
    poses = np.zeros((1, len(t), 6))
    poses[0, :, T.POSE_NAMES.index(axis)] = RATE_RAD_S * t
    T.save(path, T.from_samples(t, poses))
    overrides = {
        "num_envs": 1,
        "domain_rand": {"enabled": False},
        "curriculum": {"enabled": False},
        "trajectory": {"file": path},
        "init_state": {"yaw_range_rad": [yaw, yaw]},
        "sim": sim,
    }
    env = MovingPlatformEnv(build_env_cfg(overrides, schema=MovingPlatformCfg))
    env.reset()
    creep, tilt = None, 0.0
    for _ in range(env.max_episode_length):
        _, _, done, extras = env.step(torch.zeros(1, 12))
        if done[0]:
            break
        # the platform's, not the reference's
        tilt = float(np.arccos(np.clip(float(env.readout.r_wp[0, 2, 2]), -1.0, 1.0)))
        if creep is None and tilt >= CREEP_AT_RAD:
            creep = float(np.linalg.norm(env.readout.p_body_p[0, :2].numpy()))
    fell = bool(done[0]) and not bool(extras["time_outs"][0])
    return {
        "axis": axis,
        "robot_yaw_deg": round(np.degrees(yaw)),
        "fell": fell,
        "tilt_at_fall_rad": tilt if fell else None,
        f"creep_at_{CREEP_AT_RAD}_rad_m": creep,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cone", default="pyramidal", choices=("pyramidal", "elliptic"))
    ap.add_argument("--impratio", type=float, default=1.0)
    ap.add_argument("--noslip", type=int, default=0, help="sim.noslip_iterations")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    sim = {"cone": args.cone, "impratio": args.impratio, "noslip_iterations": args.noslip}
    with tempfile.TemporaryDirectory() as tmp:
        rows = [
            fall_tilt(axis, yaw, sim, os.path.join(tmp, "ramp.npz"))
            for axis in ("roll", "pitch")
            for yaw in (0.0, np.pi / 2)
        ]
    out = {"sim": sim, "cases": rows}
    print(json.dumps(out) if args.json else "\n".join(map(str, rows)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
