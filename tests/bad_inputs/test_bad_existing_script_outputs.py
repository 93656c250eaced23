"""Files the user already has, the scripts' share: each script that writes a file
the user names (--out, --json) claims it before its minutes of play (`lasmp.io.atomic.claim_output`), so
an existing file is refused without --force (exit code != 0, one line naming it, no traceback, its
bytes unchanged) and replaced with it; a Ctrl-C during the play leaves no empty file. The play itself
(minutes of MuJoCo) is replaced here by a stand-in of a few lines: what is tested is the file's
claim and write. Scripts covered: tilt_probe.py --json, curriculum_probe.py --json,
apparent_vertical_stats.py --out, level_acceleration_estimates.py --out DIR (estimates.json and
estimates.png); test_bad_existing_outputs.py covers the entry points and tools."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from badkit import ROOT, call, refused, succeeded
from testkit import load_script

import lasmp.eval.build as eval_build
from lasmp.eval import platform_probe as pp
from lasmp.io.atomic import atomic_open

USER_DATA = b"user data\n"
POLICY = str(ROOT / "resources" / "policies" / "lasmp_a1.pt")

tilt = load_script("scripts/tilt_probe.py")
curriculum = load_script("scripts/curriculum_probe.py")
vertical = load_script("scripts/apparent_vertical_stats.py")
estimates = load_script("scripts/level_acceleration_estimates.py")


def _fake_deploy_env(*args, **kwargs):
    """What curriculum_probe reads of load_deploy_env's env, policy, cfg and data."""
    dist = SimpleNamespace(update=lambda mean: None, std=torch.ones(1, 2))
    env = SimpleNamespace(num_envs=2, curriculum=None, max_episode_length=3)
    return env, SimpleNamespace(distribution=dist), SimpleNamespace(seed=0), {"num_actions": 2}


def _fake_plot(summary, path):
    with atomic_open(path) as f:
        f.write(b"\x89PNG a figure")


@pytest.fixture(autouse=True)
def stand_ins(monkeypatch):
    """The scripts' plays replaced by stand-ins that return at once (the benchmark, the rollouts)."""
    monkeypatch.setattr(
        eval_build, "load_or_make_benchmark", lambda path: SimpleNamespace(num_trajectories=4)
    )
    monkeypatch.setattr(tilt, "load_or_make_benchmark", lambda path: None)
    monkeypatch.setattr(tilt, "play", lambda checkpoint, episodes, bench: ({}, 0.02))
    monkeypatch.setattr(tilt, "tilt_split", lambda **arrays: {})
    monkeypatch.setattr(tilt, "summary", lambda split: {"lean": 0.1})
    monkeypatch.setattr(curriculum, "load_deploy_env", _fake_deploy_env)
    outcome = {"success_rate": 1.0, "stderr": 0.0, "episodes": 2, "mean_failure_step": None}
    monkeypatch.setattr(curriculum, "first_episodes", lambda env, act, steps: outcome)
    monkeypatch.setattr(pp, "probe_platform", lambda *args, **kwargs: {"tilt": np.array([0.1])})
    monkeypatch.setattr(vertical, "probe_motion_stats", lambda dt: {})
    monkeypatch.setattr(vertical, "table", lambda xi, probe: "a table")
    monkeypatch.setattr(estimates, "record", lambda args, bench: (None, None, 0.02, []))
    monkeypatch.setattr(estimates, "summarize", lambda *args: {"motions": {}})
    monkeypatch.setattr(estimates, "plot", _fake_plot)


# script: (its main, its argv writing `out`, the output's name, the option naming it, the work a Ctrl-C stops)
SCRIPTS = {
    "tilt_probe --json": (
        tilt,
        lambda out: [POLICY, "--episodes", "2", "--json", str(out)],
        "tilt.json",
        "--json",
        (tilt, "play"),
    ),
    "curriculum_probe --json": (
        curriculum,
        lambda out: [POLICY, "--envs", "2", "--json", str(out)],
        "probe.json",
        "--json",
        (curriculum, "first_episodes"),
    ),
    "apparent_vertical_stats --out": (
        vertical,
        lambda out: ["--episodes", "2", "--batch-envs", "2", "--out", str(out)],
        "vertical.json",
        "--out",
        (pp, "probe_platform"),
    ),
    "level_acceleration_estimates --out DIR": (
        estimates,
        lambda out: ["--checkpoint", POLICY, "--out", str(out.parent)],
        "estimates.json",
        "--out",
        (estimates, "record"),
    ),
}


def _run(script: str, out: Path, *force: str):
    module, argv = SCRIPTS[script][:2]
    return call(module.main, [*argv(out), *force])


@pytest.mark.parametrize("script", list(SCRIPTS))
def test_a_script_keeps_a_file_the_user_already_has_unless_forced(script, tmp_path):
    name, option = SCRIPTS[script][2:4]
    out = tmp_path / name
    out.write_bytes(USER_DATA)
    refused_run = _run(script, out)
    refused(refused_run, "already exists", "--force")
    naming = [line for line in refused_run.text.splitlines() if str(out) in line]
    assert len(naming) == 1 and option in naming[0], refused_run.text
    assert out.read_bytes() == USER_DATA
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]  # no claim, temporary or figure left
    succeeded(_run(script, out, "--force"))
    assert out.read_bytes() != USER_DATA and out.stat().st_size > 0


@pytest.mark.parametrize("script", list(SCRIPTS))
def test_a_ctrl_c_during_a_scripts_play_leaves_no_empty_file_behind(script, tmp_path, monkeypatch):
    name, (module, attr) = SCRIPTS[script][2], SCRIPTS[script][4]
    out = tmp_path / "new" / name

    def interrupted(*args, **kwargs):
        assert out.exists() and out.stat().st_size == 0  # claimed before the work
        raise KeyboardInterrupt

    monkeypatch.setattr(module, attr, interrupted)
    with pytest.raises(KeyboardInterrupt):
        _run(script, out)
    assert not out.exists() and not out.parent.exists()
