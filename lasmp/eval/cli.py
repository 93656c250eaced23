"""`python evaluate.py`: measure a controller on the benchmark (SPEC §12).

    python evaluate.py --checkpoint PATH [--plot-estimates]      # a trained LAS-MP policy (deployment mode)
    python evaluate.py --controller stand_still                   # PD to q_nominal, a = 0
    python evaluate.py --controller rs --checkpoint RS_PATH       # the R-S policy, zero velocity command
    python evaluate.py --controller rs_oracle --checkpoint RS_PATH  # R-S with the oracle command (below)
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

import numpy as np
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
    """(env, controller, policy with estimators or None, method name)."""
    from lasmp.envs.moving_platform.env import MovingPlatformEnv
    from lasmp.play import load_deploy_policy

    n = min(args.batch_envs, args.num_trajectories)
    if args.controller == "stand_still":
        env = MovingPlatformEnv(build_env_cfg(eval_env_overrides(n, args.seed)))
        zeros = torch.zeros(n, env.num_actions)
        return env, (lambda obs: zeros), None, "stand_still"
    _, policy, cfg = load_deploy_policy(args.checkpoint, num_envs=1, seed=args.seed)
    if args.controller in ("rs", "rs_oracle"):
        if cfg.task != "rough_static" or not policy.command_input:
            raise CheckpointError(f"--controller {args.controller} needs an R-S checkpoint (task=rough_static), "
                                  f"got task={cfg.task}")  # fmt: skip
        env = MovingPlatformEnv(build_env_cfg(eval_env_overrides(n, args.seed)))
        command = oracle_command if args.controller == "rs_oracle" else zero_command

        def rs_controller(obs):
            obs = obs.clone()
            obs["command"] = command(env)
            return policy(obs)

        return env, rs_controller, None, f"{args.controller} ({args.checkpoint})"
    if cfg.task != "moving_platform":
        raise CheckpointError(
            f"--checkpoint without --controller needs a moving_platform policy, got {cfg.task}"
        )
    env_cfg = build_env_cfg({**_asdict(cfg.env), **eval_env_overrides(n, args.seed)})
    env = MovingPlatformEnv(env_cfg)
    return env, (lambda obs: policy(obs)), policy, f"LAS-MP checkpoint {args.checkpoint} ({cfg.policy.name})"


def zero_command(env) -> torch.Tensor:
    return torch.zeros(env.num_envs, 3)


ORACLE_GAIN_PER_S = 1.0  # commanded speed per metre of offset from the platform centre
ORACLE_MAX_MPS = 1.0  # the R-S policy's training command range


def oracle_command(env) -> torch.Tensor:
    """[v_x, v_y, 0] toward the platform centre, in the trunk's heading frame: a clipped proportional
    law on the horizontal offset from the trunk to the platform centre, from privileged world
    positions (v = clip(ORACLE_GAIN_PER_S * offset, +-ORACLE_MAX_MPS) per axis); no yaw command."""
    r = env.readout
    offset_w = r.p_plf_w[:, :2] - r.p_body_w[:, :2]
    yaw = r.phi_body_w[:, 2]
    c, s = np.cos(yaw), np.sin(yaw)
    offset_h = np.stack(
        [c * offset_w[:, 0] + s * offset_w[:, 1], -s * offset_w[:, 0] + c * offset_w[:, 1]], axis=1
    )
    v = np.clip(ORACLE_GAIN_PER_S * offset_h, -ORACLE_MAX_MPS, ORACLE_MAX_MPS)
    return torch.from_numpy(np.concatenate([v, np.zeros((env.num_envs, 1))], axis=1).astype(np.float32))


def _asdict(cfg) -> dict:
    from omegaconf import OmegaConf

    return OmegaConf.to_container(OmegaConf.structured(cfg))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument(
        "--checkpoint", help="a checkpoint file or run directory (LAS-MP, or R-S for rs/rs_oracle)"
    )
    p.add_argument("--controller", choices=["stand_still", "rs", "rs_oracle"],
                   help="a baseline (default with --checkpoint: the checkpoint's own LAS-MP policy)")  # fmt: skip
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
    if args.controller == "stand_still" and args.checkpoint:
        p.error("--controller stand_still takes no --checkpoint")
    if args.controller != "stand_still" and not args.checkpoint:
        p.error("give --checkpoint PATH (a LAS-MP policy, or an R-S policy with --controller rs|rs_oracle)")
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
    run = run_benchmark(
        env, controller, bench, args.num_trajectories, policy=policy, trace=args.plot_estimates
    )
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
        result["estimates_plot_episode"] = run["trace"]["episode"]
        write_results(out_dir, result)
    print((out_dir / "metrics.md").read_text())
    return 0
