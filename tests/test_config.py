"""Configuration: every override example of the README composes and validates as written, a typo
fails naming the key in every subtree, the presets validate, saved configs read back, and the env
schemas import without the envs."""

from __future__ import annotations

import dataclasses
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
import torch
import yaml
from hydra import compose, initialize_config_dir
from hydra.errors import ConfigCompositionException
from omegaconf import OmegaConf
from omegaconf.errors import ConfigKeyError

from lasmp.cli.build import make_runner
from lasmp.config.checks import ConfigError, check_config
from lasmp.config.train import (
    TASKS,
    AlgoCfg,
    PolicyCfg,
    RunnerCfg,
    SymmetryCfg,
    register_configs,
    to_plain,
    to_train_cfg,
)
from lasmp.envs.moving_platform.rewards import RewardsCfg

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")
register_configs()

# `python train.py ARGS` anywhere in the README, in code blocks and inline code; ARGS end at a
# comment, a closing backtick or a shell operator
TRAIN_COMMAND = re.compile(r"python train\.py((?:[ \t]+[^\s`#&|;]+)*)")
# an inline code span made of overrides only, e.g. `env.trajectory.file=PATH`; placeholders such as
# `domain_rand.split=train|test` or env-relative field names are prose, not command lines
OVERRIDE = re.compile(
    r"\+{0,2}(?:(?:env|policy|algo|runner)\.[\w.]+|task|policy|recipe|preset|seed|device|torch_threads|resume)"
    r"=[^\s|<>]+"
)
HYDRA_FLAGS_WITH_VALUE = ("--cfg", "-c", "--package", "-p")  # Hydra's own options, not overrides


def readme_override_examples() -> list[tuple[str, ...]]:
    examples: list[tuple[str, ...]] = []
    for match in TRAIN_COMMAND.finditer(README):
        args, overrides = match.group(1).split(), []
        while args:
            arg = args.pop(0)
            if arg in HYDRA_FLAGS_WITH_VALUE:
                args.pop(0)
            elif not arg.startswith("-"):
                overrides.append(arg)
        examples.append(tuple(overrides))
    for span in re.findall(r"`([^`\n]+)`", README):
        tokens = span.split()
        if tokens and all(OVERRIDE.fullmatch(token) for token in tokens):
            examples.append(tuple(tokens))
    return list(dict.fromkeys(examples))  # unique, in README order


README_EXAMPLES = readme_override_examples()


def compose_cfg(overrides):
    with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
        return compose("config", overrides=list(overrides))


def test_the_readme_has_override_examples_in_the_plain_form():
    assert len(README_EXAMPLES) >= 10, README_EXAMPLES  # the regexes still find the README's commands
    env_keys = {token.split("=")[0] for example in README_EXAMPLES for token in example}
    assert {"env.num_envs", "env.trajectory.file", "env.rewards.h_des_from", "preset"} <= env_keys
    # env keys are typed structured configs: `+env.key=value` is not needed (and fails for a set key)
    assert "+env." not in README


@pytest.mark.parametrize("overrides", README_EXAMPLES, ids=" ".join)
def test_every_readme_override_example_composes_and_validates(overrides):
    cfg = to_train_cfg(compose_cfg(overrides))  # validates, device=cuda included (no GPU needed)
    plain = to_plain(cfg)
    for override in overrides:
        key, value = override.lstrip("+").split("=", 1)
        if key in ("preset", "recipe"):  # options that set several keys (tested on their own)
            continue
        got = cfg.policy.name if key == "policy" else OmegaConf.select(OmegaConf.create(plain), key)
        assert got == yaml.safe_load(value), override  # the value reached the validated config


@pytest.mark.parametrize(
    "overrides, key",
    [
        (["env.trajectory.fiel=x"], "env.trajectory.fiel"),
        (["env.platform.mass=3"], "env.platform.mass"),
        (["env.num_env=8"], "env.num_env"),
        (["env.rewards.weights.task1_centre=1.0"], "env.rewards.weights.task1_centre"),
        (["task=rough_static", "env.terrain.roughnes_m=0.02"], "env.terrain.roughnes_m"),
        (["task=rough_static", "env.trajectory.file=x"], "env.trajectory"),  # R-S has no trajectory
        (["policy.use_aligment=false"], "policy.use_aligment"),
        (["algo.learning_rat=0.1"], "algo.learning_rat"),
        (["runner.max_iteration=3"], "runner.max_iteration"),
        (["seeed=1"], "seeed"),
    ],
)
def test_a_typo_fails_at_composition_naming_the_key(overrides, key):
    with pytest.raises(ConfigCompositionException, match=re.escape(key)):
        compose_cfg(overrides)


@pytest.mark.parametrize(
    "overrides, key",
    [
        (["+env.trajectory.fiel=x"], "env.trajectory.fiel"),
        (["+env.platfrom.mass_kg=3"], "env.platfrom"),
        (["task=rough_static", "+env.pushes.max_mp=1"], "env.pushes.max_mp"),
        (["+policy.use_aligment=false"], "policy.use_aligment"),
        (["+algo.learning_rat=0.1"], "algo.learning_rat"),
        (["+runner.max_iteration=3"], "runner.max_iteration"),
        (["+seeed=1"], "seeed"),
    ],
)
def test_an_appended_typo_fails_validation_naming_the_key(overrides, key):
    cfg = compose_cfg(overrides)  # Hydra appends a `+key` it does not know
    with pytest.raises(ConfigError, match=re.escape(f"'{key}'")):
        to_train_cfg(cfg)


@pytest.mark.parametrize(
    "conf, key",
    [
        ({"env": {"trajectory": {"fiel": "x"}}}, "fiel"),
        ({"task": "rough_static", "env": {"commands": {"resample": 1.0}}}, "resample"),
        ({"policy": {"latent_dims": 8}}, "latent_dims"),
        ({"algo": {"gama": 0.9}}, "gama"),
        ({"runner": {"log": "x"}}, "log"),
        ({"sed": 1}, "sed"),
    ],
)
def test_a_typo_in_a_saved_config_fails_naming_the_key(conf, key):
    """A checkpoint's config is a plain dict: it is checked against the same schemas."""
    with pytest.raises((ConfigError, ConfigKeyError), match=rf"\b{key}\b"):
        to_train_cfg(OmegaConf.create(conf))


@pytest.mark.parametrize(
    "task, one_valid_term", [("moving_platform", "task1_center"), ("rough_static", "stand_still")]
)
def test_an_unknown_reward_term_is_refused_listing_the_tasks_terms(task, one_valid_term):
    cfg = compose_cfg([f"task={task}", "+env.rewards.weights.task1_centre=1.0"])
    with pytest.raises(
        ConfigError, match=r"env\.rewards\.weights: unknown reward term\(s\) \['task1_centre'\]"
    ) as err:
        to_train_cfg(cfg)
    assert one_valid_term in str(err.value)


@pytest.mark.parametrize("task", TASKS)
@pytest.mark.parametrize("preset", sorted(p.stem for p in (ROOT / "cfg" / "preset").glob("*.yaml")))
def test_every_preset_validates_for_every_task(preset, task):
    cfg = to_train_cfg(compose_cfg([f"preset={preset}", f"task={task}"]))
    assert (
        cfg.task == task
        and type(cfg.env).__name__
        == {"moving_platform": "MovingPlatformCfg", "rough_static": "RoughStaticCfg"}[task]
    )


def test_the_paper_preset_validates_and_only_the_runner_needs_a_gpu():
    cfg = to_train_cfg(compose_cfg(["preset=paper"]))
    assert (cfg.device, cfg.env.num_envs, cfg.runner.max_iterations) == ("cuda", 8192, 4000)
    if not torch.cuda.is_available():  # refused where the learner would start, before building the env
        with pytest.raises(ConfigError, match="no CUDA device"):
            make_runner(cfg, None)


def _recipe_keys(cfg) -> tuple:
    return (
        cfg.env.rewards.air_time_charge,
        cfg.env.rewards.weights["ours_support_margin"],
        cfg.env.rewards.support_margin_at_height,
        cfg.algo.symmetry_cfg.use_data_augmentation,
    )


def test_las_mp_plus_is_the_default_recipe_and_the_papers_is_one_override_away():
    default = to_train_cfg(compose_cfg([]))
    plus = to_train_cfg(compose_cfg(["recipe=lasmp_plus"]))
    paper = to_train_cfg(compose_cfg(["recipe=paper"]))
    assert to_plain(default) == to_plain(plus)
    plus_yaml = OmegaConf.load(ROOT / "cfg" / "recipe" / "lasmp_plus.yaml")
    yaml_rewards = plus_yaml.env.rewards
    assert yaml_rewards.air_time_charge != "touchdown" and yaml_rewards.weights.ours_support_margin > 0
    assert _recipe_keys(plus) == (
        yaml_rewards.air_time_charge,
        yaml_rewards.weights.ours_support_margin,
        False,
        True,
    )
    # the paper's recipe is the schema's defaults, every LAS-MP+ option off, with rsl_rl's 5 learning
    # epochs where LAS-MP+ takes the schema's 2 (R-S, which takes no recipe, 5 as well)
    assert _recipe_keys(paper) == ("touchdown", 0.0, False, False)
    assert paper.env.rewards == RewardsCfg()
    assert paper.algo == dataclasses.replace(AlgoCfg(), num_learning_epochs=5)
    assert (plus.algo.num_learning_epochs, AlgoCfg().num_learning_epochs) == (2, 2)
    assert to_train_cfg(compose_cfg(["task=rough_static"])).algo.num_learning_epochs == 5
    # the ablations take the recipe they are given
    ablation = to_train_cfg(compose_cfg(["policy=no_alignment_command", "recipe=paper"]))
    assert _recipe_keys(ablation) == _recipe_keys(paper) and not ablation.policy.use_alignment


def test_a_command_line_key_overrides_the_recipe_and_the_rough_terrain_task_takes_none():
    cfg = to_train_cfg(compose_cfg(["env.rewards.air_time_charge=timeout"]))
    assert cfg.env.rewards.air_time_charge == "timeout" and cfg.algo.symmetry_cfg.use_data_augmentation
    cfg = to_train_cfg(compose_cfg(["recipe=paper", "algo.symmetry_cfg.use_data_augmentation=true"]))
    assert cfg.env.rewards.air_time_charge == "touchdown" and cfg.algo.symmetry_cfg.use_data_augmentation
    rough = to_train_cfg(compose_cfg(["task=rough_static"]))
    assert not rough.algo.symmetry_cfg.enabled


def test_the_env_option_must_be_the_tasks():
    with pytest.raises(ConfigError, match="task=moving_platform needs a MovingPlatformCfg"):
        to_train_cfg(compose_cfg(["env=rough_static", "~recipe"]))  # a recipe sets env keys


@pytest.mark.parametrize(
    "part, name, pattern",
    [
        (PolicyCfg(explicit="none"), "policy", "policy.use_alignment needs policy.explicit=all"),
        (PolicyCfg(explicit="some"), "policy", "policy.explicit must be one of all | no_platform | none"),
        (AlgoCfg(roa_lambda=-1.0), "algo", "algo.roa_lambda must be a number in [0, 100]"),
        (
            AlgoCfg(symmetry_cfg=SymmetryCfg(use_mirror_loss=True)),
            "algo",
            "algo.symmetry_cfg.mirror_loss_coeff",
        ),
        (RunnerCfg(keep_full=0), "runner", "runner.keep_full"),
    ],
)
def test_each_part_of_the_training_config_is_checked_by_what_its_class_declares_naming_the_key(
    part, name, pattern
):
    """As the env's parts are: its class declares its limits and rules, `check_config` checks them, the
    one place each setting is checked (validate_train_cfg walks the whole config with it)."""
    with pytest.raises(ConfigError, match=re.escape(pattern)):
        check_config(part, name)


@pytest.mark.parametrize("task", TASKS)
def test_a_saved_config_reads_back_to_the_same_train_cfg(task):
    cfg = to_train_cfg(compose_cfg([f"task={task}", "seed=4", "env.sim.num_threads=1"]))
    saved = to_plain(cfg)  # what config.yaml and every checkpoint hold
    again = to_train_cfg(OmegaConf.create(json.loads(json.dumps(saved))))
    assert again == cfg and to_plain(again) == saved
    # the saved layout, as checkpoints written before the env schemas moved hold it (plus env.backend,
    # which older checkpoints lack: they read back with its default, cpu)
    assert list(saved) == [
        "task",
        "seed",
        "device",
        "torch_threads",
        "resume",
        "resume_drop_env_state",
        "warm_start",
        "env",
        "policy",
        "algo",
        "runner",
    ]
    # the keys every task shares, then the task's own (an older rough_static config lists init_state
    # and domain_rand after pushes: the order changed, the keys did not)
    common = ["num_envs", "seed", "backend", "sim", "control", "observations", "init_state", "domain_rand"]
    assert (
        list(saved["env"])
        == common
        + {
            "moving_platform": ["platform", "trajectory", "curriculum", "rewards", "termination"],
            "rough_static": [
                "episode_length_s",
                "terrain",
                "commands",
                "pushes",
                "rewards",
                "termination",
                "study_rng_stream",
            ],
        }[task]
    )


def test_the_env_schemas_import_without_the_envs():
    """lasmp.config.base imports no task; a task's cfg module imports none of the modules that import it
    (env, scene), so there is no import cycle to trip over."""
    code = (
        "import json, sys\n"
        "import lasmp.config.base\n"
        "before = sorted(m for m in sys.modules if m.startswith('lasmp.envs'))\n"
        "import lasmp.envs.moving_platform.cfg, lasmp.envs.rough_static.cfg\n"
        "print(json.dumps([before, sorted(m for m in sys.modules if m.startswith('lasmp.'))]))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT, timeout=120
    )
    before, after = json.loads(out.stdout)
    assert before == []
    assert "lasmp.envs.moving_platform.cfg" in after and "lasmp.envs.rough_static.cfg" in after
    assert [m for m in after if m.rsplit(".", 1)[-1] in ("env", "scene")] == []


def test_check_config_checks_each_sections_declared_limits_then_its_rules_once_naming_nested_keys():
    from dataclasses import dataclass, field

    from lasmp.config.checks import Bound

    ruled = []

    @dataclass
    class Leaf:
        BOUNDS = {"n": Bound(1, 10, "a count")}
        RANGES = {"span": Bound(0, 1, "a share")}
        CHOICES = {"kind": ("a", "b")}
        n: int = 2
        span: list[float] = field(default_factory=lambda: [0.2, 0.4])
        kind: str = "a"

        def check_rules(self, p):
            ruled.append(p)
            if self.n == 3:
                raise ConfigError(f"{p}.n: three is refused by a rule")

    @dataclass
    class Root:
        left: Leaf = field(default_factory=Leaf)
        right: Leaf = field(default_factory=Leaf)

    check_config(Root(), "top")
    assert ruled == ["top.left", "top.right"]  # each section's rules once, in the tree's order
    for bad, message in [
        (Leaf(n=11), "top.right.n must be an integer in [1, 10] (a count), got 11"),
        (Leaf(n=2.5), "top.right.n must be an integer"),  # declared int
        (Leaf(span=[0.5, 0.2]), "top.right.span must be a [low, high] pair with low <= high"),
        (Leaf(kind="c"), "top.right.kind must be one of a | b, got 'c'"),
        (Leaf(n=3), "top.right.n: three is refused by a rule"),
    ]:
        with pytest.raises(ConfigError, match=re.escape(message)):
            check_config(Root(right=bad), "top")
    # every section's limits come before any rule: a limit broken on the right is named before a rule
    # that the left breaks
    ruled.clear()
    with pytest.raises(ConfigError, match=re.escape("top.right.n must be")):
        check_config(Root(left=Leaf(n=3), right=Leaf(n=0)), "top")
    assert ruled == []
    with pytest.raises(ConfigError, match=re.escape("unknown config key(s) ['top.left.typo']")):
        leaf = Leaf()
        leaf.typo = 1
        check_config(Root(left=leaf), "top")
