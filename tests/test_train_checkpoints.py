"""A tiny training run's checkpoints: the round trip and the exact resume, the latest by number,
bad checkpoints named with what is wrong, and the determinism they rely on (one seed, the same
parameters; another seed, others)."""

from __future__ import annotations

import pytest
import torch
from testkit import tiny

from lasmp.algo.checkpoint import CheckpointError, latest_checkpoint, read_checkpoint
from lasmp.cli.build import make_runner
from lasmp.cli.train import train


def test_checkpoint_round_trip_and_exact_resume(tmp_path):
    cfg = tiny(tmp_path / "a")
    runner = train(cfg)
    ckpt = latest_checkpoint(tmp_path / "a")
    assert ckpt.name == "model_1.pt"
    data = read_checkpoint(ckpt)
    assert data["iter"] == 1 and data["num_actions"] == 12
    assert data["obs_layout"]["history"] == [20, 44]
    assert data["config"]["env"]["num_envs"] == 4
    assert "estimator_optimizer_state_dict" in data and data["env_state"]["curriculum"]["level"] == 5

    runner.env.curriculum._level = 7  # a state only the checkpoint can bring back
    runner.alg.learning_rate = 0.000123
    for group in runner.alg.optimizer.param_groups:
        group["lr"] = 0.000123
    runner.save(str(tmp_path / "a" / "model_5.pt"))

    resumed = make_runner(tiny(tmp_path / "b"), None)
    resumed.load(str(tmp_path / "a"))  # a run directory: its latest checkpoint, model_5
    assert resumed.current_learning_iteration == runner.current_learning_iteration + 1
    assert resumed.env.curriculum.level == 7
    assert resumed.alg.learning_rate == pytest.approx(0.000123)
    for (k, v), (k2, v2) in zip(
        runner.alg.get_policy().state_dict().items(),
        resumed.alg.get_policy().state_dict().items(),
        strict=True,
    ):
        assert k == k2 and torch.equal(v, v2), k


def test_latest_checkpoint_is_numeric(tmp_path):
    for n in (9, 10, 2):
        (tmp_path / f"model_{n}.pt").write_bytes(b"x")
    (tmp_path / "model_best.pt").write_bytes(b"x")
    assert latest_checkpoint(tmp_path).name == "model_10.pt"
    with pytest.raises(CheckpointError, match="no checkpoint"):
        latest_checkpoint(tmp_path / "empty_dir_that_does_not_exist")


def test_bad_checkpoints_fail_with_a_message_that_says_what_is_wrong(tmp_path):
    train(tiny(tmp_path / "a"))
    good = latest_checkpoint(tmp_path / "a")
    with pytest.raises(CheckpointError, match="does not exist"):
        read_checkpoint(tmp_path / "missing.pt")
    truncated = tmp_path / "truncated.pt"
    truncated.write_bytes(good.read_bytes()[:1000])
    with pytest.raises(CheckpointError, match="unreadable"):
        read_checkpoint(truncated)
    other = make_runner(tiny(tmp_path / "b", env={"observations": {"history_length": 15}}), None)
    with pytest.raises(CheckpointError, match=r"'history'.*\[20, 44\].*\[15, 44\]"):
        other.load(str(good))


def test_two_cpu_runs_with_the_same_seed_give_identical_parameters(tmp_path):
    def run(name, seed):
        cfg = tiny(tmp_path / name, seed=seed, runner={"max_iterations": 3})
        return train(cfg).alg.get_policy().state_dict()

    a, b, c = run("a", 1), run("b", 1), run("c", 2)
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert not all(torch.equal(a[k], c[k]) for k in a)
