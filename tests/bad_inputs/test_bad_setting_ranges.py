"""Every numeric setting is checked for meaning: each has a range that a physical or computational
reason sets (`lasmp.config.checks.Bound`), and a value outside it is refused at start-up with a ConfigError
that names the key (train.py prints it as one line, `error: ...`, exit 2).

The walk covers the class, not a list of examples: it visits every numeric leaf of the composed default
config of each task (nested dataclasses, each number of a list, each entry of a dict) and gives it
absurd values, validating in this process. A few cases then go through the training's entry point."""

from __future__ import annotations

import copy
import dataclasses
import math
import re
from dataclasses import fields, is_dataclass
from functools import cache

import pytest
from badkit import ROOT, refused, tiny, train, train_py
from hydra import compose, initialize_config_dir

from lasmp.config.base import MIN_HISTORY_LENGTH
from lasmp.config.checks import ConfigError
from lasmp.config.train import TASKS, TrainCfg, to_train_cfg, validate_train_cfg
from lasmp.envs import registry
from lasmp.modules.estimator import HistoryEstimator

# Keys where any value is meaningful, with the reason. None today: every number here is a size, a time,
# a scale, a weight, a rate or a seed, and each has a bound past which it means nothing.
EXEMPT: dict[str, str] = {}
INT_VALUES = (-(10**12), 10**12)
FLOAT_VALUES = (-1e12, 1e12, math.nan)


@cache
def composed(task: str) -> TrainCfg:
    """The default training config of `task`, as train.py composes it."""
    with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
        return to_train_cfg(compose("config", overrides=[f"task={task}"]))


def numeric_leaves(node, path: tuple = ()):
    """(path, value) of every number under `node`; a path is a tuple of attribute names and list or
    dict keys. Booleans are not numbers here."""
    if is_dataclass(node):
        for f in fields(node):
            yield from numeric_leaves(getattr(node, f.name), (*path, f.name))
    elif isinstance(node, dict):
        for k, v in node.items():
            yield from numeric_leaves(v, (*path, k))
    elif isinstance(node, (list, tuple)):
        for i, v in enumerate(node):
            yield from numeric_leaves(v, (*path, i))
    elif isinstance(node, (int, float)) and not isinstance(node, bool):
        yield path, node


def key_of(path: tuple) -> str:
    """The dotted key a message names: list indices dropped (`env.platform.size_m`), dict keys kept."""
    return ".".join(str(p) for p in path if not isinstance(p, int))


def with_value(cfg: TrainCfg, path: tuple, value) -> TrainCfg:
    out = copy.deepcopy(cfg)
    node = out
    for step in path[:-1]:
        node = node[step] if isinstance(node, (dict, list)) else getattr(node, step)
    if isinstance(node, (dict, list)):
        node[path[-1]] = value
    else:
        setattr(node, path[-1], value)
    return out


CASES = [
    (task, path, value)
    for task in TASKS
    for path, default in numeric_leaves(composed(task))
    if key_of(path) not in EXEMPT
    for value in (INT_VALUES if isinstance(default, int) else FLOAT_VALUES)
]


def test_the_walk_visits_every_part_of_each_tasks_config():
    """A walk that misses a part would pass for the wrong reason."""
    for task in TASKS:
        keys = {key_of(path) for path, _ in numeric_leaves(composed(task))}
        assert len(keys) > 80, sorted(keys)
        for key in (
            "seed",
            "torch_threads",
            "env.num_envs",
            "env.sim.decimation",
            "policy.actor_hidden_dims",
        ):
            assert key in keys
        assert {"algo.learning_rate", "runner.num_steps_per_env", "env.domain_rand.test.joint_kp"} <= keys
        assert any(k.startswith("env.rewards.weights.") for k in keys)
    assert "env.trajectory.degree" in {key_of(p) for p, _ in numeric_leaves(composed("moving_platform"))}
    assert "env.terrain.resolution_m" in {key_of(p) for p, _ in numeric_leaves(composed("rough_static"))}


@pytest.mark.parametrize(
    ("task", "path", "value"), CASES, ids=[f"{t}:{'.'.join(map(str, p))}={v}" for t, p, v in CASES]
)
def test_an_absurd_value_of_any_numeric_setting_is_refused_naming_the_key(task, path, value):
    cfg = with_value(composed(task), path, value)
    with pytest.raises(ConfigError) as err:
        validate_train_cfg(cfg)
    message = str(err.value)
    assert key_of(path) in message, message
    if not (isinstance(value, float) and math.isnan(value)):  # NaN: "must be a finite number"
        said = message.split(", got")[0]  # the rule, not the value
        assert re.search(r"[\[(]-?[\d.]+, [^\]\)]+[\])]|\d+\.\.\d+", said), f"no range in: {message}"


def test_the_defaults_of_each_task_and_each_shipped_policy_file_of_it_pass():
    """The bounds leave every shipped config valid (the walk's refusals are the values', not the bounds')."""
    with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
        for policy in sorted(p.stem for p in (ROOT / "cfg" / "policy").glob("*.yaml")):
            task = "rough_static" if policy == "rs" else "moving_platform"
            to_train_cfg(compose("config", overrides=[f"task={task}", f"policy={policy}", "preset=paper"]))


def test_the_history_bound_is_what_the_estimators_convolutions_need():
    """env.observations.history_length's lower bound is the estimator's: one step less cannot build it."""
    HistoryEstimator(obs_dim=45, history_len=MIN_HISTORY_LENGTH, out_dim=13)
    with pytest.raises(ValueError, match="too short"):
        HistoryEstimator(obs_dim=45, history_len=MIN_HISTORY_LENGTH - 1, out_dim=13)


@pytest.mark.parametrize("task", TASKS)
def test_each_env_hands_out_exactly_the_observation_groups_and_widths_it_declares(task):
    """The policy/task check reads OBS_GROUPS, the memory estimate `observation_widths` and the model
    `build_model` makes (lasmp/cli/resources.py, no env built): they must be what a built env has."""
    import mujoco

    cfg = composed(task)
    one = dataclasses.replace(
        cfg.env, num_envs=1, observations=dataclasses.replace(cfg.env.observations, history_length=17)
    )
    env = registry.make_env(task, one)
    env_class = registry.env_class(task)
    obs = env.get_observations()
    assert sorted(obs.keys()) == sorted(env_class.OBS_GROUPS)
    assert {k: v[0].numel() for k, v in obs.items()} == env_class.observation_widths(one)
    assert obs["history"].shape[1:] == (17, obs["policy"].shape[1])
    built = mujoco.MjData(env_class.build_model(one)).nbuffer
    assert built == env.sim.batch.get_data(0).nbuffer > 0


# -- through the training's entry point ---------------------------------------------------------------
ENTRY_CASES = {
    "a decimation of a million": (
        ["env.sim.decimation=1000000"],
        r"env\.sim\.decimation must be an integer in \[1, 20\]",
    ),
    "no actor layers": (["policy.actor_hidden_dims=[]"], r"policy\.actor_hidden_dims must list 1 to 8"),
    "a negative actor layer": (
        ["policy.actor_hidden_dims=[-5]"],
        r"policy\.actor_hidden_dims must hold integers in \[1, 4096\]",
    ),
    "no critic layers": (["policy.critic_hidden_dims=[]"], r"policy\.critic_hidden_dims must list"),
    "no encoder layers": (["policy.encoder_hidden_dims=[]"], r"policy\.encoder_hidden_dims must list"),
    "a history the estimators cannot convolve": (
        ["env.observations.history_length=4"],
        r"history_length .*\[12, 500\]",
    ),
    "the platform policy on rough ground": (
        ["task=rough_static", "policy=lasmp"],
        r"policy=lasmp does not fit task=rough_static.*policy\.use_alignment",
    ),
    "the rough-ground policy on the platform": (
        ["policy=rs"],
        r"policy=rs does not fit task=moving_platform.*command_input",
    ),
}


@pytest.mark.parametrize("case", sorted(ENTRY_CASES))
def test_a_setting_without_meaning_is_refused_at_start_up_in_one_line(tmp_path, case):
    overrides, pattern = ENTRY_CASES[case]
    run = tmp_path / "run"
    out = train(tiny(*overrides, f"runner.log_dir={run}"))
    refused(out, pattern)
    assert out.code == 2 and not run.exists()
    assert len([line for line in out.text.splitlines() if line.startswith("error:")]) == 1, out.text


def test_train_py_refuses_a_decimation_of_a_million_at_once_with_one_line(tmp_path):
    """Accepted, it would make the first rollout ignore SIGTERM for over a minute."""
    proc = train_py(tiny("env.sim.decimation=1000000", f"runner.log_dir={tmp_path / 'run'}"), tmp_path)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 2, err[-2000:]
    assert "Traceback" not in out + err
    errors = [line for line in err.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "env.sim.decimation must be an integer in [1, 20]" in errors[0], err[-2000:]
    assert not (tmp_path / "run").exists()
