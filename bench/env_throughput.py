"""Throughput of the full moving-platform env vs raw `Batch.step` on the same model, one run.

The env runs the Stand Still controller (a = 0) with everything on: observations, rewards,
terminations, resets, domain randomization, trajectories. The raw baseline steps the same
compiled model, same env count and threads, same per-env parameters, same `nstep = decimation`
and post-step stage, from the very states the env's physics met (50 recorded during the env
run, each restored before one timed `Batch.step`), and does nothing else. Both are reported in policy steps per second (env steps x envs / s);
`ratio` = env / raw; `env_physics_share` is the
share of the env's own wall time spent inside `Batch.step` on its states. Also reports the Stand Still collision rate over the episodes it ended.

    python bench/env_throughput.py --num-envs 1024 --json
"""

from __future__ import annotations

import argparse
import json
import time

import mujoco
import mujoco.batch
import numpy as np
import torch

from lasmp.envs.moving_platform.env import MovingPlatformEnv


def measure_env(env: MovingPlatformEnv, steps: int, snapshots: list | None = None) -> tuple[float, int, int]:
    """Env policy steps/s with a = 0; optionally records the physics state before some steps."""
    actions = torch.zeros(env.num_envs, env.num_actions)
    episodes = collisions = 0
    env.sim.step_time_s = 0.0
    physics_step = env.sim.step
    if snapshots is not None:  # integration state (qpos, qvel, act, ctrl, warm start) as each step sees it
        every = max(1, steps // 50)

        def recording_step(nstep, ids=None):
            if len(snapshots) < 50 and env.episode_length_buf[0] % every == 0:
                snapshots.append(env.sim.batch.state.copy())
            return physics_step(nstep, ids)

        env.sim.step = recording_step
    start = time.perf_counter()
    for _ in range(steps):
        _, _, done, extras = env.step(actions)
        ended = int(done.sum())
        episodes += ended
        collisions += ended - int(extras["time_outs"].sum())
    elapsed = time.perf_counter() - start
    env.sim.step = physics_step
    env.physics_share = env.sim.step_time_s / elapsed
    return steps * env.num_envs / elapsed, episodes, collisions


def measure_raw(env: MovingPlatformEnv, snapshots: list) -> float:
    """Raw Batch.step on the env's own states: a new batch of the same model, with the same
    per-env parameters, restarted from each recorded state; only the step itself is timed."""
    batch = mujoco.batch.Batch(env.sim.model, env.num_envs, nthread=env.cfg.sim.num_threads, persistent=True)
    for name in ("body_mass", "body_ipos", "geom_friction", "actuator_gainprm", "actuator_biasprm"):
        batch.expand(name)[:] = env.sim.batch.expanded(name)
    batch.set_const()
    stage = int(mujoco.mjtStage.mjSTAGE_VEL)
    elapsed = 0.0
    for state in snapshots:
        batch.state[:] = state
        batch.forward(stage=stage)  # the stages the env's step starts from
        start = time.perf_counter()
        batch.step(nstep=env.cfg.sim.decimation, stage=stage)
        elapsed += time.perf_counter() - start
    return len(snapshots) * env.num_envs / elapsed


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--num-envs", type=int, default=1024)
    p.add_argument("--steps", type=int, default=1000, help="policy steps of the env (2 episodes at 500)")
    p.add_argument("--threads", type=int, default=0, help="Batch threads, 0 = all cores")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", action="store_true", help="print one JSON object only")
    args = p.parse_args(argv)
    torch.set_num_threads(1)  # the env's tensor work is small; leave the cores to the physics threads
    env = MovingPlatformEnv(
        {"num_envs": args.num_envs, "seed": args.seed, "sim": {"num_threads": args.threads}}
    )
    env.reset()
    measure_env(env, 5)  # warm-up
    snapshots: list = []
    env_sps, episodes, collisions = measure_env(env, args.steps, snapshots)
    raw = measure_raw(env, snapshots)
    result = {
        "num_envs": args.num_envs,
        "threads": env.sim.batch.nthread,
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
