"""Why a run's curriculum does not promote: the success rate at its level, three ways.

    python scripts/curriculum_probe.py CHECKPOINT [--envs 512] [--seed S] [--std-scales 0.5 ...] [--json out.json [--force]]

The curriculum promotes on the success rate (time-out without a collision) of the *training*
rollouts: the stochastic policy, on the training distribution at the checkpoint's level. This
plays one full episode per env of that same distribution (the checkpoint's curriculum and random
state, training ranges and domain randomization) with
- `mean`: the deployed policy's mean action (what evaluate.py measures),
- `sampled`: actions drawn from the policy's Gaussian with its trained std (what training sees),
  and, with `--std-scales`, with that std scaled (how much noise the level tolerates),
- `stand_still`: a = 0,
and prints each success rate with its binomial standard error, and the first-contact causes.
A gap between `mean` and `sampled` is the exploration noise's share of the failures.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from lasmp.algo.checkpoint import CheckpointError, checkpoint_file  # noqa: E402
from lasmp.deploy import load_deploy_env  # noqa: E402
from lasmp.io.atomic import atomic_open, claim_output  # noqa: E402
from lasmp.io.inputs import InputError, check_out_file  # noqa: E402


def first_episodes(env, act, steps: int) -> dict:
    """Play `steps` policy steps from a fresh reset; each env's first episode's outcome."""
    n = env.num_envs
    outcome = torch.full((n,), -1, dtype=torch.int8)  # -1 running, 0 collided, 1 timed out
    ended_at = torch.zeros(n, dtype=torch.int64)
    obs = env.get_observations()
    with torch.inference_mode():
        for step in range(steps):
            obs, _, dones, extras = env.step(act(obs))
            new = dones & (outcome < 0)
            outcome[new & extras["time_outs"]] = 1
            outcome[new & ~extras["time_outs"]] = 0
            ended_at[new] = step + 1
            if bool((outcome >= 0).all()):
                break
    ended = outcome >= 0
    k, m = int((outcome == 1).sum()), int(ended.sum())
    p = k / m if m else math.nan
    return {
        "episodes": m,
        "success_rate": p,
        "stderr": math.sqrt(p * (1 - p) / m) if m else math.nan,
        "mean_failure_step": float(ended_at[outcome == 0].float().mean()) if (outcome == 0).any() else None,
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("checkpoint")
    p.add_argument("--envs", type=int, default=512)
    p.add_argument("--seed", type=int, default=None, help="default: the checkpoint's own random streams")
    p.add_argument("--std-scales", type=float, nargs="*", default=[], help="extra sampled runs, std scaled")
    p.add_argument("--json", type=Path)
    p.add_argument("--force", action="store_true", help="overwrite --json if it exists")
    args = p.parse_args(argv)
    if args.envs < 1:
        p.error(f"--envs must be >= 1, got {args.envs}")

    if any(s < 0 for s in args.std_scales):
        p.error("--std-scales must be >= 0")
    claims = contextlib.ExitStack()
    try:  # the files named, before the minutes of play
        checkpoint = checkpoint_file(args.checkpoint)
        if args.json:
            check_out_file(args.json, suffixes=(".json",), force=True, option="--json")
            # claimed (create-exclusive): a file already there is refused without --force
            claims.enter_context(claim_output(args.json, force=args.force, option="--json"))
    except (CheckpointError, InputError, OSError) as err:
        p.error(str(err))
    with claims:  # the claim is removed if the play fails
        # (name, std scale): scale None plays the mean action
        modes = [("mean", None), ("sampled", 1.0), *((f"sampled_std_x{s:g}", s) for s in args.std_scales)]
        results = {}
        for name, scale in [*modes, ("stand_still", None)]:
            with contextlib.redirect_stdout(io.StringIO()):  # rsl_rl's models print themselves
                env, policy, cfg, data = load_deploy_env(checkpoint, num_envs=args.envs, seed=args.seed)
            torch.manual_seed(cfg.seed)  # the action noise: the same draws in every mode
            num_actions = int(data["num_actions"])
            dist = policy.distribution
            dist.update(torch.zeros(1, num_actions))  # rsl_rl's std, as its sampling takes it (clamped)
            std = dist.std[0].detach().clone()
            if name == "stand_still":

                def act(obs, n=env.num_envs, a=num_actions):
                    return torch.zeros(n, a)
            elif scale is None:
                act = policy
            else:

                def act(obs, policy=policy, std=std * scale):
                    mean = policy(obs)
                    return mean + std * torch.randn_like(mean)

            level = env.curriculum.level if env.curriculum is not None else None  # its episodes' level
            r = results[name] = {**first_episodes(env, act, int(env.max_episode_length) + 1), "level": level}
            print(
                f"{name:12s} level {level}: success {r['success_rate']:.3f} ± {r['stderr']:.3f} "
                f"over {r['episodes']} episodes (mean failure at step {r['mean_failure_step']})",
                flush=True,
            )
        results["action_std"] = [round(float(s), 4) for s in std]
        print("trained action std:", results["action_std"])
        if args.json:
            with atomic_open(args.json, "w") as f:
                f.write(json.dumps(results, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
