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
from lasmp.eval import episodes as ep
from lasmp.eval.metrics import ALL_METRICS, EpisodeMetrics, TrunkPose, rotation_angle, summarize
from lasmp.eval.run import BenchmarkSource

ROOT = Path(__file__).resolve().parents[2]
H = 0.37


def rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_x(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def pose(p_body_p, r_wb=None, r_wp=None, p_body_t=None) -> TrunkPose:
    """A TrunkPose of n envs from per-env (3,) / (3, 3) lists (identity rotations by default;
    the translating-frame position defaults to the platform-frame one)."""
    p = np.atleast_2d(np.asarray(p_body_p, dtype=float))
    n = len(p)
    eye = np.tile(np.eye(3), (n, 1, 1))
    r_wb = eye if r_wb is None else np.asarray(r_wb, dtype=float).reshape(n, 3, 3)
    r_wp = eye if r_wp is None else np.asarray(r_wp, dtype=float).reshape(n, 3, 3)
    p_t = p if p_body_t is None else np.atleast_2d(np.asarray(p_body_t, dtype=float))
    return TrunkPose(p, p_t, r_wb, r_wp)


def play(metrics, env, steps):
    """Feed (p_body_p, R_pb, tau, q_dot, collision) per step to env `env` of a 2-env accumulator; the
    platform stays level (R_wp = I), so R_wb = R_pb."""
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
        metrics.step(np.array([True, True]), cc, pose(pp, rr), tt, qq)


def start_level(m, p=((0.0, 0.0, H), (0.0, 0.0, H))):
    m.start(np.array([0, 1]), pose(p))


def test_collision_at_step_k_counts_violations_and_deviations_up_to_k_only():
    m = EpisodeMetrics(2, H)
    start_level(m)
    ok = ([0.0, 0.0, H], np.eye(3), np.zeros(12), np.zeros(12), False)
    # 0.2 m low: a violation
    low = ([0.3, 0.4, H - 0.2], rot_z(0.5), np.full(12, 2.0), np.full(12, 1.0), False)
    crash = ([5.0, 5.0, -3.0], rot_z(3.0), np.full(12, 100.0), np.full(12, 100.0), True)
    after = ([9.0, 9.0, -9.0], rot_z(3.0), np.full(12, 100.0), np.full(12, 100.0), True)
    play(m, 0, [ok, low, ok, crash, after])  # collision at step k = 3: steps 0..2 count
    out = m.close(np.array([0]), np.array([True]))
    assert out["steps"][0] == 3
    assert out["collision"][0] == 1.0
    assert out["height_violation_rate"][0] == pytest.approx(1 / 3)
    assert out["position_deviation_m"][0] == pytest.approx(math.sqrt(0.3**2 + 0.4**2 + 0.2**2) / 3)
    assert out["position_deviation_translating_m"][0] == pytest.approx(
        math.sqrt(0.3**2 + 0.4**2 + 0.2**2) / 3
    )
    assert out["rotation_deviation_platform_rad"][0] == pytest.approx(0.5 / 3)
    assert out["rotation_deviation_rad"][0] == pytest.approx(0.0)  # a turn about the vertical: no tilt
    assert out["power_w"][0] == pytest.approx(12 * 2.0 / 3)


def test_episode_without_collision_counts_its_full_length():
    m = EpisodeMetrics(2, H)
    start_level(m)
    step = ([0.1, 0.0, H + 0.15], rot_x(0.2), np.full(12, -1.0), np.full(12, 1.0), False)  # negative power
    play(m, 1, [step] * 500)
    out = m.close(np.array([1]), np.array([False]))
    assert out["steps"][0] == 500 and out["collision"][0] == 0.0
    assert out["height_violation_rate"][0] == 1.0
    assert out["position_deviation_m"][0] == pytest.approx(math.hypot(0.1, 0.15))
    assert out["rotation_deviation_rad"][0] == pytest.approx(0.2)  # a roll on a level platform: both readings
    assert out["rotation_deviation_platform_rad"][0] == pytest.approx(0.2)
    assert out["power_w"][0] == 0.0  # only positive mechanical power counts


def test_collision_on_the_first_step_counts_for_the_collision_rate_only():
    m = EpisodeMetrics(2, H)
    start_level(m, np.zeros((2, 3)))
    play(m, 0, [([0, 0, 0.0], np.eye(3), np.zeros(12), np.zeros(12), True)])
    out = m.close(np.array([0]), np.array([True]))
    assert out["steps"][0] == 0 and np.isnan(out["position_deviation_m"][0])
    summary = summarize(
        {k: np.array([v[0], 0.0]) if k != "collision" else np.array([1.0, 0.0]) for k, v in out.items()},
        num_batches=2,
    )
    assert summary["collision_rate"]["mean"] == 0.5


def test_summary_std_is_over_batches():
    episodes = {
        k: np.array([0.0, 0.0, 1.0, 1.0])
        for k in (
            "collision",
            "height_violation_rate",
            "position_deviation_m",
            "rotation_deviation_rad",
            "power_w",
            "position_deviation_translating_m",
            "rotation_deviation_platform_rad",
        )
    }
    s = summarize(episodes, num_batches=2)
    assert s["collision_rate"] == {"mean": 0.5, "std": 0.5}
    assert set(s) == {
        "collision_rate",
        "height_violation_rate",
        "position_deviation_m",
        "rotation_deviation_rad",
        "power_w",
    }  # the paper's five by default
    assert set(summarize(episodes, 2, ALL_METRICS)) == set(ALL_METRICS)


def test_rotation_angle():
    a = np.stack([np.eye(3), rot_z(0.3)])
    b = np.stack([rot_z(1.0), rot_z(-0.2)])
    assert np.allclose(rotation_angle(a, b), [1.0, 0.5])


def test_benchmark_source_pairs_episodes_in_order_and_marks_the_rest_inactive():
    bench = bm.generate(num_trajectories=5, num_robots=2, seed=0)
    src = BenchmarkSource(bench, num_episodes=5, num_envs=3)
    traj, levels, robots, pose = src.next_episodes(np.array([0, 1, 2]))
    assert src.episode_of_env.tolist() == [0, 1, 2]
    assert np.array_equal(robots.trunk_mass_kg, bench.robots.trunk_mass_kg[[0, 1, 0]])
    assert np.array_equal(levels, bench.trajectories.n_waypoints[:3])
    src.next_episodes(np.array([1, 2]))
    src.next_episodes(np.array([0]))
    assert src.episode_of_env.tolist() == [-1, 3, 4]  # episode 5 does not exist: env 0 is a filler
    with pytest.raises(ValueError, match="num_episodes"):
        BenchmarkSource(bench, num_episodes=6, num_envs=1)
    np.testing.assert_array_equal(pose, bench.initial_pose_draws([0, 1, 2]))


def test_each_benchmark_episode_has_its_own_initial_pose_draws_whatever_the_set_size():
    bench = bm.generate(num_trajectories=6, num_robots=2, seed=0)
    draws = bench.initial_pose_draws(np.arange(6))
    assert draws.shape == (6, 3) and np.all((draws >= 0) & (draws < 1))
    assert len(np.unique(draws[:, 0])) == 6  # not one draw shared by the robots' rows
    np.testing.assert_array_equal(bench.subset(3).initial_pose_draws([2, 0]), draws[[2, 0]])
    other_seed = bm.generate(num_trajectories=6, num_robots=2, seed=1)
    assert not np.array_equal(other_seed.initial_pose_draws([0]), draws[:1])


def test_an_episode_starts_at_the_same_heading_whichever_env_plays_it_and_whatever_played_before():
    """play.py --benchmark-episode k must show the robot as the evaluation met it: episode 3 played
    by env 0 after a fresh start and by env 1 after episodes 0..2 starts at one heading."""
    from lasmp.config import build_env_cfg
    from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
    from lasmp.envs.moving_platform.env import MovingPlatformEnv

    bench = bm.generate(num_trajectories=6, num_robots=2, seed=0)
    yaw = {}
    for first, num_envs in ((0, 4), (3, 2)):
        env = MovingPlatformEnv(build_env_cfg({"num_envs": num_envs}, schema=MovingPlatformCfg))
        env.reset()  # a training reset first: it consumes the env's own random stream
        source = BenchmarkSource(bench, 6, num_envs)
        source.next_episode = first
        env.episode_source = source
        env.reset()
        for k, y in zip(source.episode_of_env, env.readout.phi_body_w[:, 2].tolist(), strict=True):
            yaw.setdefault(int(k), []).append(y)
    assert yaw[3][0] == pytest.approx(yaw[3][1], abs=1e-6)  # env 3 of 4, then env 0 of 2
    lo, hi = MovingPlatformCfg().init_state.yaw_range_rad
    expected = lo + (hi - lo) * bench.initial_pose_draws([0, 1, 2, 3, 4])[:, 0]
    got = [yaw[k][0] for k in range(5)]
    np.testing.assert_allclose(np.angle(np.exp(1j * (np.array(got) - expected))), 0.0, atol=1e-6)


def run_evaluate(*args, cwd):
    return subprocess.run(
        [sys.executable, str(ROOT / "evaluate.py"), *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
    )


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


def strict_load(path):
    """JSON that a strict reader accepts: NaN or Infinity fail the test."""
    return json.loads(Path(path).read_text(), parse_constant=lambda c: pytest.fail(f"{path}: non-strict {c}"))


def tiny_benchmark(tmp_path):
    path = tmp_path / "bench.npz"
    bm.save(path, bm.generate(num_trajectories=4, num_robots=2, seed=0))
    return path


STAND_STILL_2 = ("--controller", "stand_still", "--num-trajectories", "2", "--batch-envs", "2")


def test_evaluate_refuses_an_earlier_result_before_playing_unless_forced(tmp_path):
    bench = tiny_benchmark(tmp_path)
    out_dir = tmp_path / "ev"
    out_dir.mkdir()
    (out_dir / "metrics.json").write_text('{"earlier": true}')
    out = run_evaluate(*STAND_STILL_2, "--benchmark", str(bench), "--out", str(out_dir), cwd=tmp_path)
    assert out.returncode == 2 and f"{out_dir / 'metrics.json'} already exists" in out.stderr
    assert "--force" in out.stderr and "episodes" not in out.stderr  # refused before any episode
    assert json.loads((out_dir / "metrics.json").read_text()) == {"earlier": True}
    out = run_evaluate(
        *STAND_STILL_2,
        "--benchmark",
        str(bench),
        "--out",
        str(out_dir),
        "--force",
        "--no-platform-probe",
        cwd=tmp_path,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    result = strict_load(out_dir / "metrics.json")  # strict JSON: null, never NaN
    assert result["num_episodes"] == 2 and result["forced_episodes"] is None
    assert np.isnan(ep.read_csv(out_dir / ep.EPISODES_FILE)["forced"]).all()  # no probe: empty cells
    assert out.stdout.splitlines()[-1] == f"results in {out_dir}: metrics.json, metrics.md, episodes.csv.gz"


def test_evaluate_says_last_where_it_wrote_its_results_and_git_ignores_the_default_place(tmp_path):
    """Without --out the results land in eval/<controller> of the working directory: the last line
    printed names it and every file written there, and the repository's .gitignore keeps it out of
    git (tests/test_repository.py checks the pattern against the package's own eval/ folders)."""
    bench = tiny_benchmark(tmp_path)
    out = run_evaluate(*STAND_STILL_2, "--benchmark", str(bench), "--no-platform-probe", cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    where, names = out.stdout.splitlines()[-1].removeprefix("results in ").split(": ")
    assert Path(where) == Path("eval") / "stand_still"
    assert names.split(", ") == ["metrics.json", "metrics.md", ep.EPISODES_FILE]
    assert sorted(p.name for p in (tmp_path / where).iterdir()) == sorted(names.split(", "))


def test_evaluate_fails_at_once_on_an_unwritable_output_directory(tmp_path):
    bench = tiny_benchmark(tmp_path)
    (tmp_path / "a_file").write_text("")
    out = run_evaluate(
        *STAND_STILL_2, "--benchmark", str(bench), "--out", str(tmp_path / "a_file" / "ev"), cwd=tmp_path
    )
    assert out.returncode == 2 and "cannot write results to" in out.stderr and "a_file" in out.stderr
    assert "Traceback" not in out.stderr and "episodes" not in out.stderr


def test_the_default_output_directory_is_one_per_checkpoint_file_even_where_names_repeat(tmp_path):
    """E27: results/study/lasmp/seed0/policy_449.pt and results/study/lasmp_centre/seed0/policy_449.pt
    have the same run-directory and file names; their default directories still differ. The same
    file always lands in the same place, however it is named on the command line."""
    import hashlib
    from types import SimpleNamespace

    from lasmp.eval.outdir import default_out_dir

    def out_dir(checkpoint, controller=None):
        return default_out_dir(SimpleNamespace(checkpoint=checkpoint, controller=controller), Path("eval"))

    def run_hash(run):
        return hashlib.sha256(str(run.resolve()).encode()).hexdigest()[:8]

    study = tmp_path / "results" / "study"
    a = out_dir(str(study / "lasmp" / "seed0" / "policy_449.pt"))
    b = out_dir(str(study / "lasmp_centre" / "seed0" / "policy_449.pt"))
    assert a != b
    assert a == Path(f"eval/seed0-{run_hash(study / 'lasmp' / 'seed0')}/policy_449")
    assert out_dir(str(study / "lasmp" / "seed0" / ".." / "seed0" / "policy_449.pt")) == a
    assert out_dir(str(study / "lasmp" / "seed0" / "policy_450.pt")).parent == a.parent  # one run, one folder
    assert out_dir(None, "stand_still") == Path("eval/stand_still")
    rs = tmp_path / "rs_run"
    assert out_dir(str(rs / "model_9.pt"), "rs_oracle") == Path(
        f"eval/rs_run-{run_hash(rs)}/model_9_rs_oracle"
    )
    run = tmp_path / "runs" / "seed2"
    run.mkdir(parents=True)
    for k in (9, 10):
        (run / f"model_{k}.pt").write_text("")
    assert out_dir(str(run)) == Path(f"eval/seed2-{run_hash(run)}/model_10")  # a run directory: its latest


def test_metrics_json_writes_missing_values_as_null(tmp_path):
    from lasmp.eval.report import write_results

    result = {
        "method": "m",
        "num_episodes": 1,
        "std_over": "1 batch",
        "wall_time_s": 1.0,
        "metrics": {
            "collision_rate": {"mean": 1.0, "std": 0.0},
            "power_w": {"mean": float("nan"), "std": np.float64("nan")},
        },
        "extra": [np.inf, np.int64(3)],
    }
    write_results(tmp_path, result)
    back = strict_load(tmp_path / "metrics.json")
    assert back["metrics"]["power_w"] == {"mean": None, "std": None} and back["extra"] == [None, 3]
    assert "| power (W) | n/a | n/a |" in (tmp_path / "metrics.md").read_text()


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


def test_oracle_command_points_to_the_platform_centre_in_the_heading_frame():
    from lasmp.config import build_env_cfg
    from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
    from lasmp.envs.moving_platform.env import MovingPlatformEnv
    from lasmp.envs.moving_platform.readout import read_scene
    from lasmp.eval.cli import oracle_command

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


def test_evaluate_rs_controllers_end_to_end(tmp_path):
    from lasmp.train import train
    from lasmp.train_cfg import to_train_cfg

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
    from lasmp.train import train
    from lasmp.train_cfg import to_train_cfg

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


def test_position_deviation_reads_both_frames_and_height_the_platform_frame():
    """The platform-frame and translating-frame deviations follow their own positions; the height stays in P."""
    m = EpisodeMetrics(2, H)
    m.start(np.array([0, 1]), pose([[0.0, 0.0, H]] * 2, p_body_t=np.zeros((2, 3))))
    p_body_p = np.array([[0.0, 0.0, H], [0.0, 0.0, H - 0.3]])  # env 1 is 0.3 m low in P
    p_body_t = np.array([[0.3, 0.4, 0.0], [0.0, 0.0, 0.0]])  # env 0 moved 0.5 m in the translating frame only
    z = np.zeros((2, 12))
    m.step(np.array([True, True]), np.zeros(2, bool), pose(p_body_p, p_body_t=p_body_t), z, z)
    out = m.close(np.array([0, 1]), np.array([False, False]))
    np.testing.assert_allclose(out["position_deviation_translating_m"], [0.5, 0.0])
    np.testing.assert_allclose(out["position_deviation_m"], [0.0, 0.3])
    np.testing.assert_allclose(out["height_violation_rate"], [0.0, 1.0])


def test_trunk_pose_reads_the_platform_and_translating_frames_of_a_readout():
    from types import SimpleNamespace

    rot = rot_z(0.7)[None]
    r = SimpleNamespace(
        p_body_p=np.array([[0.2, 0.0, 0.47]]),
        p_body_w=np.array([[1.0, 2.0, 3.5]]),
        p_plf_w=np.array([[1.0, 1.8, 3.0]]),
        r_wp=rot,
        r_wb=rot,
    )
    p = TrunkPose.from_readout(r)
    np.testing.assert_allclose(p.p_body_p, r.p_body_p)
    np.testing.assert_allclose(p.r_pb[0], np.eye(3), atol=1e-12)  # trunk aligned with the platform
    np.testing.assert_allclose(p.p_body_t, [[0.0, 0.2, 0.5]])


def tilts(r_wb, r_wp, r_wb0=None):
    """(world tilt, platform-relative angle) of one step after a start on a level platform (the trunk
    level, or at r_wb0)."""
    m = EpisodeMetrics(1, H)
    m.start(np.array([0]), pose([[0, 0, H]], r_wb=np.eye(3) if r_wb0 is None else r_wb0))
    m.step(
        np.array([True]),
        np.array([False]),
        pose([[0, 0, H]], r_wb=r_wb, r_wp=r_wp),
        np.zeros((1, 12)),
        np.zeros((1, 12)),
    )
    out = m.close(np.array([0]), np.array([False]))
    return out["rotation_deviation_rad"][0], out["rotation_deviation_platform_rad"][0]


def test_a_trunk_that_stays_level_while_the_platform_tilts_has_no_world_tilt_but_turns_relative_to_it():
    world, platform = tilts(r_wb=np.eye(3), r_wp=rot_x(0.3))
    assert world == pytest.approx(0.0, abs=1e-12) and platform == pytest.approx(0.3)


def test_a_trunk_rigid_on_a_tilting_platform_tilts_in_the_world_but_not_relative_to_the_platform():
    world, platform = tilts(r_wb=rot_x(0.3), r_wp=rot_x(0.3))
    assert world == pytest.approx(0.3) and platform == pytest.approx(0.0, abs=1e-7)


def test_a_trunk_that_tilts_on_a_level_platform_tilts_in_both_readings():
    world, platform = tilts(r_wb=rot_x(0.3), r_wp=np.eye(3))
    assert world == pytest.approx(0.3) and platform == pytest.approx(0.3)


def test_yaw_alone_gives_no_world_tilt_even_from_a_tilted_start():
    assert tilts(r_wb=rot_z(1.2), r_wp=np.eye(3))[0] == pytest.approx(0.0, abs=1e-12)
    tilted = rot_x(0.2)
    # turned about the world vertical
    world, _ = tilts(r_wb=rot_z(2.5) @ tilted, r_wp=np.eye(3), r_wb0=tilted)
    assert world == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("h_des_from", ["top", "centre"])
def test_the_height_band_is_centred_037_m_above_the_top_whatever_the_reward_reads(h_des_from, monkeypatch):
    from lasmp.config import build_env_cfg
    from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
    from lasmp.envs.moving_platform.env import MovingPlatformEnv
    from lasmp.eval.cli import eval_env_overrides
    from lasmp.eval.metrics import metric_h_des_p_m
    from lasmp.eval.run import run_benchmark

    overrides = {
        **eval_env_overrides(2, 0),
        "rewards": {"h_des_from": h_des_from},
        "trajectory": {"split": "test", "duration_s": 0.1},
    }
    env = MovingPlatformEnv(build_env_cfg(overrides, schema=MovingPlatformCfg))
    assert metric_h_des_p_m(env.plf_top_m) == pytest.approx(env.plf_top_m + 0.37) == pytest.approx(0.47)
    bench = bm.generate(num_trajectories=2, num_robots=2, seed=0)
    seen = {}

    class Spy(EpisodeMetrics):
        def __init__(self, n, h_des_p_m, *a):
            seen["h_des_p_m"] = h_des_p_m
            super().__init__(n, h_des_p_m, *a)

    monkeypatch.setattr("lasmp.eval.run.EpisodeMetrics", Spy)
    run_benchmark(env, lambda obs: torch.zeros(2, 12), bench, 2, progress=False)
    assert seen["h_des_p_m"] == pytest.approx(0.47)  # not the reward's 0.27 under h_des_from=centre
    assert env.h_des_p_m == pytest.approx(0.47 if h_des_from == "top" else 0.37)


def test_shrinking_the_tail_steps_only_playing_envs_and_changes_no_episode():
    import torch

    from lasmp.config import build_env_cfg
    from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
    from lasmp.envs.moving_platform.env import MovingPlatformEnv
    from lasmp.eval.cli import eval_env_overrides
    from lasmp.eval.run import run_benchmark

    bench = bm.generate(num_trajectories=10, num_robots=4, seed=0)
    results, stepped = {}, {}
    for shrink in (False, True):
        overrides = {**eval_env_overrides(4, 0), "trajectory": {"split": "test", "duration_s": 2.0}}
        env = MovingPlatformEnv(build_env_cfg(overrides, schema=MovingPlatformCfg))
        zeros = torch.zeros(4, 12)
        results[shrink] = run_benchmark(
            env, lambda obs, zeros=zeros: zeros, bench, 10, progress=False, shrink_tail=shrink
        )
        stepped[shrink] = env.sim.env_steps
        assert env.stepped_envs is None  # the hook is cleared after the run
    for key, value in results[False]["episodes"].items():
        np.testing.assert_array_equal(results[True]["episodes"][key], value, err_msg=key)
    # 10 episodes on 4 envs: the third wave has 2 episodes, so the tail steps fewer envs
    assert stepped[True] < stepped[False]


def test_evaluate_refuses_a_thread_count_below_one(capsys):
    from lasmp.eval import cli

    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--controller", "stand_still", "--torch-threads", "0"])
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and "--torch-threads: must be an integer >= 1, got '0'" in err
