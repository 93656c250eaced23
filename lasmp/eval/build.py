"""What an evaluation plays: the benchmark it reads, the env it builds (the evaluation's overrides on
the checkpoint's or the default world) and the controller on it (a trained policy, Stand Still, or the
R-S policy with a zero or an oracle command). evaluate.py (lasmp/eval/cli.py), the in-training
validation, play.py and the benchmarks in bench/ build with these.
"""

from __future__ import annotations

from pathlib import Path

import torch

from lasmp.algo.checkpoint import CheckpointError, check_compatible
from lasmp.config.recipe import recipe_name
from lasmp.deploy import check_backend, load_policy
from lasmp.eval import benchmark as bm

DEFAULT_BENCHMARK = Path(bm.XI_EVAL.path)


def eval_env_overrides(num_envs: int, seed: int, extra: dict | None = None) -> dict:
    """Evaluation: the benchmark decides trajectories and robots; no curriculum. `extra` (nested)
    is merged on top (the real-motion suite's episode length and platform drive)."""
    base = {
        "num_envs": num_envs,
        "seed": seed,
        "curriculum": {"enabled": False},
        "trajectory": {"split": "test", "hold_s": 0.0},  # a training run's hold never reaches Xi_eval
        "domain_rand": {"split": "test"},
    }
    return deep_merge(base, extra or {})


def deep_merge(base: dict, top: dict) -> dict:
    """`top` merged into a copy of `base`, recursively for nested dicts."""
    out = dict(base)
    for key, value in top.items():
        out[key] = (
            deep_merge(out[key], value)
            if isinstance(value, dict) and isinstance(out.get(key), dict)
            else value
        )
    return out


def benchmark_arg(text: str) -> Path:
    """--benchmark: a set's name (xi_eval, validation) stands for its file; anything else is a file."""
    return Path(bm.SETS[text].path) if text in bm.SETS else Path(text)


def load_or_make_benchmark(path: Path):
    """The benchmark file `path`; a set's own file (Xi_eval's, the validation set's) is made on first use."""
    for which in bm.SETS.values():
        if path == Path(which.path):
            return bm.load_or_make(which)
    if not path.exists():
        raise bm.BenchmarkFileError(f"benchmark file {path} does not exist")
    return bm.load(path)


def build(args, extra_env: dict | None = None, checkpoint: Path | None = None):
    """(env, controller, policy with estimators or None, method name); `extra_env`: env overrides;
    `checkpoint`: the file --checkpoint names (a run directory's latest, resolved once by the caller,
    so the file loaded is the file hashed)."""
    from lasmp.config.base import build_env_cfg
    from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
    from lasmp.envs.moving_platform.env import MovingPlatformEnv

    n = min(args.batch_envs, args.num_trajectories)
    overrides = eval_env_overrides(n, args.seed, extra_env)
    if args.controller == "stand_still":
        env = MovingPlatformEnv(build_env_cfg(overrides, schema=MovingPlatformCfg))
        zeros = torch.zeros(n, env.num_actions)
        return env, (lambda obs: zeros), None, "stand_still"
    deployed = load_policy(checkpoint or args.checkpoint, seed=args.seed)
    policy, cfg = deployed.policy, deployed.cfg
    if args.controller in ("rs", "rs_oracle"):
        if cfg.task != "rough_static" or not policy.command_input:
            raise CheckpointError(
                f"--controller {args.controller} needs an R-S checkpoint (task=rough_static), "
                f"got task={cfg.task}"
            )
        env = MovingPlatformEnv(build_env_cfg(overrides, schema=MovingPlatformCfg))
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
    check_backend(deployed)  # a warp checkpoint without MuJoCo Warp: refused before the env is built
    env = policy_eval_env(cfg, n, args.seed, extra_env)
    check_compatible(deployed.checkpoint, env)
    method = f"{recipe_name(cfg)} checkpoint {args.checkpoint} ({cfg.policy.name})"
    return env, (lambda obs: policy(obs)), policy, method


def policy_eval_env(cfg, num_envs: int, seed: int, extra_env: dict | None = None):
    """The moving-platform env a policy of config `cfg` (a TrainCfg) is evaluated in: its own env config
    under the benchmark's overrides (`eval_env_overrides`), `num_envs` envs."""
    from lasmp.config.base import build_env_cfg
    from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
    from lasmp.envs.moving_platform.env import MovingPlatformEnv

    overrides = eval_env_overrides(num_envs, seed, extra_env)
    return MovingPlatformEnv(build_env_cfg(deep_merge(_asdict(cfg.env), overrides), schema=MovingPlatformCfg))


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
    c, s = torch.cos(yaw), torch.sin(yaw)
    offset_h = torch.stack(
        [c * offset_w[:, 0] + s * offset_w[:, 1], -s * offset_w[:, 0] + c * offset_w[:, 1]], dim=1
    )
    v = torch.clamp(ORACLE_GAIN_PER_S * offset_h, -ORACLE_MAX_MPS, ORACLE_MAX_MPS)
    return torch.cat([v, torch.zeros_like(v[:, :1])], dim=1).to(torch.float32)


def _asdict(cfg) -> dict:
    from omegaconf import OmegaConf

    return OmegaConf.to_container(OmegaConf.structured(cfg))
