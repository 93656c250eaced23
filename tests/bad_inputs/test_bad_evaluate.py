"""evaluate.py (`lasmp.eval.cli.main`): a bad benchmark robot, checkpoint or trajectory file, and an
output path it must not write or overwrite."""

from __future__ import annotations

import json
import re
import time

import pytest
from badkit import _bench_case, _pose_far, _scale, _traj_case, _truncated, evaluate, refused, stand_still
from testkit import hostile_checkpoint


# -- evaluation inputs and outputs ---------------------------------------------------------------
def test_evaluate_refuses_a_benchmark_robot_with_negative_friction_before_playing(tmp_path):
    bench = _bench_case(_scale("robot_foot_friction", -1.0))(tmp_path / "bench.npz")
    out = stand_still(bench, tmp_path / "eval", probe=True)
    refused(out, "robot_foot_friction")
    assert not (tmp_path / "eval").exists()  # no results of NaN, not even an empty directory


@pytest.mark.parametrize("case", ["a missing checkpoint", "a truncated checkpoint", "a hostile checkpoint"])
def test_evaluate_refuses_a_bad_checkpoint_with_one_message(base_run, tmp_path, case):
    path = {
        "a missing checkpoint": lambda: tmp_path / "nope.pt",
        "a truncated checkpoint": lambda: _truncated(base_run / "model_1.pt", tmp_path / "t.pt"),
        "a hostile checkpoint": lambda: hostile_checkpoint(tmp_path / "h.pt", tmp_path / "marker"),
    }[case]()
    bench = _bench_case(lambda a: None)(tmp_path / "bench.npz")
    out = evaluate(
        "--checkpoint",
        str(path),
        "--benchmark",
        str(bench),
        "--num-trajectories",
        "1",
        "--out",
        str(tmp_path / "eval"),
    )
    refused(out, re.escape(path.name))
    assert not (tmp_path / "marker").exists() and not (tmp_path / "eval").exists()


def test_evaluate_refuses_a_bad_trajectory_file_with_one_message(tmp_path):
    bench = _bench_case(lambda a: None)(tmp_path / "bench.npz")
    traj = _traj_case("samples", _pose_far)(tmp_path / "traj.npz")
    out = stand_still(bench, tmp_path / "eval", "--trajectories", str(traj), probe=True)
    refused(out, "traj.npz", "physical range")


def test_evaluate_refuses_an_output_path_that_is_a_file_before_playing(tmp_path):
    bench = _bench_case(lambda a: None)(tmp_path / "bench.npz")
    (tmp_path / "eval").write_text("mine")
    started = time.monotonic()
    out = stand_still(bench, tmp_path / "eval", probe=True)
    refused(out, "eval")
    assert (tmp_path / "eval").read_text() == "mine"
    assert time.monotonic() - started < 20  # before the episode, not after it


def test_evaluate_never_overwrites_an_earlier_result_silently(tmp_path):
    bench = _bench_case(lambda a: None)(tmp_path / "bench.npz")
    earlier = tmp_path / "eval"
    earlier.mkdir()
    (earlier / "metrics.json").write_text(json.dumps({"method": "earlier"}))
    out = stand_still(bench, earlier, probe=True)
    assert (earlier / "metrics.json").read_text() == json.dumps({"method": "earlier"})
    if out.code != 0:
        refused(out, "metrics.json|eval")
