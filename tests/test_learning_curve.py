"""scripts/learning_curve.py: which checkpoint each budget plays, the training minutes read from the
run's own logs, and the refusals before any evaluation, on a constructed run directory (the
evaluation itself is replaced by one that writes a metrics.json)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from testkit import load_script


def constructed_run(d: Path, iterations: int, collect_s: float, learn_s: float) -> Path:
    from torch.utils.tensorboard import SummaryWriter

    d.mkdir(parents=True)
    with SummaryWriter(log_dir=str(d)) as w:
        for it in range(iterations):
            w.add_scalar("Perf/collection_time", collect_s, it)
            w.add_scalar("Perf/learning_time", learn_s, it)
    return d


@pytest.fixture
def curve(tmp_path, monkeypatch):
    mod = load_script("scripts/learning_curve.py")
    played = []

    def fake_run(cmd, cwd, check, stdout):
        ckpt, out = Path(cmd[cmd.index("--checkpoint") + 1]), Path(cmd[cmd.index("--out") + 1])
        n = int(ckpt.stem.split("_")[1]) + 1  # iterations it holds
        played.append(ckpt.name)
        out.mkdir(parents=True)
        metrics = {
            "num_episodes": int(cmd[cmd.index("--num-trajectories") + 1]),
            "metrics": {"collision_rate": {"mean": 1.0 / n}, "height_violation_rate": {"mean": 0.01}},
            "gait": {"four_feet_step_share": 0.5},
        }
        (out / "metrics.json").write_text(json.dumps(metrics))

    monkeypatch.setattr(mod.subprocess, "run", fake_run)
    mod.played = played
    return mod


def test_each_checkpoint_is_played_and_counted_with_the_iterations_it_holds_and_their_training_minutes(
    curve, tmp_path, capsys
):
    run = constructed_run(tmp_path / "run", 300, collect_s=2.0, learn_s=4.0)
    (run / "model_149.pt").write_bytes(b"")
    (run / "policy_299.pt").write_bytes(b"")  # keep_full turned the full checkpoint into the policy's
    out = tmp_path / "curve"
    curve.main([str(run), "--at", "299", "149", "--out", str(out), "--episodes", "20"])
    assert curve.played == ["model_149.pt", "policy_299.pt"]
    points = json.loads((out / "curve.json").read_text())["points"]
    assert [p["iterations"] for p in points] == [150, 300]
    assert [p["collision_rate"] for p in points] == [1 / 150, 1 / 300]
    assert [p["training_minutes"] for p in points] == pytest.approx([150 * 6 / 60, 300 * 6 / 60])
    assert "| 300 | 0.003 | 0.010 | 0.500 | 30.0 |" in capsys.readouterr().out
    curve.main([str(run), "--at", "149", "--out", str(out), "--episodes", "20"])  # evaluated: not replayed
    assert curve.played == ["model_149.pt", "policy_299.pt"]


def test_a_missing_checkpoint_is_refused_before_any_evaluation(curve, tmp_path):
    run = constructed_run(tmp_path / "run", 10, 1.0, 1.0)
    (run / "model_4.pt").write_bytes(b"")
    with pytest.raises(SystemExit, match="no checkpoint of iteration 9"):
        curve.main([str(run), "--at", "4", "9", "--out", str(tmp_path / "curve")])
    assert curve.played == []


def test_an_evaluation_of_another_episode_count_in_the_output_is_refused(curve, tmp_path):
    run = constructed_run(tmp_path / "run", 10, 1.0, 1.0)
    (run / "model_9.pt").write_bytes(b"")
    curve.main([str(run), "--at", "9", "--out", str(tmp_path / "curve"), "--episodes", "20"])
    with pytest.raises(SystemExit, match="evaluated 20 episodes, not 2000"):
        curve.main([str(run), "--at", "9", "--out", str(tmp_path / "curve")])


def test_logs_shorter_than_the_budget_are_refused_before_any_evaluation(curve, tmp_path):
    run = constructed_run(tmp_path / "run", 5, 1.0, 1.0)
    (run / "model_9.pt").write_bytes(b"")
    with pytest.raises(SystemExit, match="for 5 of the first 10 iterations"):
        curve.main([str(run), "--at", "9", "--out", str(tmp_path / "curve"), "--episodes", "20"])
    assert curve.played == []
