"""Where one training iteration's time goes, for the default config (cfg/, preset=cpu).

Runs rsl_rl's own `learn()` for a few iterations and splits each one into physics
(`Batch.step`), policy inference (`alg.act`: actor + critic forward), the rest of the env step
(observations, rewards, resets), the PPO update and the ROA (estimator) update. Prints one JSON
object with the seconds per iteration of each part, the end-to-end policy steps per second and the
learner it ran (`algo.precision` and what it resolved to: bfloat16 autocast, fused Adam, compiled
MLPs). The untimed warm-up iterations take the compilation (and any recompilation) out of the
timing; `compiles_timed` counts the graphs torch.compile still built while timing (should be 0).
Then one in-training validation (runner.validation_episodes of the validation benchmark, after a first,
untimed one that builds its env) is timed: `validation_share` is its part of the wall time at the
config's runner.validation_interval, validation_s / (validation_s + interval * s_per_iteration).

    python bench/train_iteration.py --json [--num-envs 1024] [--iterations 3] [--warmup 2] [override ...]
    python bench/train_iteration.py --json algo.precision=float32
    python bench/train_iteration.py --json --backend warp --device cuda --num-envs 8192
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import time
from pathlib import Path

from hydra import compose, initialize_config_dir

from lasmp.cli.build import make_runner
from lasmp.config.train import register_configs, to_train_cfg

ROOT = Path(__file__).resolve().parents[1]


def timed(obj, name: str, totals: dict, key: str) -> None:
    """Wrap obj.name so that its wall time accumulates in totals[key]."""
    fn = getattr(obj, name)

    def wrapper(*args, **kwargs):
        start = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            totals[key] += time.perf_counter() - start

    setattr(obj, name, wrapper)


def compiled_graphs() -> int:
    """Graphs torch.compile has built in this process so far (0 before it is first used)."""
    utils = sys.modules.get("torch._dynamo.utils")
    return int(utils.counters["stats"]["unique_graphs"]) if utils is not None else 0


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--num-envs", type=int, default=None, help="default: the config's (1024)")
    p.add_argument("--iterations", type=int, default=3)
    p.add_argument("--warmup", type=int, default=2, help="untimed iterations first (compilation and such)")
    p.add_argument("--backend", choices=("cpu", "warp"), default=None, help="physics backend (env.backend)")
    p.add_argument("--device", default=None, help="learner device, and the warp backend's (cpu, cuda[:N])")
    p.add_argument("--json", action="store_true")
    p.add_argument("--no-validation", action="store_true", help="skip timing the in-training validation")
    p.add_argument("overrides", nargs="*", help="Hydra overrides, e.g. policy=no_alignment_command")
    args = p.parse_args(argv)
    register_configs()
    overrides = list(args.overrides) + ([f"env.num_envs={args.num_envs}"] if args.num_envs else [])
    overrides += [f"env.backend={args.backend}"] if args.backend else []
    overrides += [f"device={args.device}"] if args.device else []
    with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
        cfg = to_train_cfg(compose("config", overrides=overrides))
    with contextlib.redirect_stdout(io.StringIO()) if args.json else contextlib.nullcontext():
        runner = make_runner(cfg, log_dir=None)  # prints a line per network (lasmp/algo/console.py)
    totals = dict.fromkeys(("physics", "inference", "env_step", "update_ppo_and_roa", "update_roa"), 0.0)
    timed(runner.env.sim, "step", totals, "physics")
    timed(runner.alg, "act", totals, "inference")
    timed(runner.env, "step", totals, "env_step")
    timed(runner.alg, "update", totals, "update_ppo_and_roa")
    timed(runner.alg, "update_roa", totals, "update_roa")
    with contextlib.redirect_stdout(io.StringIO()) if args.json else contextlib.nullcontext():
        # warm-up: compilation (the rollout's and the update's graphs; a second iteration catches the
        # recompilations a new shape or mode brings), allocations, first-touch of buffers
        runner.learn(max(args.warmup, 1))
    for key in totals:
        totals[key] = 0.0
    graphs_before = compiled_graphs()
    start = time.perf_counter()
    runner.learn(args.iterations)
    wall = time.perf_counter() - start
    plan = runner.alg.learner_precision
    n = args.iterations
    steps = n * cfg.env.num_envs * cfg.runner.num_steps_per_env
    result = {
        "backend": cfg.env.backend,
        "device": cfg.device,
        "num_envs": cfg.env.num_envs,
        "iterations": n,
        "warmup_iterations": max(args.warmup, 1),
        "precision": plan.precision,
        "bf16_autocast": plan.bf16_autocast,
        "fused_adam": plan.fused_adam,
        "compiled_mlps": plan.compile_mlps,
        "compiles_timed": compiled_graphs() - graphs_before,
        "s_per_iteration": round(wall / n, 3),
        "physics_s": round(totals["physics"] / n, 3),
        "policy_inference_s": round(totals["inference"] / n, 3),
        "env_other_s": round((totals["env_step"] - totals["physics"]) / n, 3),
        "update_ppo_s": round((totals["update_ppo_and_roa"] - totals["update_roa"]) / n, 3),
        "update_roa_s": round(totals["update_roa"] / n, 3),
        "policy_steps_per_s": round(steps / wall, 1),
        # the learner's share against physics (its target: docs/performance.md#training)
        "learner_over_physics": round(totals["update_ppo_and_roa"] / totals["physics"], 3),
    }
    if runner.validator is not None and not args.no_validation:
        result.update(validation_cost(runner, result["s_per_iteration"]))
    if args.json:
        print(json.dumps(result | {"learner": plan.line()}))
    else:
        for k, v in result.items():
            print(f"{k:>20}: {v}")
    return result


def validation_cost(runner, s_per_iteration: float) -> dict:
    """One in-training validation of the runner's current policy, timed warm, and its share of a run."""
    from lasmp.algo.checkpoint import obs_layout

    def validate():
        layout = obs_layout(runner.env.get_observations())
        return runner.validator(0, runner.alg.actor.state_dict(), layout, runner.env.num_actions).seconds

    first = validate()  # builds the validation env (and the benchmark file, on first use)
    seconds = validate()
    interval = runner.validation_interval
    return {
        "validation_episodes": runner.validator.num_episodes,
        "validation_interval": interval,
        "validation_first_s": round(first, 3),
        "validation_s": round(seconds, 3),
        "validation_share": round(seconds / (seconds + interval * s_per_iteration), 4),
    }


if __name__ == "__main__":
    main()
