"""How the platform follows its reference in the calibrated world, on Xi_eval's trajectories.

Stand Still (a = 0) plays the first K benchmark episodes (trajectory k, robot k, with the robot's
test-range platform gain factors, or the factors given). Every policy step until the episode ends
(time-out or collision) records the platform's joint positions and its reference. Reported:
- tracking error |x_plf - x_ref|: RMS and maximum, translation (m, norm over x, y, z) and rotation
  (rad, norm over the three Euler angles);
- the platform's own translational path length (m) and mean speed (m/s) over the episodes that
  reach T, against the reference's over the same episodes;
- `coverage`: the share of the K x T episode time that was recorded.

    python bench/platform_tracking.py --episodes 1024 --json
    python bench/platform_tracking.py --episodes 1024 --factors 0.5 0.01 --json   # kp and kd factors
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from lasmp.config.base import build_env_cfg
from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
from lasmp.envs.moving_platform.env import MovingPlatformEnv
from lasmp.eval.build import DEFAULT_BENCHMARK, eval_env_overrides, load_or_make_benchmark
from lasmp.eval.run import BenchmarkSource
from lasmp.eval.tracking import record_platform


def measure(episodes: int, factors: tuple[float, float] | None) -> dict:
    bench = load_or_make_benchmark(DEFAULT_BENCHMARK).subset(episodes)
    if factors is not None:
        bench.robots.platform_kp_factor[:] = factors[0]
        bench.robots.platform_kd_factor[:] = factors[1]
    env = MovingPlatformEnv(build_env_cfg(eval_env_overrides(episodes, 0), schema=MovingPlatformCfg))
    env.episode_source = BenchmarkSource(bench, episodes, episodes)
    env.reset()
    rec = record_platform(env)
    err = rec["q"] - rec["ref"]
    live = rec["live"][1:]
    et = np.linalg.norm(err[1:, :, :3], axis=2)[live]
    er = np.linalg.norm(err[1:, :, 3:], axis=2)[live]
    complete = rec["timed_out"]

    def length(x):
        return np.linalg.norm(np.diff(x, axis=0), axis=2).sum(axis=0)

    t_s = env.max_episode_length * env.dt_s
    plf, ref = length(rec["q"][:, :, :3])[complete], length(rec["ref"][:, :, :3])[complete]
    return {
        "episodes": episodes,
        "factors": "benchmark robots" if factors is None else list(factors),
        "coverage": float(live.mean()),
        "translation_error_rms_m": float(np.sqrt(np.mean(et**2))),
        "translation_error_max_m": float(et.max()),
        "rotation_error_rms_rad": float(np.sqrt(np.mean(er**2))),
        "rotation_error_max_rad": float(er.max()),
        "complete_episodes": int(complete.sum()),
        "platform_path_length_m": float(plf.mean()),
        "reference_path_length_m": float(ref.mean()),
        "platform_mean_speed_mps": float(plf.mean() / t_s),
        "reference_mean_speed_mps": float(ref.mean() / t_s),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--episodes", type=int, default=1024)
    ap.add_argument(
        "--factors", type=float, nargs=2, metavar=("KP", "KD"), help="platform gain factors for all"
    )
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    out = measure(args.episodes, None if args.factors is None else tuple(args.factors))
    print(json.dumps(out) if args.json else "\n".join(f"{k}: {v}" for k, v in out.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
