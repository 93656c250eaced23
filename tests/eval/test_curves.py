"""The learning-curve tool reads a run's TensorBoard scalars, plots them and summarizes windows."""

from __future__ import annotations

import json

import pytest
from torch.utils.tensorboard import SummaryWriter

from lasmp.eval import curves


def write_run(path, iterations: int = 20, reward_scale: float = 2.0):
    w = SummaryWriter(str(path))
    for it in range(iterations):
        w.add_scalar("Episode/success_rate", it / 20, it)
        w.add_scalar("Curriculum/level", 5 + it // 10, it)
        w.add_scalar("Train/mean_reward", reward_scale * it, it)
        w.add_scalar("Episode_Reward/task1_center", 0.1 * it, it)
        w.add_scalar("Loss/value_function", 1.0, it)  # not a curve we summarize
    w.close()
    return path


@pytest.fixture
def run_dir(tmp_path):
    return write_run(tmp_path)


def test_windows_average_the_main_tags_and_reward_terms(run_dir, capsys):
    out = run_dir / "curve.png"
    assert curves.main([str(run_dir), "--out", str(out), "--json", "--every", "10"]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    windows = json.loads(capsys.readouterr().out)["windows"]
    assert [w["iterations"] for w in windows] == [[0, 9], [10, 19]]
    assert windows[0]["Curriculum/level"] == 5.0 and windows[1]["Curriculum/level"] == 6.0
    assert windows[1]["Train/mean_reward"] == pytest.approx(2.0 * 14.5)
    assert windows[0]["Episode_Reward/task1_center"] == pytest.approx(0.45)
    assert "Loss/value_function" not in windows[0]


def test_an_rs_runs_timeout_rate_reads_as_the_success_rate(tmp_path):
    """Event files that tag the share of episodes reaching the time limit `Episode/timeout_rate`
    read under the tag both tasks log it as."""
    w = SummaryWriter(str(tmp_path))
    for it in range(3):
        w.add_scalar("Episode/timeout_rate", it / 4, it)
    w.close()
    scalars = curves.read_scalars(tmp_path)
    assert "Episode/timeout_rate" not in scalars
    assert scalars["Episode/success_rate"][1].tolist() == [0.0, 0.25, 0.5]


def test_a_directory_without_event_files_is_an_error(tmp_path, capsys):
    assert curves.main([str(tmp_path), "--json"]) == 2
    assert "no TensorBoard event files" in capsys.readouterr().err


def test_several_runs_are_compared_at_one_budget(tmp_path, capsys):
    a, b = write_run(tmp_path / "a"), write_run(tmp_path / "b", iterations=30, reward_scale=3.0)
    out = tmp_path / "compare.png"
    argv = [
        str(a),
        str(b),
        "--labels",
        "A",
        "B",
        "--last-iteration",
        "14",
        "--every",
        "10",
        "--out",
        str(out),
        "--json",
    ]
    assert curves.main(argv) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    runs = json.loads(capsys.readouterr().out)["runs"]
    assert [r["label"] for r in runs] == ["A", "B"]
    for run, scale in zip(runs, (2.0, 3.0), strict=True):  # both cut after iteration 14
        assert [w["iterations"] for w in run["windows"]] == [[0, 9], [10, 14]]
        assert run["windows"][1]["Train/mean_reward"] == pytest.approx(scale * 12.0)


def test_labels_must_match_the_runs(tmp_path):
    with pytest.raises(SystemExit):
        curves.main([str(write_run(tmp_path / "a")), "--labels", "A", "B"])
    with pytest.raises(SystemExit):
        curves.main([str(tmp_path / "a"), str(write_run(tmp_path / "b")), "--labels", "A", "A"])
    with pytest.raises(SystemExit):  # nothing would be left to plot
        curves.main([str(tmp_path / "a"), "--last-iteration", "-1"])
