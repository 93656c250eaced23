"""Every private or undocumented rsl_rl name lasmp uses is still in the installed rsl_rl: an upgrade
that drops or renames one fails here, naming it, instead of deep in a training run
(lasmp/algo/rsl_compat.py says what each is for)."""

from __future__ import annotations

import inspect

import pytest
import torch
from rsl_rl.modules import EmpiricalNormalization
from rsl_rl.runners import OnPolicyRunner

from lasmp.algo.rsl_compat import LoggerCompat, OnPolicyRunnerCompat

# lasmp/algo/rsl_compat.py: the Logger's buffers it reads and restores
LOGGER_BUFFERS = ("rewbuffer", "lenbuffer", "cur_reward_sum", "cur_episode_length", "ep_extras")
# read by lasmp/algo/console.py and runner.py, as rsl_rl's runner and logger read them
LOGGER_ATTRIBUTES = ("log_dir", "writer", "cfg", "num_envs", "gpu_world_size")
# read by lasmp/modules/policy.py and lasmp/modules/export.py (the observation normalizer's statistics)
NORMALIZER_BUFFERS = ("_mean", "_std")


def test_the_runner_still_calls_its_multi_gpu_hook_before_it_builds_the_learner():
    init = inspect.getsource(OnPolicyRunner.__init__)
    assert callable(getattr(OnPolicyRunner, "_configure_multi_gpu", None))
    assert "self._configure_multi_gpu()" in init
    assert init.index("self._configure_multi_gpu()") < init.index("construct_algorithm")
    assert OnPolicyRunnerCompat._configure_multi_gpu is not OnPolicyRunner._configure_multi_gpu


def logger_of(num_envs: int) -> LoggerCompat:
    return LoggerCompat(
        log_dir=None,
        cfg={"algorithm": {}},
        env_cfg={},
        num_envs=num_envs,
        is_distributed=False,
        gpu_world_size=1,
        gpu_global_rank=0,
        device="cpu",
    )


@pytest.mark.parametrize("name", LOGGER_BUFFERS + LOGGER_ATTRIBUTES)
def test_the_logger_still_keeps(name):
    assert hasattr(logger_of(num_envs=3), name), f"rsl_rl's Logger no longer has {name}"


def test_the_logger_s_episode_statistics_go_round_a_checkpoint():
    logger = logger_of(num_envs=2)
    logger.writer = object()  # rsl_rl gathers statistics only with a writer
    rewards, extras = torch.tensor([1.0, 2.0]), {"episode": {"x": 1.0}}
    logger.process_env_step(rewards, torch.tensor([0, 1]), extras)
    logger.process_env_step(rewards, torch.tensor([0, 0]), extras)
    assert logger.take_episode_extras() == [{"x": 1.0}] * 2 and logger.take_episode_extras() == []
    restored = logger_of(num_envs=2)
    restored.load_episode_log_state(logger.episode_log_state())
    assert [list(b) for b in restored.finished_episodes()] == [[2.0], [1.0]]
    state = restored.episode_log_state()
    assert state["reward_sum"].tolist() == [2.0, 2.0] and state["length"].tolist() == [2.0, 1.0]


@pytest.mark.parametrize("name", NORMALIZER_BUFFERS)
def test_the_normalizer_still_keeps(name):
    assert hasattr(EmpiricalNormalization(4), name), f"rsl_rl's EmpiricalNormalization no longer has {name}"
