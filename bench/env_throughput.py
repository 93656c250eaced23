"""Throughput of the full moving-platform env vs its raw physics backend on the same model, one run.

The env runs the Stand Still controller (a = 0) with everything on: observations, rewards,
terminations, resets, domain randomization, trajectories. The raw baseline is a second backend of
the same kind (`--backend`: cpu = `mujoco.batch.Batch`, warp = MuJoCo Warp on `--device`) on the
same compiled model, same env count and threads, same per-env parameters, same `nstep =
decimation`, stepped from the very states the env's physics met (`--raw-samples`, 200, recorded
during the env run, each restored with `set_state` before one timed `step`), and does nothing else. The
raw steps are interleaved with the env's (one right after each recorded env step), so that both rates are
measured over the same minutes of a shared machine. Both are reported in policy steps per second (env steps x envs / s);
`ratio` = env / raw; `env_physics_share` is the
share of the env's own wall time spent inside `Batch.step` on its states, `env_other_ms_per_step` the rest
of an env step in ms. Also reports the Stand Still collision rate over the episodes it ended.

    python bench/env_throughput.py --num-envs 1024 --json
    python bench/env_throughput.py --backend warp --device cuda --num-envs 8192 --json
"""

from __future__ import annotations

import argparse
import json
import time

import lasmp  # noqa: F401  (first: it sets the OpenMP spin that torch reads when it loads, lasmp/__init__.py)

# isort: split
import numpy as np
import torch

from lasmp.config.base import build_env_cfg
from lasmp.envs.backends import make_backend
from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
from lasmp.envs.moving_platform.env import MovingPlatformEnv

RAW_SAMPLES = 200  # env states replayed on the raw backend; fewer leave the ratio noisy (docs/performance.md)


def measure(env: MovingPlatformEnv, steps: int, raw_samples: int = RAW_SAMPLES) -> dict:
    """Env policy steps/s with a = 0 and, interleaved with them, raw backend steps/s on the env's own
    states: before every (steps // raw_samples)-th env step the physics state it meets is recorded
    (inside the env's step, the recording's time left out), and right after that env step a second
    backend of the same kind and model restarts from it and takes one timed step. Both rates are
    thus measured over the same minutes, since on a shared machine the speed drifts between minutes;
    the raw rate's own noise shrinks with the samples (docs/performance.md#the-environment)."""
    raw_sim = make_backend(env.cfg.backend, env.sim.model, env.num_envs, env.cfg.sim, env.device)
    actions = torch.zeros(env.num_envs, env.num_actions)
    every = max(1, steps // raw_samples)
    physics_step = env.sim.step
    pending: list = []
    recording_s = [0.0]

    def recording_step(nstep, ids=None):
        if want_snapshot:
            start = time.perf_counter()
            pending.append(env.sim.get_state())
            recording_s[0] += time.perf_counter() - start
        return physics_step(nstep, ids)

    env.sim.step = recording_step
    env.sim.step_time_s = 0.0
    env_s = raw_s = 0.0
    episodes = collisions = raw_steps = 0
    for k in range(steps):
        want_snapshot = k % every == 0
        start = time.perf_counter()
        _, _, done, extras = env.step(actions)
        ended = int(done.sum())  # a host sync each step, so the GPU's queue is drained when timed
        env_s += time.perf_counter() - start
        episodes += ended
        collisions += ended - int(extras["time_outs"].sum())
        while pending:
            raw_sim.set_state(pending.pop())
            before = raw_sim.step_time_s
            raw_sim.step(env.cfg.sim.decimation)
            raw_s += raw_sim.step_time_s - before
            raw_steps += 1
    env.sim.step = physics_step
    env_s -= recording_s[0]
    return {
        "env_steps_per_s": steps * env.num_envs / env_s,
        "raw_steps_per_s": raw_steps * env.num_envs / raw_s,
        # share of the env's wall time spent inside the backend's stepping itself
        "env_physics_share": env.sim.step_time_s / env_s,
        # the rest of an env step (actions, readout, rewards, resets, observations), ms: a steadier measure
        # of the env's own work than the ratio, whose physics part drifts with the machine's load
        "env_other_ms_per_step": (env_s - env.sim.step_time_s) / steps * 1e3,
        "raw_samples": raw_steps,
        "episodes": episodes,
        "collisions": collisions,
    }


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--num-envs", type=int, default=1024)
    p.add_argument("--steps", type=int, default=1000, help="policy steps of the env (2 episodes at 500)")
    p.add_argument(
        "--raw-samples", type=int, default=RAW_SAMPLES, help="env states replayed by the raw backend"
    )
    p.add_argument("--threads", type=int, default=0, help="Batch threads, 0 = all cores")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--backend", choices=("cpu", "warp"), default="cpu", help="physics backend (env.backend)")
    p.add_argument(
        "--device", default="cpu", help="the warp backend's device: cuda[:N], or cpu (Warp's CPU device)"
    )
    p.add_argument(
        "--torch-threads",
        type=int,
        default=1,
        help="torch's threads for the env's tensor work (0: torch's default, all cores, as train.py)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object only")
    args = p.parse_args(argv)
    if args.raw_samples < 1 or args.steps < 1:
        p.error(f"--steps and --raw-samples must be >= 1, got {args.steps} and {args.raw_samples}")
    # the env's tensor work is small; by default leave the cores to the physics threads
    if args.torch_threads > 0:
        torch.set_num_threads(args.torch_threads)
    overrides = {
        "num_envs": args.num_envs,
        "seed": args.seed,
        "backend": args.backend,
        "sim": {"num_threads": args.threads},
    }
    env = MovingPlatformEnv(build_env_cfg(overrides, schema=MovingPlatformCfg), device=args.device)
    env.reset()
    measure(env, 5, raw_samples=1)  # warm-up
    m = measure(env, args.steps, args.raw_samples)
    env_sps, raw, episodes, collisions = (
        m["env_steps_per_s"],
        m["raw_steps_per_s"],
        m["episodes"],
        m["collisions"],
    )
    result = {
        "num_envs": args.num_envs,
        "backend": args.backend,
        "device": str(env.device),
        "threads": env.sim.batch.nthread if args.backend == "cpu" else None,
        "torch_threads": torch.get_num_threads(),
        "env_steps_per_s": round(env_sps, 1),
        "raw_steps_per_s": round(raw, 1),
        "ratio": round(env_sps / raw, 3),
        "env_physics_share": round(m["env_physics_share"], 3),
        "env_other_ms_per_step": round(m["env_other_ms_per_step"], 2),
        "raw_samples": m["raw_samples"],
        "stand_still_episodes": episodes,
        "stand_still_collision_rate": round(collisions / episodes, 4) if episodes else float("nan"),
        "faults": env.fault_count,
    }
    if args.json:
        print(json.dumps(result))
    else:
        for k, v in result.items():
            print(f"{k:>28}: {v}")
    return result


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    main()
