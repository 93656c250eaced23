"""Evaluation: metrics on constructed episodes, the benchmark loop's bookkeeping, evaluate.py."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from omegaconf import OmegaConf

from lasmp.envs import trajectories as trj
from lasmp.eval import benchmark as bm
from lasmp.eval.metrics import EpisodeMetrics, rotation_angle, summarize
from lasmp.eval.run import BenchmarkSource

ROOT = Path(__file__).resolve().parents[1]
H = 0.37


def rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def play(metrics, env, steps):
    """Feed (p, R, tau, q_dot, collision) per step to env `env` of a 2-env accumulator."""
    for p, r, tau, q_dot, col in steps:
        pp = np.zeros((2, 3))
        pp[:, 2] = H
        pp[env] = p
        rr = np.tile(np.eye(3), (2, 1, 1))
        rr[env] = r
        tt = np.zeros((2, 12))
        tt[env] = tau
        qq = np.zeros((2, 12))
        qq[env] = q_dot
        cc = np.zeros(2, bool)
        cc[env] = col
        metrics.step(np.array([True, True]), cc, pp, rr, tt, qq)


def test_collision_at_step_k_counts_violations_and_deviations_up_to_k_only():
    m = EpisodeMetrics(2, H)
    m.start(np.array([0, 1]), np.array([[0, 0, H]] * 2), np.tile(np.eye(3), (2, 1, 1)))
    ok = ([0.0, 0.0, H], np.eye(3), np.zeros(12), np.zeros(12), False)
    low = (
        [0.3, 0.4, H - 0.2],
        rot_z(0.5),
        np.full(12, 2.0),
        np.full(12, 1.0),
        False,
    )  # 0.2 m low: a violation
    crash = ([5.0, 5.0, -3.0], rot_z(3.0), np.full(12, 100.0), np.full(12, 100.0), True)
    after = ([9.0, 9.0, -9.0], rot_z(3.0), np.full(12, 100.0), np.full(12, 100.0), True)
    play(m, 0, [ok, low, ok, crash, after])  # collision at step k = 3: steps 0..2 count
    out = m.close(np.array([0]), np.array([True]))
    assert out["steps"][0] == 3
    assert out["collision"][0] == 1.0
    assert out["height_violation_rate"][0] == pytest.approx(1 / 3)
    assert out["position_deviation_m"][0] == pytest.approx(math.sqrt(0.3**2 + 0.4**2 + 0.2**2) / 3)
    assert out["rotation_deviation_rad"][0] == pytest.approx(0.5 / 3)
    assert out["power_w"][0] == pytest.approx(12 * 2.0 / 3)


def test_episode_without_collision_counts_its_full_length():
    m = EpisodeMetrics(2, H)
    m.start(np.array([0, 1]), np.array([[0, 0, H]] * 2), np.tile(np.eye(3), (2, 1, 1)))
    step = ([0.1, 0.0, H + 0.15], rot_z(0.2), np.full(12, -1.0), np.full(12, 1.0), False)  # negative power
    play(m, 1, [step] * 500)
    out = m.close(np.array([1]), np.array([False]))
    assert out["steps"][0] == 500 and out["collision"][0] == 0.0
    assert out["height_violation_rate"][0] == 1.0
    assert out["position_deviation_m"][0] == pytest.approx(math.hypot(0.1, 0.15))
    assert out["rotation_deviation_rad"][0] == pytest.approx(0.2)
    assert out["power_w"][0] == 0.0  # only positive mechanical power counts


def test_collision_on_the_first_step_counts_for_the_collision_rate_only():
    m = EpisodeMetrics(2, H)
    m.start(np.array([0, 1]), np.zeros((2, 3)), np.tile(np.eye(3), (2, 1, 1)))
    play(m, 0, [([0, 0, 0.0], np.eye(3), np.zeros(12), np.zeros(12), True)])
    out = m.close(np.array([0]), np.array([True]))
    assert out["steps"][0] == 0 and np.isnan(out["position_deviation_m"][0])
    summary = summarize({k: np.array([v[0], 0.0]) if k != "collision" else np.array([1.0, 0.0])
                         for k, v in out.items()}, num_batches=2)  # fmt: skip
    assert summary["collision_rate"]["mean"] == 0.5


def test_summary_std_is_over_batches():
    episodes = {k: np.array([0.0, 0.0, 1.0, 1.0]) for k in
                ("collision", "height_violation_rate", "position_deviation_m", "rotation_deviation_rad", "power_w")}  # fmt: skip
    s = summarize(episodes, num_batches=2)
    assert s["collision_rate"] == {"mean": 0.5, "std": 0.5}


def test_rotation_angle():
    a = np.stack([np.eye(3), rot_z(0.3)])
    b = np.stack([rot_z(1.0), rot_z(-0.2)])
    assert np.allclose(rotation_angle(a, b), [1.0, 0.5])


def test_benchmark_source_pairs_episodes_in_order_and_marks_the_rest_inactive():
    bench = bm.generate(num_trajectories=5, num_robots=2, seed=0)
    src = BenchmarkSource(bench, num_episodes=5, num_envs=3)
    traj, levels, robots = src.next_episodes(np.array([0, 1, 2]))
    assert src.episode_of_env.tolist() == [0, 1, 2]
    assert np.array_equal(robots.trunk_mass_kg, bench.robots.trunk_mass_kg[[0, 1, 0]])
    assert np.array_equal(levels, bench.trajectories.n_waypoints[:3])
    src.next_episodes(np.array([1, 2]))
    src.next_episodes(np.array([0]))
    assert src.episode_of_env.tolist() == [-1, 3, 4]  # episode 5 does not exist: env 0 is a filler
    with pytest.raises(ValueError, match="num_episodes"):
        BenchmarkSource(bench, num_episodes=6, num_envs=1)


def run_evaluate(*args, cwd):
    return subprocess.run([sys.executable, str(ROOT / "evaluate.py"), *args], capture_output=True, text=True,
                          cwd=cwd, timeout=600)  # fmt: skip


def test_evaluate_stand_still_end_to_end(tmp_path):
    bench_path = tmp_path / "bench.npz"
    bm.save(bench_path, bm.generate(num_trajectories=32, num_robots=8, seed=0))
    out = run_evaluate("--controller", "stand_still", "--num-trajectories", "16", "--benchmark", str(bench_path),
                       "--out", str(tmp_path / "ev"), cwd=tmp_path)  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    result = json.loads((tmp_path / "ev" / "metrics.json").read_text())
    assert result["num_episodes"] == 16
    for key in ("collision_rate", "height_violation_rate", "position_deviation_m", "rotation_deviation_rad",
                "power_w"):  # fmt: skip
        assert set(result["metrics"][key]) == {"mean", "std"}
    assert 0.0 <= result["metrics"]["collision_rate"]["mean"] <= 1.0
    assert result["metrics"]["power_w"]["mean"] > 0.0  # the PD does work against the platform's motion
    assert "| collision rate |" in (tmp_path / "ev" / "metrics.md").read_text()


def test_evaluate_refuses_a_malformed_trajectory_file(tmp_path):
    bench_path = tmp_path / "bench.npz"
    bm.save(bench_path, bm.generate(num_trajectories=4, num_robots=2, seed=0))
    bad = tmp_path / "bad.npz"
    np.savez(bad, format="lasmp-trajectories", version=1, kind="samples", t_s=np.array([0.0, 1.0, 0.5]),
             poses=np.zeros((1, 3, 6)))  # fmt: skip
    out = run_evaluate("--controller", "stand_still", "--benchmark", str(bench_path), "--trajectories", str(bad),
                       cwd=tmp_path)  # fmt: skip
    assert out.returncode == 2 and "bad.npz" in out.stderr and "Traceback" not in out.stderr
    with pytest.raises(trj.TrajectoryFileError):
        trj.load(bad)
    out = run_evaluate("--controller", "stand_still", "--benchmark", str(tmp_path / "none.npz"), cwd=tmp_path)
    assert out.returncode == 2 and "none.npz" in out.stderr


def test_oracle_command_points_to_the_platform_centre_in_the_heading_frame():
    from lasmp.envs.moving_platform.env import MovingPlatformEnv
    from lasmp.envs.moving_platform.readout import read
    from lasmp.eval.cli import oracle_command

    env = MovingPlatformEnv({"num_envs": 2, "domain_rand": {"enabled": False}})
    env.reset()
    ix = env.index
    yaw = math.pi / 2  # facing world +y
    quat = torch.tensor([math.cos(yaw / 2), 0, 0, math.sin(yaw / 2)])
    env.sim.qpos[:, ix.root_qpos + 3 : ix.root_qpos + 7] = quat
    env.sim.qpos[0, ix.root_qpos] = 0.5  # 0.5 m along world +x of the centre: the centre is on its left
    env.sim.qpos[1, ix.root_qpos] = 3.0  # far away: the command saturates
    env.sim.forward()
    env.readout = read(env.sim, ix)
    cmd = oracle_command(env).numpy()
    assert np.allclose(cmd[0], [0.0, 0.5, 0.0], atol=1e-6)
    assert np.allclose(cmd[1], [0.0, 1.0, 0.0], atol=1e-6)


def test_evaluate_rs_controllers_end_to_end(tmp_path):
    from lasmp.train import to_train_cfg, train

    cfg = to_train_cfg(OmegaConf.create({
        "task": "rough_static", "env": {"num_envs": 4}, "torch_threads": 1,
        "policy": {"name": "rs", "use_alignment": False, "explicit": "no_platform", "command_input": True,
                   "actor_hidden_dims": [32, 32, 32]},
        "runner": {"max_iterations": 1, "log_dir": str(tmp_path / "rs")},
    }))  # fmt: skip
    train(cfg)
    bench_path = tmp_path / "bench.npz"
    bm.save(bench_path, bm.generate(num_trajectories=8, num_robots=4, seed=0))
    for controller in ("rs", "rs_oracle"):
        out = run_evaluate("--controller", controller, "--checkpoint", str(tmp_path / "rs"), "--benchmark",
                           str(bench_path), "--num-trajectories", "4", "--out", str(tmp_path / controller),
                           cwd=tmp_path)  # fmt: skip
        assert out.returncode == 0, out.stderr[-2000:]
        assert json.loads((tmp_path / controller / "metrics.json").read_text())["num_episodes"] == 4
    # a LAS-MP evaluation refuses the R-S checkpoint with a clear message
    out = run_evaluate("--checkpoint", str(tmp_path / "rs"), "--benchmark", str(bench_path), cwd=tmp_path)
    assert out.returncode == 2 and "moving_platform" in out.stderr


def test_evaluate_lasmp_checkpoint_reports_estimator_accuracy_and_plots(tmp_path):
    from lasmp.train import to_train_cfg, train

    cfg = to_train_cfg(OmegaConf.create({
        "env": {"num_envs": 4}, "torch_threads": 1, "policy": {"actor_hidden_dims": [32, 32, 32]},
        "runner": {"max_iterations": 1, "log_dir": str(tmp_path / "mp")},
    }))  # fmt: skip
    train(cfg)
    bench_path = tmp_path / "bench.npz"
    bm.save(bench_path, bm.generate(num_trajectories=8, num_robots=4, seed=0))
    out = run_evaluate("--checkpoint", str(tmp_path / "mp"), "--benchmark", str(bench_path), "--num-trajectories",
                       "6", "--batch-envs", "3", "--plot-estimates", "--out", str(tmp_path / "ev"), cwd=tmp_path)  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    result = json.loads((tmp_path / "ev" / "metrics.json").read_text())
    est = result["estimator"]
    assert len(est["x_exp_mean_abs_error"]) == 13 and est["l_imp_mean_l2_error"] > 0
    assert est["samples"] >= 6
    assert (tmp_path / "ev" / "estimates.png").stat().st_size > 10_000
    assert 0 <= result["estimates_plot_episode"] < 3  # an episode of the first wave (3 envs)


def test_position_deviation_uses_the_frame_of_p_rel_and_height_the_platform_frame():
    """With p_rel given (e.g. the translating frame), the deviation follows it; the height stays in P."""
    m = EpisodeMetrics(2, H)
    m.start(np.array([0, 1]), np.zeros((2, 3)), np.tile(np.eye(3), (2, 1, 1)))
    p_body_p = np.array([[0.0, 0.0, H], [0.0, 0.0, H - 0.3]])  # env 1 is 0.3 m low in P
    p_rel = np.array([[0.3, 0.4, 0.0], [0.0, 0.0, 0.0]])  # env 0 moved 0.5 m in the other frame
    z = np.zeros((2, 12))
    m.step(np.array([True, True]), np.zeros(2, bool), p_body_p, np.tile(np.eye(3), (2, 1, 1)), z, z, p_rel)
    out = m.close(np.array([0, 1]), np.array([False, False]))
    np.testing.assert_allclose(out["position_deviation_m"], [0.5, 0.0])
    np.testing.assert_allclose(out["height_violation_rate"], [0.0, 1.0])


def test_relative_pose_frames():
    from types import SimpleNamespace

    from lasmp.eval.run import relative_pose

    rot = rot_z(0.7)[None]
    r = SimpleNamespace(p_body_p=np.array([[0.2, 0.0, 0.47]]), p_body_w=np.array([[1.0, 2.0, 3.5]]),
                        p_plf_w=np.array([[1.0, 1.8, 3.0]]), r_wp=rot, r_wb=rot)  # fmt: skip
    p, r_pb = relative_pose(r, "platform")
    np.testing.assert_allclose(p, r.p_body_p)
    np.testing.assert_allclose(r_pb[0], np.eye(3), atol=1e-12)  # trunk aligned with the platform
    p, _ = relative_pose(r, "translating")
    np.testing.assert_allclose(p, [[0.0, 0.2, 0.5]])
    with pytest.raises(ValueError, match="unknown position frame 'world'"):
        relative_pose(r, "world")


def test_shrinking_the_tail_steps_only_playing_envs_and_changes_no_episode():
    import torch

    from lasmp.envs.moving_platform.env import MovingPlatformEnv
    from lasmp.eval.cli import eval_env_overrides
    from lasmp.eval.run import run_benchmark

    bench = bm.generate(num_trajectories=10, num_robots=4, seed=0)
    results, stepped = {}, {}
    for shrink in (False, True):
        env = MovingPlatformEnv({**eval_env_overrides(4, 0), "trajectory": {"split": "test", "duration_s": 2.0}})
        zeros = torch.zeros(4, 12)
        results[shrink] = run_benchmark(env, lambda obs, zeros=zeros: zeros, bench, 10, progress=False, shrink_tail=shrink)
        stepped[shrink] = env.sim.env_steps
        assert env.stepped_envs is None  # the hook is cleared after the run
    for key, value in results[False]["episodes"].items():
        np.testing.assert_array_equal(results[True]["episodes"][key], value, err_msg=key)
    # 10 episodes on 4 envs: the third wave has 2 episodes, so the tail steps fewer envs
    assert stepped[True] < stepped[False]


def test_results_table_rows_and_refusals(tmp_path, capsys):
    from lasmp.eval import results_table as rt
    from lasmp.eval.metrics import METRICS

    def write(name, collision, estimator=None, episodes=100):
        d = tmp_path / name
        d.mkdir()
        metrics = {k: {"mean": 0.5, "std": 0.01} for k in METRICS}
        metrics["collision_rate"] = {"mean": collision, "std": 0.02}
        result = {"method": name, "benchmark": "b.npz", "num_episodes": episodes, "metrics": metrics}
        if estimator:
            result["estimator"] = estimator
        (d / "metrics.json").write_text(json.dumps(result))
        return d

    est = {"x_exp_mean_abs_error": {"contact_FR": 0.1, "v_body_x": 0.2}, "l_imp_mean_l2_error": 0.3}
    dirs = [write("ss", 0.65), write("lasmp", 0.25, est), write("noexp", 0.3, {"x_exp_mean_abs_error": {},
                                                                             "l_imp_mean_l2_error": 0.4})]  # fmt: skip
    rt.main([str(d) for d in dirs] + ["--labels", "Stand Still", "LAS-MP", "no explicit"])
    out = capsys.readouterr().out
    assert "| Stand Still | 0.650 ± 0.020 |" in out and "| LAS-MP | 0.250 ± 0.020 |" in out
    assert "| LAS-MP | 0.100 | 0.200 | 0.300 |" in out  # the estimator table: only methods that estimate
    assert "| no explicit |  |  | 0.400 |" in out and "| Stand Still | 0.650" in out.split("Estimator")[0]
    with pytest.raises(ValueError, match="different benchmarks or episode counts"):
        rt.load_results([dirs[0], write("short", 0.5, episodes=10)])
    with pytest.raises(FileNotFoundError, match="run `python evaluate.py"):
        rt.load_results([tmp_path / "missing"])
    with pytest.raises(ValueError, match="2 labels for 1 results"):
        rt.load_results([dirs[0]], ["a", "b"])


def test_evaluate_refuses_a_thread_count_below_one(capsys):
    from lasmp.eval import cli

    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--controller", "stand_still", "--torch-threads", "0"])
    assert exit_info.value.code == 2 and "--torch-threads must be >= 1, got 0" in capsys.readouterr().err
