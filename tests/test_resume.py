"""What a resume takes from its command line (`lasmp.cli.command_line.explicit_keys`): the keys the overrides
set, read from the overrides alone, for the overrides the resume tests give
(tests/bad_inputs/test_bad_resume.py) and for each kind of group option."""

from __future__ import annotations

import contextlib
from pathlib import Path

import pytest
from hydra import initialize_config_dir

from lasmp.cli.command_line import explicit_keys
from lasmp.config.train import register_configs

ROOT = Path(__file__).resolve().parents[1]
register_configs()

RESUME = ["resume=logs/run", "runner.log_dir=logs/run"]
CASES = {
    "no other override": ([], set()),
    "more envs": (["env.num_envs=8"], {"env.num_envs"}),
    "more envs, their state dropped": (
        ["env.num_envs=8", "resume_drop_env_state=true"],
        {"env.num_envs", "resume_drop_env_state"},
    ),
    "other actor layers": (["policy.actor_hidden_dims=[16,16,16]"], {"policy.actor_hidden_dims"}),
    "another activation": (["policy.activation=tanh"], {"policy.activation"}),
    "another seed": (["seed=7"], {"seed"}),
    "another observation history": (
        ["env.observations.history_length=15"],
        {"env.observations.history_length"},
    ),
    "a new learning rate": (
        ["algo.schedule=fixed", "algo.learning_rate=0.0005"],
        {"algo.schedule", "algo.learning_rate"},
    ),
    "a reward setting": (["env.rewards.sigma_center_m=1.0"], {"env.rewards.sigma_center_m"}),
    "an appended key": (["+seed=3"], {"seed"}),
    # a group option: the keys its own config sets, under its package
    # its env and policy stay the run's; the task's file also sets R-S's learning epochs
    "another task": (["task=rough_static"], {"task", "algo.num_learning_epochs"}),
    "a preset": (["preset=paper"], {"device", "env.num_envs", "runner.max_iterations"}),
    "an ablation": (["policy=no_alignment_command"], {"policy.name", "policy.use_alignment"}),
}


@contextlib.contextmanager
def _hydra(app: bool):
    """As train.py's Hydra app (initialized on cfg/), or a caller outside any."""
    if not app:
        yield
        return
    with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
        yield


@pytest.mark.parametrize("app", [True, False], ids=["in Hydra's app", "outside Hydra"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_a_resume_takes_the_keys_its_overrides_set(case, app):
    overrides, keys = CASES[case]
    with _hydra(app):
        assert explicit_keys(overrides + RESUME) == keys | {"resume", "runner.log_dir"}


def test_an_env_option_sets_every_key_of_its_schema():
    keys = explicit_keys(["env=rough_static"])
    assert all(k.startswith("env.") for k in keys)
    assert {"env.num_envs", "env.terrain.resolution_m", "env.pushes.enabled"} <= keys


@pytest.mark.parametrize(
    "run_dir",
    ["logs/run", "/runs/my run", "/runs/it's, [a]=b", "/runs/back\\slash", '/runs/"quoted"\\'],
)
def test_the_printed_resume_command_pastes_back_to_the_same_paths(run_dir):
    """T08: a path with a space, a quote, a comma or brackets is quoted for the shell and for Hydra,
    so that the printed command, pasted, resumes from that very checkpoint."""
    import shlex

    from hydra.core.override_parser.overrides_parser import OverridesParser

    from lasmp.cli.command_line import resume_command

    checkpoint = f"{run_dir}/model_7.pt"
    command = resume_command(checkpoint, run_dir, 3)
    words = shlex.split(command)
    assert words[:2] == ["python", "train.py"]
    values = {o.key_or_group: o.value() for o in OverridesParser.create().parse_overrides(words[2:])}
    assert values == {"runner.max_iterations": 3, "resume": checkpoint, "runner.log_dir": run_dir}
