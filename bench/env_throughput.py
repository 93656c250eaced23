"""Throughput of the full moving-platform env vs its raw physics backend on the same model, one run.

The env runs the Stand Still controller (a = 0) with everything on: observations, rewards,
terminations, resets, domain randomization, trajectories. The raw baseline is a second backend of
the same kind (`--backend`: cpu = `mujoco.batch.Batch`, warp = MuJoCo Warp on `--device`) on the
same compiled model, same env count and threads, same per-env parameters, same `nstep =
decimation`, stepped from the very states the env's physics met (50 recorded during the env run,
each restored with `set_state` before one timed `step`), and does nothing else. Both are reported in policy steps per second (env steps x envs / s);
`ratio` = env / raw; `env_physics_share` is the
share of the env's own wall time spent inside `Batch.step` on its states. Also reports the Stand Still collision rate over the episodes it ended.

    python bench/env_throughput.py --num-envs 1024 --json
    python bench/env_throughput.py --backend warp --device cuda --num-envs 8192 --json
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch

from lasmp.envs.backends import make_backend
from lasmp.envs.moving_platform.env import MovingPlatformEnv


def measure_env(env: MovingPlatformEnv, steps: int, snapshots: list | None = None) -> tuple[float, int, int]:
    """Env policy steps/s with a = 0; optionally records the physics state before some steps."""
    actions = torch.zeros(env.num_envs, env.num_actions)
    episodes = collisions = 0
    env.sim.step_time_s = 0.0
    physics_step = env.sim.step
    if snapshots is not None:  # the physics state (and per-env model) as each step sees it
        every = max(1, steps // 50)

        def recording_step(nstep, ids=None):
            if len(snapshots) < 50 and int(env.episode_length_buf[0]) % every == 0:
                snapshots.append(env.sim.get_state())
            return physics_step(nstep, ids)

        env.sim.step = recording_step
    start = time.perf_counter()
    for _ in range(steps):
        _, _, done, extras = env.step(actions)
        ended = int(done.sum())  # a host sync each step, so the GPU's queue is drained when timed
        episodes += ended
        collisions += ended - int(extras["time_outs"].sum())
    elapsed = time.perf_counter() - start
    env.sim.step = physics_step
    env.physics_share = env.sim.step_time_s / elapsed
    return steps * env.num_envs / elapsed, episodes, collisions


def measure_raw(env: MovingPlatformEnv, snapshots: list) -> float:
    """Raw backend steps on the env's own states: a new backend of the same kind and model, restarted
    from each recorded state (per-env parameters included); only the stepping itself is timed (the
    backend's `step_time_s`, which leaves out its fault screen)."""
    sim = make_backend(env.cfg.backend, env.sim.model, env.num_envs, env.cfg.sim, env.device)
    elapsed = 0.0
    for state in snapshots:
        sim.set_state(state)
        before = sim.step_time_s
        sim.step(env.cfg.sim.decimation)
        elapsed += sim.step_time_s - before
    return len(snapshots) * env.num_envs / elapsed


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--num-envs", type=int, default=1024)
    p.add_argument("--steps", type=int, default=1000, help="policy steps of the env (2 episodes at 500)")
    p.add_argument("--threads", type=int, default=0, help="Batch threads, 0 = all cores")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--backend", choices=("cpu", "warp"), default="cpu", help="physics backend (env.backend)")
    p.add_argument("--device", default="cpu", help="the warp backend's device: cuda[:N], or cpu (Warp's CPU device)")
    p.add_argument("--json", action="store_true", help="print one JSON object only")
    args = p.parse_args(argv)
    torch.set_num_threads(1)  # the env's tensor work is small; leave the cores to the physics threads
    env = MovingPlatformEnv(
        {"num_envs": args.num_envs, "seed": args.seed, "backend": args.backend, "sim": {"num_threads": args.threads}},
        device=args.device,
    )
    env.reset()
    measure_env(env, 5)  # warm-up
    snapshots: list = []
    env_sps, episodes, collisions = measure_env(env, args.steps, snapshots)
    raw = measure_raw(env, snapshots)
    result = {
        "num_envs": args.num_envs,
        "backend": args.backend,
        "device": str(env.device),
        "threads": env.sim.batch.nthread if args.backend == "cpu" else None,
        "env_steps_per_s": round(env_sps, 1),
        "raw_steps_per_s": round(raw, 1),
        "ratio": round(env_sps / raw, 3),
        # share of the env's wall time spent inside Batch.step itself (same states as the env)
        "env_physics_share": round(env.physics_share, 3),
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
