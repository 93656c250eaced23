"""The mirror evaluation (`evaluate.py --mirror K`) and the stance measures of every evaluation."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lasmp.eval import benchmark as bm
from lasmp.eval import episodes as ep
from lasmp.eval.gait import GaitTracker, summarize_gait
from lasmp.eval.mirror import legs_in_cause, mirror_report

ROOT = Path(__file__).resolve().parents[2]


def test_stand_still_fails_the_same_episodes_as_their_mirror_twins_on_the_mirror_legs(tmp_path):
    """Stand Still is left-right symmetric: the mirrored world must give it overlap 1.0, the same
    collision times, and each failure on the mirror image of the original's legs."""
    bench_path = tmp_path / "bench.npz"
    bm.save(bench_path, bm.generate(num_trajectories=32, num_robots=8, seed=0))
    out = subprocess.run(
        [sys.executable, str(ROOT / "evaluate.py"), "--controller", "stand_still", "--benchmark", str(bench_path),
         "--num-trajectories", "32", "--mirror", "24", "--no-platform-probe", "--out", str(tmp_path / "ev")],
        capture_output=True, text=True, cwd=tmp_path, timeout=600,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    report = json.loads((tmp_path / "ev" / "metrics.json").read_text())["mirror"]
    assert report["episodes"] == 24 and report["failed_in_both"] > 5
    assert report["failure_overlap"] == 1.0
    assert report["mirrored_legs_as_original"] == report["original_legs"]
    assert report["original_legs"] != report["mirrored_legs"]  # the twins fail on the other side
    original = ep.read_csv(tmp_path / "ev" / ep.EPISODES_FILE)
    twins = ep.read_csv(tmp_path / "ev" / ep.MIRROR_EPISODES_FILE)
    np.testing.assert_array_equal(twins["collision_time_s"], original["collision_time_s"][:24])
    np.testing.assert_allclose(
        twins["com_shift_y_m"], -original["com_shift_y_m"][:24] - 2 * 0.002186, atol=1e-12
    )
    assert "Mirror evaluation" in (tmp_path / "ev" / "metrics.md").read_text()
    assert out.stdout.splitlines()[-1].endswith(
        ": metrics.json, metrics.md, episodes.csv.gz, episodes_mirror.csv.gz"
    )


def test_a_mirror_outside_the_episodes_played_is_refused_before_any_episode(tmp_path):
    out = subprocess.run(
        [sys.executable, str(ROOT / "evaluate.py"), "--controller", "stand_still", "--num-trajectories", "8",
         "--mirror", "9", "--out", str(tmp_path / "ev")],
        capture_output=True, text=True, cwd=tmp_path, timeout=120,
    )  # fmt: skip
    assert out.returncode == 2 and "--mirror must be in [1, 8]" in out.stderr
    assert not (tmp_path / "ev").exists()  # refused before any output


def _episodes(collided, causes):
    return {
        "collision": np.asarray(collided, dtype=float),
        "collision_cause": np.asarray(causes, dtype=object),
    }


def test_the_mirror_report_counts_overlap_and_relabels_the_twins_legs():
    original = _episodes([1, 1, 0, 1], ["RL_thigh", "trunk+FR_calf", "", "RL_calf+RL_thigh"])
    twins = _episodes([1, 0, 1, 1], ["RL_thigh", "", "FL_hip", "RR_thigh"])
    r = mirror_report(original, twins)
    assert r["failed_in_both"] == 2 and r["failure_overlap"] == pytest.approx(2 / 4)
    assert r["original_legs"] == {"FR": 1, "FL": 0, "RR": 0, "RL": 2}
    assert r["mirrored_legs"] == {"FR": 0, "FL": 1, "RR": 1, "RL": 1}
    assert r["mirrored_legs_as_original"] == {"FR": 1, "FL": 0, "RR": 1, "RL": 1}
    assert mirror_report(_episodes([0, 0], ["", ""]), _episodes([0, 0], ["", ""]))["failure_overlap"] == 1.0
    assert legs_in_cause(["below_top", "FL_hip+FR_hip"]).tolist() == [[False] * 4, [True, True, False, False]]


def test_the_stance_counts_four_foot_steps_and_the_longest_air_phase_open_ones_included():
    g = GaitTracker(2, dt_s=0.5)
    g.start(np.arange(2))
    down, fr_up = np.ones(4, bool), np.array([False, True, True, True])
    for contact in ([down, fr_up], [down, fr_up], [fr_up, fr_up], [down, fr_up]):
        g.step(np.array([True, True]), np.array(contact))
    closed = g.close(np.arange(2))
    assert closed["four_feet_share"].tolist() == [0.75, 0.0]
    assert closed["longest_air_s"].tolist() == [0.5, 2.0]  # env 1's foot is still up: 4 steps of 0.5 s
    summary = summarize_gait({"steps": np.array([3.0, 3.0]), **closed})
    assert summary["four_feet_step_share"] == pytest.approx(0.375)
    assert summary["episodes_with_foot_up_over_2s"] == 0.0  # 2.0 s is not more than 2 s


def test_metrics_md_puts_the_papers_row_beside_the_method_it_measured():
    from lasmp.eval.paper import paper_key, paper_row
    from lasmp.eval.report import markdown

    assert (
        paper_key(None, "LAS-MP checkpoint runs/x/model_449.pt (no_alignment_command)")
        == "no_alignment_command"
    )
    assert paper_key(None, "LAS-MP checkpoint runs/x/model_449.pt (my_variant)") is None
    metrics = {"collision_rate": {"mean": 0.1, "std": 0.01}, "power_w": {"mean": 2.0, "std": 0.1}}
    result = {
        "method": "m",
        "num_episodes": 10,
        "std_over": "10 batches",
        "metrics": metrics,
        "wall_time_s": 1.0,
    }
    text = markdown({**result, "paper": paper_row("stand_still")})
    assert "the paper's Stand Still" in text and "| collision rate | 0.1000 | 0.0100 | 0.612 ± 0.29 |" in text
    assert "paper" not in markdown(result)
