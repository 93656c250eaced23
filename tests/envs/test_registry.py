"""The task registry (lasmp.envs.registry): one table that the Hydra options, the task check, the
env a run builds and cfg/task/*.yaml agree with; envs take their validated config dataclass only."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from hydra.core.config_store import ConfigStore

from lasmp.config.base import build_env_cfg
from lasmp.config.checks import ConfigError
from lasmp.config.train import TASKS, register_configs
from lasmp.envs import registry

ROOT = Path(__file__).resolve().parents[2]


def test_every_task_yaml_names_a_registered_task_and_every_task_has_one():
    named = {yaml.safe_load(p.read_text())["task"]: p.stem for p in (ROOT / "cfg" / "task").glob("*.yaml")}
    assert named == {task: task for task in registry.TASKS}
    assert TASKS == tuple(registry.TASKS)


def test_the_hydra_env_options_are_the_registrys_schemas():
    register_configs()
    repo = ConfigStore.instance().repo["env"]
    for task in registry.TASKS:
        node = repo[f"{task}.yaml"].node
        assert node._metadata.object_type is registry.env_schema(task) is registry.TASKS[task].cfg_class


def test_an_unknown_task_is_refused_naming_the_tasks():
    with pytest.raises(
        ConfigError, match=r"task must be one of \['moving_platform', 'rough_static'\], got 'walk'"
    ):
        registry.env_schema("walk")


@pytest.mark.parametrize("task", list(registry.TASKS))
@pytest.mark.parametrize("cfg", [None, {"num_envs": 1}])
def test_an_env_takes_its_validated_config_dataclass_only(task, cfg):
    env_class = registry.env_class(task)
    with pytest.raises(
        TypeError,
        match=rf"{env_class.__name__} takes a validated {env_class.cfg_class.__name__}.*"
        r"build_env_cfg",
    ):
        env_class(cfg)


def test_an_env_refuses_the_other_tasks_config():
    mp, rs = registry.env_class("moving_platform"), registry.env_class("rough_static")
    with pytest.raises(TypeError, match="takes a validated MovingPlatformCfg, got a RoughStaticCfg"):
        mp(build_env_cfg({"num_envs": 1}, schema=rs.cfg_class))


def test_make_env_builds_the_tasks_env_on_the_cpu_with_the_cpu_backend():
    cfg = build_env_cfg(
        {"num_envs": 1, "sim": {"num_threads": 1}}, schema=registry.env_schema("rough_static")
    )
    # the learner's device: the physics stays here
    env = registry.make_env("rough_static", cfg, device="cuda")
    assert type(env) is registry.TASKS["rough_static"] and env.cfg is cfg and env.device.type == "cpu"
