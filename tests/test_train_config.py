"""The training configuration: Hydra's composition of every policy group, preset and override and
of the rough-static task into the R-S policy, and the validation that names a bad field."""

from __future__ import annotations

import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf
from testkit import ROOT

from lasmp.algo.checkpoint import read_checkpoint
from lasmp.cli.build import make_runner
from lasmp.cli.train import train
from lasmp.config.checks import ConfigError
from lasmp.config.train import register_configs, to_train_cfg

register_configs()


@pytest.mark.parametrize(
    "group, input_dim",
    [
        ("lasmp", 76),
        ("no_alignment_command", 73),
        ("no_platform_velocity_estimates", 67),
        ("no_explicit_estimator", 60),
        ("no_explicit_estimator_history", 60 + 20 * 44),
    ],
)
def test_every_policy_group_composes_with_its_actor_input_size(tmp_path, group, input_dim):
    with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
        cfg = compose("config", overrides=[f"policy={group}", "env.num_envs=2", "torch_threads=1"])
    runner = make_runner(to_train_cfg(cfg), None)
    assert runner.alg.get_policy().backbone_input_dim == input_dim
    assert cfg.policy.name == group


def test_presets_and_overrides_compose():
    with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
        cpu = compose("config")
        paper = compose("config", overrides=["preset=paper"])
        custom = compose(
            "config",
            overrides=["env.num_envs=8", "runner.max_iterations=3", "seed=5", "runner.log_dir=/tmp/x"],
        )
    assert (cpu.env.num_envs, cpu.runner.max_iterations, cpu.device) == (1024, 1000, "cpu")
    assert (paper.env.num_envs, paper.runner.max_iterations, paper.device) == (8192, 4000, "cuda")
    assert (custom.env.num_envs, custom.runner.max_iterations, custom.seed) == (8, 3, 5)
    assert to_train_cfg(custom).env.seed == 5


def test_invalid_training_config_names_the_field():
    with pytest.raises(ConfigError, match="algo.roa_lambda"):
        to_train_cfg(OmegaConf.create({"algo": {"roa_lambda": -1.0}}))
    with pytest.raises(ConfigError, match="algo.entropy_decay_iterations"):
        to_train_cfg(OmegaConf.create({"algo": {"entropy_decay_iterations": -1}}))
    with pytest.raises(ConfigError, match="policy.use_alignment"):
        to_train_cfg(OmegaConf.create({"policy": {"explicit": "none"}}))
    # NaN passes a comparison (`nan <= 0` is false): every number of the config must be finite
    with pytest.raises(ConfigError, match=r"algo.learning_rate must be a finite number, got nan"):
        to_train_cfg(OmegaConf.create({"algo": {"learning_rate": float("nan")}}))
    with pytest.raises(ConfigError, match=r"env.rewards.weights.reg4_air_time must be a finite number"):
        to_train_cfg(OmegaConf.create({"env": {"rewards": {"weights": {"reg4_air_time": float("-inf")}}}}))
    with pytest.raises(ConfigError, match=r"env.init_state.yaw_range_rad\[1\] must be a finite number"):
        to_train_cfg(OmegaConf.create({"env": {"init_state": {"yaw_range_rad": [0.0, float("nan")]}}}))
    with pytest.raises(Exception, match="num_env"):  # a typo: OmegaConf names the unknown key
        to_train_cfg(OmegaConf.create({"env": {"num_env": 8}}))


def test_rough_static_task_trains_the_rs_policy(tmp_path):
    with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
        cfg = compose(
            "config",
            overrides=[
                "task=rough_static",
                "env.num_envs=4",
                "runner.max_iterations=1",
                f"runner.log_dir={tmp_path}",
                "torch_threads=1",
                "policy.actor_hidden_dims=[32,32,32]",
            ],
        )
    assert cfg.policy.name == "rs"  # the task picks its policy
    runner = train(cfg)
    actor = runner.alg.get_policy()
    assert actor.command_input and actor.num_explicit == 7 and not actor.use_alignment
    assert actor.backbone_input_dim == 44 + 7 + 3 + 16
    data = read_checkpoint(tmp_path)
    assert data["config"]["task"] == "rough_static" and "command" in data["obs_layout"]
