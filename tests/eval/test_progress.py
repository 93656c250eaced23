"""evaluate's ETA: a dash until enough stepping is measured, then the env steps left at the measured
rate, so that the early collisions do not extrapolate a short job to a long one."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import torch

from lasmp.eval.run import MIN_MEASURED_S, BenchmarkSource, eta_text, steps_left


def test_the_eta_is_a_dash_until_enough_stepping_is_measured_then_the_steps_left_at_the_measured_rate():
    assert eta_text(0, 1000.0, 10.0) == "\u2013"  # nothing stepped
    assert eta_text(500, 1000.0, MIN_MEASURED_S / 2) == "\u2013"  # the warm-up alone
    assert eta_text(500, 1000.0, 5.0) == "10 s"  # 100 steps/s, 1,000 left


def test_the_steps_left_count_each_playing_episode_to_its_time_out_and_each_unstarted_one_in_full():
    bench = SimpleNamespace(num_episodes=10)
    source = BenchmarkSource(bench, num_episodes=10, num_envs=2)
    source.next_episode, source.episode_of_env[:] = 4, [2, 3]  # episodes 2 and 3 playing, 6 unstarted
    env = SimpleNamespace(num_envs=2, max_episode_length=500, episode_length_buf=torch.tensor([100, 400]))
    steps = np.full(10, np.nan)
    steps[:2] = [50, 70]  # two short early collisions: fewer than a wave, so not yet the mean
    assert steps_left(env, source, steps, done_count=1) == 400 + 100 + 6 * 500
    # a wave has ended: the unstarted ones count at the mean length of those ended
    assert steps_left(env, source, steps, done_count=2) == 400 + 100 + 6 * 60
    source.episode_of_env[:] = [-1, 3]  # an env with nothing left to play counts nothing
    assert steps_left(env, source, steps, done_count=2) == 100 + 6 * 60
