"""evaluate.py run end to end on each controller (stand still, R-S and its oracle, a LAS-MP
checkpoint with its estimator report), the oracle's command, and the inputs it refuses (a malformed
trajectory file, a missing benchmark, a thread count below one)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from omegaconf import OmegaConf
from testkit import run_script

from lasmp.envs import trajectories as trj
from lasmp.eval import benchmark as bm
from lasmp.eval import episodes as ep
from lasmp.eval.metrics import ALL_METRICS


def run_evaluate(*args, cwd):
    """evaluate.py run as a user runs it; its exit status is the test's to check."""
    return run_script("evaluate.py", *args, cwd=cwd, ok=False)


def test_evaluate_stand_still_end_to_end(tmp_path):
    bench_path = tmp_path / "bench.npz"
    bm.save(bench_path, bm.generate(num_trajectories=32, num_robots=8, seed=0))
    out = run_evaluate(
        "--controller",
        "stand_still",
        "--num-trajectories",
        "16",
        "--benchmark",
        str(bench_path),
        "--out",
        str(tmp_path / "ev"),
        cwd=tmp_path,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    result = json.loads((tmp_path / "ev" / "metrics.json").read_text())
    assert result["num_episodes"] == 16
    # what it was measured with: the seed, the benchmark file's hash, no checkpoint
    assert result["seed"] == 0 and result["benchmark_sha256"] == sha256(bench_path)
    assert result["checkpoint"] is None and result["checkpoint_sha256"] is None
    for key in (
        "collision_rate",
        "height_violation_rate",
        "position_deviation_m",
        "rotation_deviation_rad",
        "power_w",
    ):
        assert set(result["metrics"][key]) == {"mean", "std"}
    assert 0.0 <= result["metrics"]["collision_rate"]["mean"] <= 1.0
    assert result["metrics"]["power_w"]["mean"] > 0.0  # the PD does work against the platform's motion
    assert set(result["metrics"]) == set(ALL_METRICS) and result["h_des_p_m"] == pytest.approx(0.47)
    assert "| collision rate |" in (tmp_path / "ev" / "metrics.md").read_text()
    rows = ep.read_csv(tmp_path / "ev" / ep.EPISODES_FILE)  # one row per episode, in benchmark order
    np.testing.assert_array_equal(rows["episode"], np.arange(16))
    assert set(np.unique(rows["collided"])) <= {0.0, 1.0}
    collided = rows["collided"] > 0
    assert np.all(np.isfinite(rows["collision_time_s"][collided])) and np.all(
        rows["collision_time_s"][collided] <= 10
    )
    assert all(c for c in rows["collision_cause"][collided]) and not any(rows["collision_cause"][~collided])
    assert np.all(np.isfinite(rows["platform_tilt_max_rad"])) and set(np.unique(rows["forced"])) <= {0.0, 1.0}
    assert result["forced_episodes"] == int(rows["forced"].sum())


def sha256(path) -> str:
    import hashlib

    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def test_evaluate_rs_controllers_end_to_end(tmp_path):
    from lasmp.cli.train import train
    from lasmp.config.train import to_train_cfg

    cfg = to_train_cfg(
        OmegaConf.create(
            {
                "task": "rough_static",
                "env": {"num_envs": 4},
                "torch_threads": 1,
                "policy": {
                    "name": "rs",
                    "use_alignment": False,
                    "explicit": "no_platform",
                    "command_input": True,
                    "actor_hidden_dims": [32, 32, 32],
                },
                "runner": {"max_iterations": 1, "log_dir": str(tmp_path / "rs")},
            }
        )
    )
    train(cfg)
    bench_path = tmp_path / "bench.npz"
    bm.save(bench_path, bm.generate(num_trajectories=8, num_robots=4, seed=0))
    for controller in ("rs", "rs_oracle"):
        out = run_evaluate(
            "--controller",
            controller,
            "--checkpoint",
            str(tmp_path / "rs"),
            "--benchmark",
            str(bench_path),
            "--num-trajectories",
            "4",
            "--out",
            str(tmp_path / controller),
            cwd=tmp_path,
        )
        assert out.returncode == 0, out.stderr[-2000:]
        assert json.loads((tmp_path / controller / "metrics.json").read_text())["num_episodes"] == 4
    # a LAS-MP evaluation refuses the R-S checkpoint with a clear message
    out = run_evaluate("--checkpoint", str(tmp_path / "rs"), "--benchmark", str(bench_path), cwd=tmp_path)
    assert out.returncode == 2 and "moving_platform" in out.stderr


def test_evaluate_lasmp_checkpoint_reports_estimator_accuracy_and_plots(tmp_path):
    from lasmp.cli.train import train
    from lasmp.config.train import to_train_cfg

    cfg = to_train_cfg(
        OmegaConf.create(
            {
                "env": {"num_envs": 4},
                "torch_threads": 1,
                "policy": {"actor_hidden_dims": [32, 32, 32]},
                "runner": {"max_iterations": 1, "log_dir": str(tmp_path / "mp")},
            }
        )
    )
    train(cfg)
    bench_path = tmp_path / "bench.npz"
    bm.save(bench_path, bm.generate(num_trajectories=8, num_robots=4, seed=0))
    out = run_evaluate(
        "--checkpoint",
        str(tmp_path / "mp"),
        "--benchmark",
        str(bench_path),
        "--num-trajectories",
        "6",
        "--batch-envs",
        "3",
        "--plot-estimates",
        "--out",
        str(tmp_path / "ev"),
        cwd=tmp_path,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    result = json.loads((tmp_path / "ev" / "metrics.json").read_text())
    from lasmp.algo.checkpoint import latest_checkpoint

    latest = latest_checkpoint(tmp_path / "mp")  # the run directory's latest checkpoint: the file evaluated
    assert result["checkpoint"] == str(latest) and result["checkpoint_sha256"] == sha256(latest)
    assert result["benchmark_sha256"] == sha256(bench_path) and result["seed"] == 0
    est = result["estimator"]
    assert len(est["x_exp_mean_abs_error"]) == 13 and est["l_imp_mean_l2_error"] > 0
    assert est["samples"] >= 6
    assert (tmp_path / "ev" / "estimates.png").stat().st_size > 10_000
    assert 0 <= result["estimates_plot_episode"] < 3  # an episode of the first wave (3 envs)


def test_oracle_command_points_to_the_platform_centre_in_the_heading_frame():
    from lasmp.config.base import build_env_cfg
    from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
    from lasmp.envs.moving_platform.env import MovingPlatformEnv
    from lasmp.envs.moving_platform.readout import read_scene
    from lasmp.eval.build import oracle_command

    env = MovingPlatformEnv(
        build_env_cfg({"num_envs": 2, "domain_rand": {"enabled": False}}, schema=MovingPlatformCfg)
    )
    env.reset()
    ix = env.index
    yaw = math.pi / 2  # facing world +y
    quat = torch.tensor([math.cos(yaw / 2), 0, 0, math.sin(yaw / 2)])
    env.sim.qpos[:, ix.root_qpos + 3 : ix.root_qpos + 7] = quat
    env.sim.qpos[0, ix.root_qpos] = 0.5  # 0.5 m along world +x of the centre: the centre is on its left
    env.sim.qpos[1, ix.root_qpos] = 3.0  # far away: the command saturates
    env.sim.forward()
    env.readout = read_scene(env.sim, ix)
    cmd = oracle_command(env).numpy()
    assert np.allclose(cmd[0], [0.0, 0.5, 0.0], atol=1e-6)
    assert np.allclose(cmd[1], [0.0, 1.0, 0.0], atol=1e-6)


def test_evaluate_refuses_a_malformed_trajectory_file(tmp_path):
    bench_path = tmp_path / "bench.npz"
    bm.save(bench_path, bm.generate(num_trajectories=4, num_robots=2, seed=0))
    bad = tmp_path / "bad.npz"
    np.savez(
        bad,
        format="lasmp-trajectories",
        version=1,
        kind="samples",
        t_s=np.array([0.0, 1.0, 0.5]),
        poses=np.zeros((1, 3, 6)),
    )
    out = run_evaluate(
        "--controller",
        "stand_still",
        "--benchmark",
        str(bench_path),
        "--trajectories",
        str(bad),
        cwd=tmp_path,
    )
    assert out.returncode == 2 and "bad.npz" in out.stderr and "Traceback" not in out.stderr
    with pytest.raises(trj.TrajectoryFileError):
        trj.load(bad)
    out = run_evaluate("--controller", "stand_still", "--benchmark", str(tmp_path / "none.npz"), cwd=tmp_path)
    assert out.returncode == 2 and "none.npz" in out.stderr


def test_evaluate_refuses_a_thread_count_below_one(capsys):
    from lasmp.eval import cli

    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--controller", "stand_still", "--torch-threads", "0"])
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and "--torch-threads: must be an integer >= 1, got '0'" in err
