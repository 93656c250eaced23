"""Command-line entry points, end to end at tiny sizes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from omegaconf import OmegaConf

ROOT = Path(__file__).resolve().parents[1]


def test_env_throughput_bench_prints_one_json_object(tmp_path):
    out = subprocess.run(
        [
            sys.executable,
            str(ROOT / "bench" / "env_throughput.py"),
            "--num-envs",
            "8",
            "--steps",
            "30",
            "--json",
        ],
        capture_output=True,
        text=True,
        check=True,
        cwd=tmp_path,
        timeout=300,
    )
    result = json.loads(out.stdout)
    for key in (
        "env_steps_per_s",
        "raw_steps_per_s",
        "ratio",
        "stand_still_collision_rate",
        "env_physics_share",
        "env_other_ms_per_step",
        "raw_samples",
    ):
        assert key in result, key
    assert result["env_steps_per_s"] > 0 and result["raw_steps_per_s"] > 0
    # the env's wall time per step is its physics plus the rest
    env_ms = 8 / result["env_steps_per_s"] * 1e3
    assert result["env_other_ms_per_step"] == pytest.approx(
        (1 - result["env_physics_share"]) * env_ms, rel=0.02, abs=0.02
    )
    assert result["torch_threads"] == 1
    assert result["raw_samples"] == 30  # one per env step when there are fewer steps than samples
    assert abs(result["ratio"] - result["env_steps_per_s"] / result["raw_steps_per_s"]) < 1e-2


def test_train_iteration_bench_prints_the_time_breakdown(tmp_path):
    out = subprocess.run(
        [
            sys.executable,
            str(ROOT / "bench" / "train_iteration.py"),
            "--num-envs",
            "8",
            "--iterations",
            "1",
            "--json",
            "torch_threads=1",
            "policy.actor_hidden_dims=[32,32,32]",
            "runner.validation_episodes=4",
        ],
        capture_output=True,
        text=True,
        check=True,
        cwd=tmp_path,
        timeout=300,
    )
    result = json.loads(out.stdout)  # --json: one JSON object and nothing else
    # one validation of 4 episodes, timed warm, and its share of a run at the default interval
    assert (result["validation_episodes"], result["validation_interval"]) == (4, 50)
    share = result["validation_s"] / (result["validation_s"] + 50 * result["s_per_iteration"])
    assert result["validation_s"] > 0 and result["validation_share"] == pytest.approx(share, abs=1e-4)
    parts = ("physics_s", "policy_inference_s", "env_other_s", "update_ppo_s", "update_roa_s")
    assert all(result[k] >= 0 for k in parts)
    assert result["physics_s"] > 0 and result["update_ppo_s"] > 0 and result["update_roa_s"] > 0
    assert sum(result[k] for k in parts) <= result["s_per_iteration"] * 1.05
    assert result["policy_steps_per_s"] > 0


@pytest.mark.parametrize(
    "task, env_key, override",
    [
        ("moving_platform", "trajectory", "env.rewards.h_des_from=top"),
        ("rough_static", "terrain", "env.pushes.max_mps=0.5"),
    ],
)
def test_train_cfg_job_prints_the_tasks_typed_env(tmp_path, task, env_key, override):
    out = subprocess.run(
        [
            sys.executable,
            str(ROOT / "train.py"),
            "--cfg",
            "job",
            f"task={task}",
            "env.sim.num_threads=1",
            override,
        ],
        capture_output=True,
        text=True,
        check=True,
        cwd=tmp_path,
        timeout=300,
    )
    cfg = OmegaConf.create(out.stdout)  # the composed config, as YAML, and nothing else
    assert cfg.task == task and env_key in cfg.env and cfg.env.sim.num_threads == 1
    key, value = override.split("=")
    assert str(OmegaConf.select(cfg, key)) == value


@pytest.mark.parametrize(
    "override, key, valid",
    [
        # refused as Hydra composes: our line, not its hint to append the key with `+`
        ("env.num_envz=3", "env.num_envz", "num_envs"),
        # appended by Hydra, refused by validation
        ("+env.trajectory.fiel=x", "env.trajectory.fiel", "file"),
    ],
)
def test_train_cli_refuses_a_typo_naming_the_key_and_the_valid_ones_never_a_plus(
    tmp_path, override, key, valid
):
    out = subprocess.run(
        [
            sys.executable,
            str(ROOT / "train.py"),
            override,
            "runner.max_iterations=0",
            f"runner.log_dir={tmp_path / 'run'}",
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=300,
    )
    assert out.returncode == 2, out.stderr[-2000:]
    error = out.stderr.strip().splitlines()[-1]
    assert error.startswith("error: unknown config key") and f"'{key}'" in error and f"'{valid}'" in error
    assert "+env" not in out.stderr and "append" not in out.stderr, out.stderr[-2000:]
    assert not (tmp_path / "run").exists()  # refused before anything was written


def unknown_key_error(argv: list[str]) -> str | None:
    """The error that refuses train.py's command line `argv` as it composes its config, in this process."""
    from lasmp.cli.command_line import CommandLine, compose_job
    from lasmp.config.train import register_configs

    register_configs()  # what train.py does on import
    (overrides,) = CommandLine.parse(argv).jobs
    return compose_job(ROOT / "cfg", "config", overrides)[1]


@pytest.mark.parametrize(
    "argv, expected",
    [
        (
            ["env.trajectory.fiel=x"],
            "unknown config key 'env.trajectory.fiel'; valid keys of env.trajectory: [",
        ),
        (
            ["task=rough_static", "env.trajectory.file=x"],
            "unknown config key 'env.trajectory'; valid keys of env: [",
        ),
        (
            ["env.rewards.weights.task1_centre=1"],
            "'env.rewards.weights.task1_centre'; valid keys of env.rewards.weights",
        ),
        (["--cfg", "job", "seeed=1"], "unknown config key 'seeed'; valid keys: ["),
        (["task=rough_static", "env.num_envs=8"], None),
        (["+env.trajectory.fiel=x"], None),  # Hydra appends it: validation refuses it, as above
        (["task=nope"], "Could not find 'task/nope'"),  # not a key: Hydra's own message, in one line
        (
            ["env=rough_static"],
            "recipe=lasmp_plus sets 'env.rewards.air_time_charge', a key this command's env",
        ),
        (["task=rough_static", "recipe=paper"], "recipe=paper sets 'env.rewards.air_time_charge'"),
        (["task=rough_static"], None),  # the task takes no recipe
    ],
)
def test_unknown_key_error_words_only_the_unknown_key(argv, expected):
    error = unknown_key_error(argv)
    if expected is None:
        assert error is None
    else:
        assert expected in error


def test_unknown_key_error_lists_the_keys_of_the_level_the_other_overrides_compose():
    platform = unknown_key_error(["env.fiel=x"])
    rough = unknown_key_error(["task=rough_static", "env.fiel=x"])
    assert "'trajectory'" in platform and "'terrain'" not in platform
    assert "'terrain'" in rough and "'trajectory'" not in rough
