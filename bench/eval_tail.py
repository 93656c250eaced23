"""What shrinking the batch at the tail of an evaluation saves (`run_benchmark(shrink_tail=...)`).

Stand Still plays the first K benchmark episodes on B envs twice, back to back in one process:
every env simulated until the last episode ends, then only the envs still playing an episode.
Prints one JSON object: wall time of each, their ratio, and the env-steps each simulated.
The per-episode metrics of the two runs are checked to be identical.

    python bench/eval_tail.py --episodes 1300 --batch-envs 1024
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch

from lasmp.config.base import build_env_cfg
from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
from lasmp.envs.moving_platform.env import MovingPlatformEnv
from lasmp.eval.build import DEFAULT_BENCHMARK, eval_env_overrides, load_or_make_benchmark
from lasmp.eval.run import run_benchmark


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--episodes", type=int, default=1300)
    p.add_argument("--batch-envs", type=int, default=1024)
    args = p.parse_args(argv)
    bench = load_or_make_benchmark(DEFAULT_BENCHMARK)
    out, episodes = {"episodes": args.episodes, "batch_envs": args.batch_envs}, {}
    for shrink in (False, True):
        env = MovingPlatformEnv(
            build_env_cfg(eval_env_overrides(args.batch_envs, 0), schema=MovingPlatformCfg)
        )
        zeros = torch.zeros(env.num_envs, env.num_actions)
        start = time.perf_counter()
        run = run_benchmark(
            env, lambda obs, zeros=zeros: zeros, bench, args.episodes, progress=False, shrink_tail=shrink
        )
        key = "shrink" if shrink else "full"
        out[f"{key}_wall_s"] = time.perf_counter() - start
        out[f"{key}_env_steps"] = env.sim.env_steps
        episodes[shrink] = run["episodes"]
    out["wall_ratio_shrink_over_full"] = out["shrink_wall_s"] / out["full_wall_s"]
    out["identical_episodes"] = all(
        np.array_equal(episodes[True][k], episodes[False][k], equal_nan=True) for k in episodes[False]
    )
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
