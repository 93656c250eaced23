"""Every private or undocumented rsl_rl name lasmp uses is still in the installed rsl_rl: an upgrade
that drops or renames one fails here, naming it, instead of deep in a training run
(lasmp/compat/rsl_rl.py says what each is for)."""

from __future__ import annotations

import inspect

import pytest
import torch
from rsl_rl.models import MLPModel
from rsl_rl.modules import EmpiricalNormalization
from rsl_rl.runners import OnPolicyRunner
from rsl_rl.utils.logger import Logger
from tensordict import TensorDict
from testkit import tensorboard_logger

from lasmp.compat.rsl_rl import (
    NORMALIZER_STD_KEY,
    NORMALIZER_VAR_KEY,
    LoggerCompat,
    MLPModelCompat,
    OnPolicyRunnerCompat,
    raised_storing_code_state,
)

# lasmp/compat/rsl_rl.py: the Logger's buffers it reads and restores
LOGGER_BUFFERS = ("rewbuffer", "lenbuffer", "cur_reward_sum", "cur_episode_length", "ep_extras")
# read by lasmp/algo/console.py and runner.py, as rsl_rl's runner and logger read them
LOGGER_ATTRIBUTES = ("log_dir", "writer", "cfg", "num_envs", "gpu_world_size")


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


def test_the_model_still_sizes_its_input_from_its_two_hooks():
    init = inspect.getsource(MLPModel.__init__)
    assert init.index("self._get_obs_dim(") < init.index("self._get_latent_dim()")
    obs = TensorDict({"a": torch.zeros(2, 3), "b": torch.zeros(2, 4)}, batch_size=[2])
    plain = MLPModelCompat(obs, {"actor": ["a", "b"]}, "actor", 5, [8])
    assert (plain.obs_groups, plain.obs_dim, plain.mlp[0].in_features) == (["a", "b"], 7, 7)

    class OneGroupWider(MLPModelCompat):
        def select_obs(self, obs, obs_groups, obs_set):
            return ["a"], obs["a"].shape[-1]

        def backbone_input_size(self):
            return self.obs_dim + 10

    model = OneGroupWider(obs, {"actor": ["a", "b"]}, "actor", 5, [8], obs_normalization=True)
    assert (model.obs_groups, model.obs_dim, model.mlp[0].in_features) == (["a"], 3, 13)
    assert model.obs_normalizer.mean.shape == (3,)


def test_the_normalizer_s_public_statistics_are_those_it_normalizes_with():
    """lasmp/modules/policy.py normalizes the history with them, export.py writes them in the metadata."""
    norm = EmpiricalNormalization(4)
    data = torch.arange(24.0).reshape(6, 4) ** 1.5
    norm.update(data)
    torch.testing.assert_close(norm.mean, data.mean(0))
    torch.testing.assert_close(norm.std, data.std(0, unbiased=False))
    assert torch.equal(norm(data), (data - norm.mean[None]) / (norm.std[None] + norm.eps))
    assert {NORMALIZER_VAR_KEY, NORMALIZER_STD_KEY} <= set(norm.state_dict())
    torch.testing.assert_close(norm.state_dict()[NORMALIZER_VAR_KEY][0], data.var(0, unbiased=False))


def test_a_failed_write_of_the_code_state_is_told_from_its_traceback(tmp_path):
    assert callable(getattr(Logger, "_store_code_state", None))
    assert "self._store_code_state()" in inspect.getsource(Logger.init_logging_writer)
    (tmp_path / "git").write_text("a file where the logger makes its git/ folder")
    logger = tensorboard_logger(tmp_path)
    with pytest.raises(OSError) as raised:
        logger.init_logging_writer()
    logger.writer.close()
    assert raised_storing_code_state(raised.value)
    try:
        raise OSError("elsewhere")
    except OSError as err:
        assert not raised_storing_code_state(err)
