"""Command-line entry points, end to end at tiny sizes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_env_throughput_bench_prints_one_json_object(tmp_path):
    out = subprocess.run(
        [sys.executable, str(ROOT / "bench" / "env_throughput.py"), "--num-envs", "8", "--steps", "30", "--json"],
        capture_output=True, text=True, check=True, cwd=tmp_path, timeout=300,
    )  # fmt: skip
    result = json.loads(out.stdout)
    for key in (
        "env_steps_per_s",
        "raw_steps_per_s",
        "ratio",
        "stand_still_collision_rate",
        "env_physics_share",
    ):
        assert key in result, key
    assert result["env_steps_per_s"] > 0 and result["raw_steps_per_s"] > 0
    assert abs(result["ratio"] - result["env_steps_per_s"] / result["raw_steps_per_s"]) < 1e-2


def test_train_iteration_bench_prints_the_time_breakdown(tmp_path):
    out = subprocess.run(
        [sys.executable, str(ROOT / "bench" / "train_iteration.py"), "--num-envs", "8", "--iterations", "1",
         "--json", "torch_threads=1", "policy.actor_hidden_dims=[32,32,32]"],
        capture_output=True, text=True, check=True, cwd=tmp_path, timeout=300,
    )  # fmt: skip
    result = json.loads(out.stdout)  # --json: one JSON object and nothing else
    parts = ("physics_s", "policy_inference_s", "env_other_s", "update_ppo_s", "update_roa_s")
    assert all(result[k] >= 0 for k in parts)
    assert result["physics_s"] > 0 and result["update_ppo_s"] > 0 and result["update_roa_s"] > 0
    assert sum(result[k] for k in parts) <= result["s_per_iteration"] * 1.05
    assert result["policy_steps_per_s"] > 0
