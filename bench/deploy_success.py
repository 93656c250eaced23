"""Success rate of a checkpoint's deployment policy (estimators only) at its curriculum level, and
its stance height: one episode per env, from the checkpoint's own env config (training ranges).

    python bench/deploy_success.py --checkpoint runs/world_cpu_default/model_850.pt --num-envs 1024 --json
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np
import torch

from lasmp.deploy import load_deploy_env


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--checkpoint", required=True)
    ap.add_argument("--num-envs", type=int, default=1024)
    ap.add_argument("--seed", type=int, default=None, help="default: the checkpoint's own random streams")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    env, policy, _, _ = load_deploy_env(args.checkpoint, num_envs=args.num_envs, seed=args.seed)
    obs = env.reset()[0]
    n = env.num_envs
    alive = np.ones(n, bool)
    t_end = np.full(n, env.max_episode_length * env.dt_s)
    heights = []
    with torch.inference_mode():
        for k in range(env.max_episode_length):
            obs, _, done, extras = env.step(policy(obs))
            if k >= 50:  # the trunk's height above the top surface once the stance has settled, m
                heights.append((env.readout.p_body_p[:, 2].numpy() - env.plf_top_m)[alive])
            done = done.numpy() & alive
            t_end[done & ~extras["time_outs"].numpy()] = (k + 1) * env.dt_s
            alive &= ~done
    ok = t_end >= env.max_episode_length * env.dt_s
    h = np.concatenate(heights)
    out = {
        "checkpoint": args.checkpoint,
        "episodes": n,
        "level": int(np.median(env.traj_level)),
        "success_rate": float(ok.mean()),
        "median_failure_s": float(np.median(t_end[~ok])) if (~ok).any() else None,
        "trunk_height_above_surface_m": float(h.mean()),
        "nominal_stance_height_m": float(env.trunk_height_m),
    }
    print(json.dumps(out) if args.json else "\n".join(f"{k}: {v}" for k, v in out.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
