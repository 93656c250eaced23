"""The benchmark loop's bookkeeping: episodes paired with envs in order, each episode's own initial
pose draws and heading whichever env plays it, and the shrinking tail that steps only the playing
envs."""

from __future__ import annotations

import numpy as np
import pytest

from lasmp.eval import benchmark as bm
from lasmp.eval.run import BenchmarkSource


def test_benchmark_source_pairs_episodes_in_order_and_marks_the_rest_inactive():
    bench = bm.generate(num_trajectories=5, num_robots=2, seed=0)
    src = BenchmarkSource(bench, num_episodes=5, num_envs=3)
    traj, levels, robots, pose = src.next_episodes(np.array([0, 1, 2]))
    assert src.episode_of_env.tolist() == [0, 1, 2]
    assert np.array_equal(robots.trunk_mass_kg, bench.robots.trunk_mass_kg[[0, 1, 0]])
    assert np.array_equal(levels, bench.trajectories.n_waypoints[:3])
    src.next_episodes(np.array([1, 2]))
    src.next_episodes(np.array([0]))
    assert src.episode_of_env.tolist() == [-1, 3, 4]  # episode 5 does not exist: env 0 is a filler
    with pytest.raises(ValueError, match="num_episodes"):
        BenchmarkSource(bench, num_episodes=6, num_envs=1)
    np.testing.assert_array_equal(pose, bench.initial_pose_draws([0, 1, 2]))


def test_each_benchmark_episode_has_its_own_initial_pose_draws_whatever_the_set_size():
    bench = bm.generate(num_trajectories=6, num_robots=2, seed=0)
    draws = bench.initial_pose_draws(np.arange(6))
    assert draws.shape == (6, 3) and np.all((draws >= 0) & (draws < 1))
    assert len(np.unique(draws[:, 0])) == 6  # not one draw shared by the robots' rows
    np.testing.assert_array_equal(bench.subset(3).initial_pose_draws([2, 0]), draws[[2, 0]])
    other_seed = bm.generate(num_trajectories=6, num_robots=2, seed=1)
    assert not np.array_equal(other_seed.initial_pose_draws([0]), draws[:1])


def test_an_episode_starts_at_the_same_heading_whichever_env_plays_it_and_whatever_played_before():
    """play.py --benchmark-episode k must show the robot as the evaluation met it: episode 3 played
    by env 0 after a fresh start and by env 1 after episodes 0..2 starts at one heading."""
    from lasmp.config.base import build_env_cfg
    from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
    from lasmp.envs.moving_platform.env import MovingPlatformEnv

    bench = bm.generate(num_trajectories=6, num_robots=2, seed=0)
    yaw = {}
    for first, num_envs in ((0, 4), (3, 2)):
        env = MovingPlatformEnv(build_env_cfg({"num_envs": num_envs}, schema=MovingPlatformCfg))
        env.reset()  # a training reset first: it consumes the env's own random stream
        source = BenchmarkSource(bench, 6, num_envs)
        source.next_episode = first
        env.episode_source = source
        env.reset()
        for k, y in zip(source.episode_of_env, env.readout.phi_body_w[:, 2].tolist(), strict=True):
            yaw.setdefault(int(k), []).append(y)
    assert yaw[3][0] == pytest.approx(yaw[3][1], abs=1e-6)  # env 3 of 4, then env 0 of 2
    lo, hi = MovingPlatformCfg().init_state.yaw_range_rad
    expected = lo + (hi - lo) * bench.initial_pose_draws([0, 1, 2, 3, 4])[:, 0]
    got = [yaw[k][0] for k in range(5)]
    np.testing.assert_allclose(np.angle(np.exp(1j * (np.array(got) - expected))), 0.0, atol=1e-6)


def test_shrinking_the_tail_steps_only_playing_envs_and_changes_no_episode():
    import torch

    from lasmp.config.base import build_env_cfg
    from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
    from lasmp.envs.moving_platform.env import MovingPlatformEnv
    from lasmp.eval.build import eval_env_overrides
    from lasmp.eval.run import run_benchmark

    bench = bm.generate(num_trajectories=10, num_robots=4, seed=0)
    results, stepped = {}, {}
    for shrink in (False, True):
        overrides = {**eval_env_overrides(4, 0), "trajectory": {"split": "test", "duration_s": 2.0}}
        env = MovingPlatformEnv(build_env_cfg(overrides, schema=MovingPlatformCfg))
        zeros = torch.zeros(4, 12)
        results[shrink] = run_benchmark(
            env, lambda obs, zeros=zeros: zeros, bench, 10, progress=False, shrink_tail=shrink
        )
        stepped[shrink] = env.sim.env_steps
        assert env.stepped_envs is None  # the hook is cleared after the run
    for key, value in results[False]["episodes"].items():
        np.testing.assert_array_equal(results[True]["episodes"][key], value, err_msg=key)
    # 10 episodes on 4 envs: the third wave has 2 episodes, so the tail steps fewer envs
    assert stepped[True] < stepped[False]
