"""The validation benchmark (drawn as Xi_eval is, from its own seed; never Xi_eval) and the in-training
validator (a fixed subset, the same score as evaluate.py gives the saved policy)."""

from __future__ import annotations

import csv
import gzip
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from testkit import tiny

from lasmp.eval import benchmark as bm
from lasmp.eval.validation import Validator

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def validation_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("bench") / "validation.npz"
    bm.save(path, bm.generate_set(bm.VALIDATION))
    return path


def test_the_validation_benchmark_is_drawn_as_xi_eval_is_from_a_seed_of_its_own(tmp_path):
    v = bm.VALIDATION
    assert (v.seed, v.num_trajectories, v.num_robots) == (1, 2_000, bm.XI_EVAL.num_robots)
    assert v.seed != bm.XI_EVAL.seed and v.path != bm.XI_EVAL.path
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    bm.save(a, bm.generate_set(v))
    bm.save(b, bm.generate(2_000, 1_024, 1))  # the generator of Xi_eval, its own seed
    assert a.read_bytes() == b.read_bytes()  # deterministic, bit for bit
    val, xi = bm.load(a), bm.generate(2_000, 1_024, bm.XI_EVAL.seed)
    assert not np.array_equal(val.robots.trunk_mass_kg, xi.robots.trunk_mass_kg)
    assert not np.array_equal(val.trajectories.n_waypoints, xi.trajectories.n_waypoints)
    assert set(np.unique(val.trajectories.n_waypoints)) == set(range(4, 17))  # the testing split's N
    stats = bm.describe(a, val)["statistics"]["overall"]
    # the testing split's calibration target (the paper's testing set, docs/trajectories.md#why-degree-10):
    # within 10 % of 7.12 m and 0.69 m/s, as Xi_eval
    assert abs(stats["mean_path_length_m"] / 7.12 - 1) < 0.1 and abs(stats["mean_speed_mps"] / 0.69 - 1) < 0.1


def test_a_validation_benchmark_drawn_from_xi_evals_seed_is_refused(tmp_path):
    path = tmp_path / "validation.npz"
    bm.save(path, bm.generate(2_000, 1_024, bm.XI_EVAL.seed))
    with pytest.raises(
        bm.BenchmarkFileError, match="Xi_eval's: the validation benchmark must not be the test set"
    ):
        bm.load_or_make(bm.VALIDATION, path)
    out = tmp_path / "made.npz"
    code = bm.main(["generate", "--set", "validation", "--seed", "0", "--out", str(out)])
    assert code == 2 and not out.exists()  # refused before anything is written


def test_evaluate_plays_the_validation_benchmark_by_name_and_writes_apart_from_xi_eval(tmp_path):
    from types import SimpleNamespace

    from lasmp.eval.build import benchmark_arg
    from lasmp.eval.outdir import default_out_dir

    assert benchmark_arg("validation") == Path(bm.VALIDATION.path)
    assert benchmark_arg("xi_eval") == Path(bm.XI_EVAL.path)
    assert benchmark_arg("my.npz") == Path("my.npz")
    args = SimpleNamespace(checkpoint=None, controller="stand_still", benchmark=benchmark_arg("validation"))
    assert default_out_dir(args) == Path("eval/stand_still_validation")
    args.benchmark = benchmark_arg("xi_eval")
    assert default_out_dir(args) == Path("eval/stand_still")


def _trained(tmp_path, iterations: int = 2):
    from lasmp.cli.train import train

    cfg = tiny(tmp_path / "run", runner={"max_iterations": iterations, "validation_interval": 0})
    return train(cfg)


def _score(runner, validator: Validator, it: int):
    obs = runner.env.get_observations()
    from lasmp.algo.checkpoint import obs_layout

    return validator(it, runner.alg.actor.state_dict(), obs_layout(obs), runner.env.num_actions)


def test_the_validator_plays_the_first_episodes_of_the_validation_set_the_same_every_time(tmp_path):
    runner = _trained(tmp_path)
    bench = bm.generate_set(bm.VALIDATION)
    validator = Validator(runner.full_config, 6, bench=bench)
    torch_before = torch.get_rng_state()
    a, b = _score(runner, validator, 1), _score(runner, validator, 1)
    assert torch.equal(torch.get_rng_state(), torch_before)  # the training's stream is untouched
    assert validator._bench.num_episodes == 6
    np.testing.assert_array_equal(
        validator._bench.trajectories.n_waypoints, bench.trajectories.n_waypoints[:6]
    )
    assert (a.collision_rate, a.height_violation_rate, a.world_tilt_rad) == (
        b.collision_rate,
        b.height_violation_rate,
        b.world_tilt_rad,
    )
    assert 0 <= a.collision_rate <= 1 and a.world_tilt_rad > 0
    # another policy scores otherwise on the same episodes: the score reads the weights it is given
    noisy = {
        k: v + 0.5 * torch.randn_like(v) if v.is_floating_point() else v
        for k, v in runner.alg.actor.state_dict().items()
    }
    from lasmp.algo.checkpoint import obs_layout

    c = validator(1, noisy, obs_layout(runner.env.get_observations()), runner.env.num_actions)
    assert (c.collision_rate, c.world_tilt_rad) != (a.collision_rate, a.world_tilt_rad)


def test_the_validation_score_is_what_evaluate_gives_the_saved_checkpoint(tmp_path, validation_file):
    from lasmp.algo.checkpoint import latest_checkpoint
    from lasmp.eval.cli import main as evaluate

    runner = _trained(tmp_path)
    score = _score(runner, Validator(runner.full_config, 6, bench=bm.load(validation_file)), 1)
    out = tmp_path / "eval"
    args = ["--checkpoint", str(latest_checkpoint(tmp_path / "run")), "--benchmark", str(validation_file)]
    args += ["--num-trajectories", "6", "--batch-envs", "6", "--no-platform-probe", "--out", str(out)]
    assert evaluate(args) == 0
    with gzip.open(out / "episodes.csv.gz", "rt") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 6
    mean = {
        k: float(np.nanmean([float(r[k] or "nan") for r in rows]))
        for k in rows[0]
        if k in ("height_violation_rate", "rotation_deviation_rad")
    }
    collided = float(np.mean([r["collision_time_s"] not in ("", "nan") for r in rows]))
    assert score.collision_rate == pytest.approx(collided)
    assert score.height_violation_rate == pytest.approx(mean["height_violation_rate"])
    assert score.world_tilt_rad == pytest.approx(mean["rotation_deviation_rad"])


def test_train_cli_validates_keeps_the_best_policy_and_its_curve(tmp_path):
    run = tmp_path / "run"
    cmd = [
        sys.executable,
        "train.py",
        "env.num_envs=4",
        "runner.max_iterations=2",
        "runner.validation_interval=1",
    ]
    cmd += [
        "runner.validation_episodes=3",
        f"runner.log_dir={run}",
        "torch_threads=1",
        "algo.precision=float32",
    ]
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    assert "validation it 0: collision" in out.stdout and "validation it 1: collision" in out.stdout
    curve = json.loads((run / "validation.json").read_text())
    assert [r["iteration"] for r in curve["history"]] == [0, 1]
    assert [r["env_steps"] for r in curve["history"]] == [48, 96]  # 4 envs x 12 steps per iteration
    assert curve["best"] in curve["history"]
    best = torch.load(run / "policy_best.pt", weights_only=True)
    assert best["kind"] == "policy" and best["iter"] == curve["best"]["iteration"]
    assert "optimizer_state_dict" not in best and "run" not in best["env_state"]


@pytest.mark.parametrize(
    "key, value, message",
    [
        ("validation_interval", -1, r"runner.validation_interval must be an integer in \[0, 1000000\]"),
        ("validation_episodes", 0, r"runner.validation_episodes must be an integer in \[1, 2000\]"),
        ("validation_episodes", 2_001, r"runner.validation_episodes must be an integer in \[1, 2000\]"),
    ],
)
def test_validation_settings_out_of_range_are_refused_naming_the_key(tmp_path, key, value, message):
    from lasmp.config.checks import ConfigError

    with pytest.raises(ConfigError, match=message):
        tiny(tmp_path, runner={key: value})
