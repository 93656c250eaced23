"""The real train.py command line at a tiny size: a run end to end, then its resume, then a resume
from a missing checkpoint refused."""

from __future__ import annotations

import os
import subprocess
import sys

from omegaconf import OmegaConf
from testkit import ROOT

from lasmp.algo.checkpoint import read_checkpoint


def run_cli(*args, cwd):
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.run(
        [sys.executable, str(ROOT / "train.py"), *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=env,
        timeout=600,
    )


def test_train_cli_end_to_end_then_resume(tmp_path):
    common = ["env.num_envs=8", "torch_threads=1", "policy.actor_hidden_dims=[32,32,32]"]
    out = run_cli(*common, "runner.max_iterations=2", f"runner.log_dir={tmp_path / 'run'}", cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    lines = [line for line in out.stdout.splitlines() if line.startswith("it ")]
    assert len(lines) == 2 and "steps/s" in lines[0] and "ETA" in lines[0]
    run = tmp_path / "run"
    assert (run / "config.yaml").exists() and (run / "model_1.pt").exists()
    assert any(p.name.startswith("events.out.tfevents") for p in run.iterdir())
    assert OmegaConf.load(run / "config.yaml").env.num_envs == 8

    out = run_cli(
        *common,
        "runner.max_iterations=1",
        f"resume={run}",
        f"runner.log_dir={tmp_path / 'run2'}",
        cwd=tmp_path,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert "at iteration 2" in out.stdout
    assert [line.split("|")[0].strip() for line in out.stdout.splitlines() if line.startswith("it ")] == [
        "it 2/2"
    ]
    assert read_checkpoint(tmp_path / "run2")["iter"] == 2

    out = run_cli(*common, f"resume={tmp_path / 'nope.pt'}", cwd=tmp_path)
    assert out.returncode != 0 and "nope.pt does not exist" in out.stderr
