"""Run a controller over the benchmark's episodes, in batches of envs, and collect metrics.

Each env plays benchmark episodes one after another: when its episode ends (collision, fall or
time-out), it resets into the next unplayed episode k (trajectory k, robot k mod R) until all K
episodes are done; envs left without an episode keep running but are no longer counted. The
pairing of trajectories and robots is therefore the same for every controller.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable

import numpy as np
import torch

from lasmp.envs.moving_platform.domain_rand import Intrinsics
from lasmp.envs.robot import as_numpy
from lasmp.eval.metrics import POSITION_FRAME, POSITION_FRAMES, EpisodeMetrics

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
        traj_rows, robot_rows = self.bench.pairing(
            np.minimum(k, self.num_episodes - 1)
        )  # fillers replay the last
        traj = self.bench.trajectories.subset(traj_rows)
        return traj, traj.n_waypoints, intrinsics_rows(self.bench.robots, robot_rows)


def relative_pose(readout, frame: str = POSITION_FRAME) -> tuple[np.ndarray, np.ndarray]:
    """(trunk position relative to the platform in `frame` (n, 3), R_pb (n, 3, 3)) of a readout."""
    if frame not in POSITION_FRAMES:
        raise ValueError(f"unknown position frame {frame!r}; valid: {list(POSITION_FRAMES)}")
    p = readout.p_body_p if frame == "platform" else readout.p_body_w - readout.p_plf_w
    return p, np.einsum("nji,njk->nik", readout.r_wp, readout.r_wb)


def run_benchmark(env, controller: Controller, bench, num_episodes: int, policy=None, trace: bool = False,
                  progress: bool = True, shrink_tail: bool = True) -> dict:  # fmt: skip
    """Play `num_episodes` benchmark episodes; per-episode metrics (arrays in benchmark order),
    estimator errors (if `policy` is given) and, with `trace`, the estimated and true x_exp over the
    longest episode of the first wave (episodes 0..num_envs-1, one per env).

    `shrink_tail`: once every episode has started, only the envs still playing one are simulated
    (`env.stepped_envs`); the idle ones stop costing physics. Each episode's numbers are the same
    either way (the simulations are independent)."""
    source = BenchmarkSource(bench, num_episodes, env.num_envs)
    env.episode_source = source
    metrics = EpisodeMetrics(env.num_envs, env.h_des_p_m)
    captured: dict = {}

    def capture(readout, collision):
        readout = as_numpy(readout)  # the metrics run on the host
        p_rel, r_pb = relative_pose(readout)
        captured.update(p=readout.p_body_p, p_rel=p_rel, r=r_pb, tau=readout.tau, q_dot=readout.q_dot,
                        collision=collision.cpu().numpy())  # fmt: skip

    env.on_step = capture
    obs, _ = env.reset()
    metrics.start(np.arange(env.num_envs), *relative_pose(as_numpy(env.readout)))
    episodes = {key: np.full(num_episodes, np.nan) for key in ("collision", "steps", "height_violation_rate",
                                                               "position_deviation_m", "rotation_deviation_rad",
                                                               "power_w")}  # fmt: skip
    est = {"abs_sum": None, "l2_sum": 0.0, "count": 0}
    first_wave: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # (episode per env, true, estimate)
    done_count, start, last_print = 0, time.perf_counter(), 0.0
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
            metrics.step(active, captured["collision"], captured["p"], captured["r"], captured["tau"],
                         captured["q_dot"], captured["p_rel"])  # fmt: skip
            done = done.cpu().numpy()
            ids = np.flatnonzero(done & active)
            if len(ids):
                collided = ~extras["time_outs"].cpu().numpy()[ids]
                for key, value in metrics.close(ids, collided).items():
                    episodes[key][ep_before[ids]] = value
                done_count += len(ids)
            restarted = np.flatnonzero(done)
            if len(restarted):
                p, r = relative_pose(as_numpy(env.readout))
                metrics.start(restarted, p[restarted], r[restarted])
            now = time.perf_counter()
            if progress and (now - last_print > 2.0 or done_count == num_episodes):
                last_print = now
                rate = done_count / max(now - start, 1e-9)
                eta = (num_episodes - done_count) / rate if rate > 0 else float("nan")
                print(f"\r{done_count}/{num_episodes} episodes | {rate:.1f} episodes/s | ETA {eta:5.0f} s",
                      end="", file=sys.stderr, flush=True)  # fmt: skip
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
