"""Run a controller over the benchmark's episodes, in batches of envs, and collect metrics.

Each env plays benchmark episodes one after another: when its episode ends (collision, fall or
time-out), it resets into the next unplayed episode k (trajectory k, robot k mod R, its own
initial heading) until all K episodes are done; envs left without an episode keep running but are no longer counted. The
pairing of trajectories and robots is therefore the same for every controller.

Besides the metrics, each episode's end is recorded: when it collided (s after its start) and
what ended it (`collision_cause`): the robot bodies that touched something (trunk, <leg>_hip,
<leg>_thigh, <leg>_calf, joined by '+'), then `off_footprint` / `below_top` for a fall, or `fault`
for a simulation the env found diverged.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable

import numpy as np
import torch

from lasmp.envs.moving_platform.domain_rand import Intrinsics
from lasmp.envs.robot import as_numpy, take_columns
from lasmp.eval.failure import FAILURE_KEYS, failure_state
from lasmp.eval.gait import GAIT_KEYS, GaitTracker
from lasmp.eval.metrics import EpisodeMetrics, TrunkPose, metric_h_des_p_m
from lasmp.robots import a1

Controller = Callable[[object], torch.Tensor]  # observations (TensorDict) -> actions (n, 12)


def intrinsics_rows(p: Intrinsics, rows: np.ndarray) -> Intrinsics:
    return Intrinsics(**{name: value[rows] for name, value in vars(p).items()})


class BenchmarkSource:
    """The env's episode source: benchmark episodes in order.

    `bench` is anything with `trajectories`, `robots`, `num_episodes` and `pairing(episodes)` ->
    (trajectory rows, robot rows): Xi_eval (:class:`lasmp.eval.benchmark.Benchmark`) or the
    real-motion suite (:class:`lasmp.eval.real_motion.suite.SuiteEpisodes`)."""

    def __init__(self, bench, num_episodes: int, num_envs: int):
        if not 1 <= num_episodes <= bench.num_episodes:
            raise ValueError(f"num_episodes must be in [1, {bench.num_episodes}], got {num_episodes}")
        self.bench = bench
        self.num_episodes = num_episodes
        self.next_episode = 0
        self.episode_of_env = np.full(num_envs, -1)

    def next_episodes(self, ids: np.ndarray):
        k = self.next_episode + np.arange(len(ids))
        self.next_episode += len(ids)
        valid = k < self.num_episodes
        self.episode_of_env[ids] = np.where(valid, k, -1)
        # fillers replay the last
        traj_rows, robot_rows = self.bench.pairing(np.minimum(k, self.num_episodes - 1))
        traj = self.bench.trajectories.subset(traj_rows)
        pose = self.bench.initial_pose_draws(np.minimum(k, self.num_episodes - 1))
        return traj, traj.n_waypoints, intrinsics_rows(self.bench.robots, robot_rows), pose


FALL_CAUSES = ("off_footprint", "below_top")
FAULT_CAUSE = "fault"
EPISODE_KEYS = (
    "collision",
    "steps",
    "height_violation_rate",
    "position_deviation_m",
    "position_deviation_translating_m",
    "rotation_deviation_rad",
    "rotation_deviation_platform_rad",
    "power_w",
    "collision_time_s",
    *GAIT_KEYS,
    *FAILURE_KEYS,
)


def fall_kinds(env, p_body_p: np.ndarray) -> np.ndarray:
    """(n, 2) bool [off the footprint, below the top] of trunk positions in P (host arrays).

    The env's own fall test (`MovingPlatformEnv._fell`) returns only their union; this repeats its
    two comparisons, read-only, to name the cause."""
    tc = env.cfg.termination
    half_xy = env.plf_half_xy_m.cpu().numpy()
    off = (np.abs(p_body_p[:, :2]) > half_xy + tc.footprint_margin_m).any(axis=1)
    below = p_body_p[:, 2] < env.plf_top_m + tc.fall_below_top_m
    return np.stack([off, below], axis=1)


def cause_names(contact: np.ndarray, fell: np.ndarray) -> np.ndarray:
    """(n,) str: the bodies of a1.NON_FOOT_COLLISION_GEOMS in contact (n, 13), then the fall kinds
    (n, 2), joined by '+'; `fault` where none (the env ended the episode on a diverged simulation)."""
    names = np.array([*a1.NON_FOOT_COLLISION_GEOMS, *FALL_CAUSES])
    flags = np.concatenate([contact, fell], axis=1)
    return np.array(["+".join(names[row]) or FAULT_CAUSE for row in flags], dtype=object)


def run_benchmark(
    env,
    controller: Controller,
    bench,
    num_episodes: int,
    policy=None,
    trace: bool = False,
    progress: bool = True,
    shrink_tail: bool = True,
) -> dict:
    """Play `num_episodes` benchmark episodes; per-episode metrics and ends (arrays in benchmark
    order, `EPISODE_KEYS` and `collision_cause`), estimator errors (if `policy` is given) and, with
    `trace`, the estimated and true x_exp over the longest episode of the first wave (episodes
    0..num_envs-1, one per env).

    The height band is centred 0.37 m above the platform's top (`metric_h_des_p_m`), not at the
    height the policy was rewarded for (`env.h_des_p_m`): one band for every method.

    `shrink_tail`: once every episode has started, only the envs still playing one are simulated
    (`env.stepped_envs`); the idle ones stop costing physics. Each episode's numbers are the same
    either way (the simulations are independent)."""
    source = BenchmarkSource(bench, num_episodes, env.num_envs)
    env.episode_source = source
    metrics = EpisodeMetrics(env.num_envs, metric_h_des_p_m(env.plf_top_m))
    captured: dict = {}

    def capture(readout, collision):
        r = as_numpy(readout)  # the metrics run on the host
        contact = take_columns(env.sim.sensordata, env.index.collision_cols).cpu().numpy() > 0
        captured.update(
            pose=TrunkPose.from_readout(r),
            tau=r.tau,
            q_dot=r.q_dot,
            collision=collision.cpu().numpy(),
            contact=contact,
            feet=r.foot_contact,
            fell=fall_kinds(env, r.p_body_p),
        )

    env.on_step = capture
    obs, _ = env.reset()
    metrics.start(np.arange(env.num_envs), TrunkPose.from_readout(as_numpy(env.readout)))
    gait = GaitTracker(env.num_envs, env.dt_s)
    episodes = {key: np.full(num_episodes, np.nan) for key in EPISODE_KEYS}
    episodes["collision_cause"] = np.full(num_episodes, "", dtype=object)
    est = {"abs_sum": None, "l2_sum": 0.0, "count": 0}
    first_wave: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # (episode per env, true, estimate)
    done_count, start, last_print, stepped = 0, time.perf_counter(), 0.0, 0
    try:  # the progress line ends however the loop does (Ctrl-C's one line then starts afresh)
        with torch.inference_mode():
            while done_count < num_episodes:
                ep_before = source.episode_of_env.copy()
                active = ep_before >= 0
                if shrink_tail and source.next_episode >= num_episodes:
                    env.stepped_envs = torch.as_tensor(np.flatnonzero(active), device=env.device)
                if policy is not None:
                    x_true, x_hat = _accumulate_estimates(policy, obs, active, est)
                    if trace and ((ep_before >= 0) & (ep_before < env.num_envs)).any():
                        first_wave.append((ep_before, x_true.numpy().copy(), x_hat.numpy().copy()))
                obs, _, done, extras = env.step(controller(obs))
                metrics.step(
                    active, captured["collision"], captured["pose"], captured["tau"], captured["q_dot"]
                )
                gait.step(active, captured["feet"])
                done = done.cpu().numpy()
                ids = np.flatnonzero(done & active)
                if len(ids):
                    collided = ~extras["time_outs"].cpu().numpy()[ids]
                    rows = ep_before[ids]
                    closed = {**metrics.close(ids, collided), **gait.close(ids)}
                    for key, value in closed.items():
                        episodes[key][rows] = value
                    # the collision step is the first one not counted: it ends at (steps + 1) dt
                    episodes["collision_time_s"][rows] = np.where(
                        collided, (closed["steps"] + 1) * env.dt_s, np.nan
                    )
                    causes = cause_names(captured["contact"][ids], captured["fell"][ids])
                    episodes["collision_cause"][rows] = np.where(collided, causes, "")
                    pose = captured["pose"]
                    at_failure = failure_state(
                        np.asarray(captured["feet"])[ids] > 0, pose.r_wp[ids], pose.r_wb[ids], collided
                    )
                    for key, value in at_failure.items():
                        episodes[key][rows] = value
                    done_count += len(ids)
                restarted = np.flatnonzero(done)
                if len(restarted):
                    metrics.start(restarted, TrunkPose.from_readout(as_numpy(env.readout)).rows(restarted))
                    gait.start(restarted)
                stepped += int(active.sum())
                now = time.perf_counter()
                if progress and (now - last_print > 2.0 or done_count == num_episodes):
                    last_print = now
                    rate = done_count / max(now - start, 1e-9)
                    left = steps_left(env, source, episodes["steps"], done_count)
                    print(
                        f"\r{done_count}/{num_episodes} episodes | {rate:.1f} episodes/s | "
                        f"ETA {eta_text(stepped, left, now - start)}",
                        end="",
                        file=sys.stderr,
                        flush=True,
                    )
    finally:
        if progress:
            print(file=sys.stderr)
    env.on_step = None
    env.episode_source = None
    env.stepped_envs = None
    out = {"episodes": episodes, "wall_time_s": time.perf_counter() - start}
    if est["count"]:
        names = policy.estimation_names
        out["estimator"] = {
            "x_exp_mean_abs_error": {
                n: float(v) for n, v in zip(names, est["abs_sum"] / est["count"], strict=True)
            },
            "l_imp_mean_l2_error": est["l2_sum"] / est["count"],
            "samples": est["count"],
        }
        if first_wave:
            wave = min(env.num_envs, num_episodes)
            longest = int(np.nanargmax(episodes["steps"][:wave]))  # played by env `longest`
            rows = [(t, e) for eps, t, e in first_wave if eps[longest] == longest]
            out["trace"] = {
                "episode": longest,
                "true": np.array([t[longest] for t, _ in rows]),
                "estimate": np.array([e[longest] for _, e in rows]),
            }
    return out


MIN_MEASURED_S = 2.0  # the ETA needs this much stepping measured: the first steps warm up


def steps_left(env, source: BenchmarkSource, steps: np.ndarray, done_count: int) -> float:
    """The env steps the evaluation has left, estimated: each playing episode at most its steps to the
    time-out, each unstarted one a full episode until a wave of them has ended (the first to end are
    the short ones, the collisions), then their mean length."""
    elapsed = env.episode_length_buf.cpu().numpy()[source.episode_of_env >= 0]
    playing = float(np.maximum(env.max_episode_length - elapsed, 0).sum())
    unstarted = max(source.num_episodes - source.next_episode, 0)
    mean = np.nanmean(steps) if done_count >= env.num_envs else env.max_episode_length
    return playing + unstarted * float(mean)


def eta_text(stepped: int, left: float, elapsed_s: float) -> str:
    """The time left at the measured rate of env steps ("12 s"); "\u2013" until MIN_MEASURED_S of
    stepping is measured. Why steps, not episodes: a rate of finished episodes counts the early
    collisions first, and at the first seconds extrapolated a 33 s evaluation to 2,016 s."""
    if elapsed_s < MIN_MEASURED_S or stepped == 0:
        return "\u2013"
    return f"{left / (stepped / elapsed_s):.0f} s"


def _accumulate_estimates(policy, obs, active, est) -> tuple[torch.Tensor, torch.Tensor]:
    """Add this step's estimation errors of the active envs; return (true, estimated) x_exp."""
    x_hat, l_hat = policy.estimates(obs)
    k = x_hat.shape[1]
    x_true = obs["priv_explicit"][:, :k]
    l_true = policy.encoder(obs["priv_implicit"])
    mask = torch.from_numpy(active)
    abs_err = (x_hat - x_true).abs()[mask].sum(0).numpy()
    est["abs_sum"] = abs_err if est["abs_sum"] is None else est["abs_sum"] + abs_err
    est["l2_sum"] += float((l_hat - l_true).norm(dim=-1)[mask].sum())
    est["count"] += int(active.sum())
    return x_true, x_hat
