"""`python evaluate.py`: measure a controller on the benchmark (SPEC §12).

    python evaluate.py --checkpoint PATH [--plot-estimates]      # a trained LAS-MP policy (deployment mode)
    python evaluate.py --controller stand_still                   # PD to q_nominal, a = 0
    options: --benchmark FILE (default benchmarks/xi_eval.npz, made on first use)
             --trajectories FILE (any trajectory file; robots still come from the benchmark)
             --num-trajectories K (the first K episodes) --out DIR --batch-envs 1024 --seed 0

Writes DIR/metrics.json and DIR/metrics.md (definitions: lasmp/eval/metrics.py and README).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import torch

from lasmp.algo.runner import CheckpointError
from lasmp.config import build_env_cfg
from lasmp.envs import trajectories as trj
from lasmp.eval import benchmark as bm
from lasmp.eval.metrics import summarize
from lasmp.eval.report import plot_estimates, write_results
from lasmp.eval.run import run_benchmark

DEFAULT_BENCHMARK = Path("benchmarks") / "xi_eval.npz"
NUM_BATCHES = 10


def eval_env_overrides(num_envs: int, seed: int) -> dict:
    """Evaluation: the benchmark decides trajectories and robots; no curriculum."""
    return {"num_envs": num_envs, "seed": seed, "curriculum": {"enabled": False},
            "trajectory": {"split": "test"}, "domain_rand": {"split": "test"}}  # fmt: skip


def load_or_make_benchmark(path: Path):
    if path.exists():
        return bm.load(path)
    if path != DEFAULT_BENCHMARK:
        raise bm.BenchmarkFileError(f"benchmark file {path} does not exist")
    print(f"{path} not found: generating it (seed 0, 10,000 trajectories, 1,024 robots)", file=sys.stderr)
    bench = bm.generate()
    bm.save(path, bench)
    return bench


def build(args):
    """(env, controller, policy or None, method name)."""
    n = min(args.batch_envs, args.num_trajectories)
    if args.checkpoint:
        from lasmp.envs.moving_platform.env import MovingPlatformEnv
        from lasmp.play import load_deploy_policy

        _, policy, cfg = load_deploy_policy(args.checkpoint, num_envs=1, seed=args.seed)
        env_cfg = dataclasses.replace(cfg.env)
        env_cfg = build_env_cfg({**_asdict(env_cfg), **eval_env_overrides(n, args.seed)})
        env = MovingPlatformEnv(env_cfg)
        return env, (lambda obs: policy(obs)), policy, f"checkpoint {args.checkpoint} ({cfg.policy.name})"
    from lasmp.envs.moving_platform.env import MovingPlatformEnv

    env = MovingPlatformEnv(build_env_cfg(eval_env_overrides(n, args.seed)))
    zeros = torch.zeros(n, env.num_actions)
    return env, (lambda obs: zeros), None, args.controller


def _asdict(cfg) -> dict:
    from omegaconf import OmegaConf

    return OmegaConf.to_container(OmegaConf.structured(cfg))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    who = p.add_mutually_exclusive_group(required=True)
    who.add_argument("--checkpoint", help="a checkpoint file or run directory of a LAS-MP policy")
    who.add_argument("--controller", choices=["stand_still"], help="a baseline controller")
    p.add_argument("--benchmark", type=Path, default=DEFAULT_BENCHMARK)
    p.add_argument("--trajectories", type=Path, help="a trajectory file to play instead of the benchmark's")
    p.add_argument("--num-trajectories", type=int, default=None, help="the first K episodes (default: all)")
    p.add_argument("--batch-envs", type=int, default=1024)
    p.add_argument("--out", type=Path, default=None, help="default: eval/<method>")
    p.add_argument(
        "--plot-estimates", action="store_true", help="estimated vs true x_exp over episode 0 (PNG)"
    )
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    try:
        bench = load_or_make_benchmark(args.benchmark)
        if args.trajectories is not None:
            bench = dataclasses.replace(bench, trajectories=trj.load(args.trajectories))
        total = len(bench.trajectories)
        args.num_trajectories = total if args.num_trajectories is None else args.num_trajectories
        if not 1 <= args.num_trajectories <= total:
            p.error(f"--num-trajectories must be in [1, {total}], got {args.num_trajectories}")
        if args.batch_envs < 1:
            p.error(f"--batch-envs must be >= 1, got {args.batch_envs}")
        env, controller, policy, method = build(args)
    except (CheckpointError, bm.BenchmarkFileError, trj.TrajectoryFileError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    out_dir = args.out or Path("eval") / (args.controller or Path(str(args.checkpoint)).name)
    if args.plot_estimates and policy is None:
        p.error("--plot-estimates needs --checkpoint (a policy with estimators)")
    run = run_benchmark(env, controller, bench, args.num_trajectories, policy=policy,
                        plot_episode=0 if args.plot_estimates else None)  # fmt: skip
    episodes = run["episodes"]
    result = {
        "method": method,
        "benchmark": str(args.trajectories or args.benchmark),
        "num_episodes": args.num_trajectories,
        "std_over": f"{min(NUM_BATCHES, args.num_trajectories)} consecutive equal batches of episodes",
        "metrics": summarize(episodes, NUM_BATCHES),
        "mean_episode_steps": float(episodes["steps"].mean()),
        "wall_time_s": run["wall_time_s"],
    }
    if "estimator" in run:
        result["estimator"] = run["estimator"]
    write_results(out_dir, result)
    if args.plot_estimates and run.get("trace") is not None and len(policy.estimation_names):
        plot_estimates(run["trace"], policy.estimation_names, env.dt_s, out_dir / "estimates.png")
    print((out_dir / "metrics.md").read_text())
    return 0
