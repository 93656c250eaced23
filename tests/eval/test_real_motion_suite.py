"""The real-motion suite: scenarios, episodes, the platform drive, the evaluate.py and module CLIs."""

import csv
import gzip
import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
from testkit import load_script

from lasmp.envs import trajectories as trj
from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
from lasmp.eval import benchmark as bm
from lasmp.eval.build import eval_env_overrides
from lasmp.eval.cli import main as evaluate_main
from lasmp.eval.metrics import METRICS
from lasmp.eval.real_motion import suite as rm
from lasmp.eval.real_motion.__main__ import main as suite_main
from lasmp.motions.motion import DEFAULT_DURATION_S, Motion, deck_pose, time_grid, to_trajectories

QUICK = ["lift_up", "bus_emergency_brake"]


@pytest.fixture(scope="module")
def small_bench(tmp_path_factory):
    path = tmp_path_factory.mktemp("bench") / "xi.npz"
    bm.save(path, bm.generate(num_trajectories=4, num_robots=8, seed=0))
    return path


def test_every_scenario_builds_a_valid_motion():
    motions = rm.build_motions()
    assert [m.name for m in motions] == list(rm.SCENARIOS)
    for m in motions:
        assert m.duration_s >= 10.0, m.name
        assert np.all(np.isfinite(m.pose)) and np.allclose(m.pose[0], 0.0), m.name
        assert np.all(np.abs(m.pose[:, 5]) <= 2.6), f"{m.name}: yaw beyond the platform world's range"
        s = rm.motion_summary(m)
        assert s["acc_max_mps2"] > 0.0, f"{m.name} does not move"


def test_a_scenario_run_alone_gives_each_robot_the_initial_pose_draws_it_has_in_the_full_suite(small_bench):
    bench = bm.load(small_bench)
    full = rm.make_episodes(rm.build_motions(), bench.robots, 4)
    alone = rm.make_episodes(rm.build_motions(["bus_stop_and_go"]), bench.robots, 4)
    i = full.names.index("bus_stop_and_go")
    np.testing.assert_array_equal(
        alone.initial_pose_draws(np.arange(4)), full.initial_pose_draws(np.arange(4) + 4 * i)
    )
    draws = full.initial_pose_draws(np.arange(full.num_episodes))
    assert len(np.unique(draws[:, 0])) == full.num_episodes  # every (scenario, robot) its own


def test_scenario_names_are_checked():
    with pytest.raises(ValueError, match="unknown scenario.*'boat'"):
        rm.scenario_names(["boat"])
    with pytest.raises(ValueError, match="no scenario"):
        rm.scenario_names([])
    assert rm.scenario_names(None) == list(rm.SCENARIOS)


def test_episodes_pair_every_scenario_with_the_same_robots(small_bench):
    bench = bm.load(small_bench)
    ep = rm.make_episodes(rm.build_motions(QUICK), bench.robots, 3)
    assert ep.num_episodes == 6 and ep.robots_per_scenario == 3
    scen, robot = ep.pairing(np.arange(6))
    assert scen.tolist() == [0, 0, 0, 1, 1, 1] and robot.tolist() == [0, 1, 2, 0, 1, 2]
    np.testing.assert_array_equal(ep.robots.trunk_mass_kg, bench.robots.trunk_mass_kg[:3])
    with pytest.raises(IndexError):
        ep.pairing([6])
    with pytest.raises(ValueError, match=r"robots per scenario must be in \[1, 8\]"):
        rm.make_episodes(rm.build_motions(QUICK), bench.robots, 9)


def test_suite_overrides_reach_the_env_config():
    from lasmp.config.base import build_env_cfg

    def build(drive: str) -> MovingPlatformCfg:
        return build_env_cfg(
            eval_env_overrides(2, 0, rm.env_overrides(20.0, drive)), schema=MovingPlatformCfg
        )

    cfg = build("close")
    assert cfg.trajectory.duration_s == 20.0 and cfg.trajectory.split == "test"  # merged, not replaced
    assert cfg.platform.velocity_feedforward and cfg.platform.omega_n_rad_s == pytest.approx(25.13)
    assert build("paper").platform.omega_n_rad_s == MovingPlatformCfg().platform.omega_n_rad_s  # the default
    with pytest.raises(ValueError, match="unknown platform drive 'stiff'"):
        rm.env_overrides(20.0, "stiff")


def test_close_drive_follows_the_scenario_and_the_paper_drive_filters_it(small_bench):
    bench = bm.load(small_bench)
    name = "lift_emergency_stop"
    ep = rm.make_episodes(rm.build_motions([name]), bench.robots, 1)
    close = rm.platform_tracking(ep, eval_env_overrides(1, 0, rm.env_overrides(DEFAULT_DURATION_S, "close")))[
        name
    ]
    paper = rm.platform_tracking(ep, eval_env_overrides(1, 0, rm.env_overrides(DEFAULT_DURATION_S, "paper")))[
        name
    ]
    assert close["recorded_s"] == paper["recorded_s"] == pytest.approx(DEFAULT_DURATION_S - 0.02)
    assert close["translation_error_rms_m"] < 0.01 and paper["translation_error_rms_m"] > 0.3
    # the close drive reproduces the reference's acceleration; the soft drive low-passes the stop away
    assert close["platform_acc_rms_mps2"] == pytest.approx(close["reference_acc_rms_mps2"], rel=0.15)
    assert paper["platform_acc_rms_mps2"] < 0.5 * paper["reference_acc_rms_mps2"]


def test_evaluate_suite_end_to_end(tmp_path, small_bench, capsys):
    out = tmp_path / "suite"
    rc = evaluate_main(
        [
            "--suite",
            "real_motion",
            "--controller",
            "stand_still",
            "--scenarios",
            *QUICK,
            "--robots-per-scenario",
            "2",
            "--benchmark",
            str(small_bench),
            "--out",
            str(out),
        ]
    )
    assert rc == 0
    result = json.loads((out / "metrics.json").read_text())
    assert result["suite"] == "real_motion" and result["num_episodes"] == 4
    # what it was measured with, as evaluate.py's benchmark results record it
    assert (
        result["seed"] == 0
        and result["benchmark_sha256"] == hashlib.sha256(small_bench.read_bytes()).hexdigest()
    )
    assert result["checkpoint"] is None and result["checkpoint_sha256"] is None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["suite"]  # no lock or staging directory left
    assert result["platform_drive"] == "close" and result["duration_s"] == DEFAULT_DURATION_S
    assert list(result["scenarios"]) == QUICK
    for name in QUICK:
        s = result["scenarios"][name]
        assert set(s["metrics"]) == set(METRICS) and s["num_episodes"] == 2
        assert 0.0 <= s["metrics"]["collision_rate"]["mean"] <= 1.0
        assert s["mean_episode_steps"] <= DEFAULT_DURATION_S / 0.02 + 1
        assert result["platform_tracking"][name]["reference_acc_rms_mps2"] > 0.0
        assert result["reference_motion"][name]["acc_max_mps2"] > 0.0
    with gzip.open(out / "episodes.csv.gz", "rt", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["scenario"], r["robot"]) for r in rows] == [(n, str(i)) for n in QUICK for i in range(2)]
    init = MovingPlatformCfg().init_state
    lo, hi = init.yaw_range_rad
    pose = rm.make_episodes(rm.build_motions(QUICK), bm.load(small_bench).robots, 2).initial_pose_draws(
        range(4)
    )
    assert [float(r["initial_yaw_rad"]) for r in rows] == pytest.approx(lo + (hi - lo) * pose[:, 0])
    for name in QUICK:  # each row's collision is the episode's: the scenario's rate is their mean
        collided = [float(r["collision"]) for r in rows if r["scenario"] == name]
        assert np.mean(collided) == pytest.approx(
            result["scenarios"][name]["metrics"]["collision_rate"]["mean"]
        )
    assert all(bool(r["collision_cause"]) == (r["collision"] == "1") for r in rows)
    md = (out / "metrics.md").read_text()
    assert "| lift_up |" in md and "| bus_emergency_brake |" in md and "How the platform followed" in md
    assert (
        capsys.readouterr().out.splitlines()[-1]
        == f"results in {out}: metrics.json, metrics.md, episodes.csv.gz"
    )
    assert suite_main(["table", str(out), str(out), "--labels", "A", "B"]) == 0
    table = capsys.readouterr().out
    lift = result["scenarios"]["lift_up"]["metrics"]
    expected = f"{lift['collision_rate']['mean']:.2f} / {lift['position_deviation_m']['mean']:.3f}"
    assert "| scenario | A | B |" in table and f"| lift_up | {expected} | {expected} |" in table
    assert suite_main(["table", str(out), "--labels", "A", "B"]) == 2
    assert "2 labels for 1 results" in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--scenarios", "lift_up"], "--scenarios needs --suite"),
        (
            ["--suite", "real_motion", "--num-trajectories", "3"],
            "--num-trajectories does not apply to --suite",
        ),
    ],
)
def test_evaluate_suite_bad_flags(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        evaluate_main(["--controller", "stand_still", *argv])
    assert exc.value.code == 2
    assert message in capsys.readouterr().err


def test_evaluate_suite_unknown_scenario(small_bench, capsys):
    rc = evaluate_main(
        [
            "--suite",
            "real_motion",
            "--controller",
            "stand_still",
            "--scenarios",
            "rocket",
            "--benchmark",
            str(small_bench),
        ]
    )
    assert rc == 2 and "unknown scenario(s) ['rocket']" in capsys.readouterr().err


def test_module_cli_generates_a_loadable_file_and_plots(tmp_path, capsys):
    path = tmp_path / "rm.npz"
    assert suite_main(["generate", "--out", str(path), "--scenarios", *QUICK]) == 0
    traj = trj.load(path)
    assert len(traj) == 2 and [s["name"] for s in traj.meta["scenarios"]] == QUICK
    motions = rm.build_motions(QUICK)
    for row, m in enumerate(motions):
        got = traj.evaluate(m.t_s, np.full(len(m.t_s), row))[0]
        np.testing.assert_allclose(got, m.pose, atol=1e-9)
    assert suite_main(["plot", "--out", str(tmp_path / "fig"), "--scenarios", "lift_up"]) == 0
    assert (tmp_path / "fig" / "lift_up.png").stat().st_size > 10_000
    capsys.readouterr()
    assert suite_main(["stats", "--json", "--scenarios", "lift_up"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["lift_up"]["z_range_m"] > 1.0  # the car travels


def test_deck_pose_adds_the_lever_arm():
    t = time_grid(10.0)
    euler = np.zeros((len(t), 3))
    euler[:, 1] = 0.05 * np.sin(t)  # pitch, nose down positive about y
    pose = deck_pose(np.zeros((len(t), 3)), euler, [20.0, 0.0, 0.0])
    # a point 20 m forward goes down by 20 sin(pitch) when the nose pitches down (R_y(+) maps x to -z)
    np.testing.assert_allclose(pose[:, 2], -20.0 * np.sin(euler[:, 1]), atol=1e-12)
    assert np.allclose(pose[:, 3:], euler)
    with pytest.raises(ValueError, match="initial attitude must be level"):
        deck_pose(np.zeros((2, 3)), np.full((2, 3), 0.1), [1.0, 0, 0])


def test_motion_rejects_a_motion_that_does_not_start_at_rest_pose():
    t = time_grid(1.0)
    with pytest.raises(ValueError, match="pose\\[0\\] must be the initial pose"):
        Motion("x", t, np.ones((len(t), 6)))
    m = Motion("y", t, np.zeros((len(t), 6)))
    assert to_trajectories([m]).meta["scenarios"][0]["name"] == "y"


def test_the_suite_plays_motions_given_from_code_and_the_level_acceleration_probe_matches_its_tilt(
    tmp_path, small_bench
):
    from lasmp.motions import level_push
    from lasmp.motions.motion import derivatives

    level, tilt, slow = level_push.motions()
    v, a = derivatives(level)
    assert np.abs(a[:, 0]).max() == pytest.approx(1.5, rel=0.01) and np.all(level.pose[:, 1:] == 0)
    v_slow, a_slow = derivatives(slow)  # the same final speed at under a third of the acceleration
    assert v_slow[-1, 0] == pytest.approx(v[-1, 0], rel=0.01) and v[-1, 0] == pytest.approx(7.5, rel=0.01)
    assert np.abs(a_slow[:, 0]).max() < 0.3 * 1.5 and np.all(slow.pose[:, 1:] == 0)
    assert np.abs(tilt.pose[:, 4]).max() == pytest.approx(np.arctan(1.5 / 9.81)) and np.all(
        tilt.pose[:, :4] == 0
    )
    out = tmp_path / "probe"
    argv = ["--controller", "stand_still", "--robots-per-scenario", "1", "--benchmark", str(small_bench)]
    assert evaluate_main([*argv, "--suite", "real_motion", "--out", str(out)], motions=[level, tilt]) == 0
    result = json.loads((out / "metrics.json").read_text())
    assert list(result["scenarios"]) == ["level_acceleration", "equivalent_tilt"]
    with pytest.raises(SystemExit):  # motions replace the named scenarios: not both
        evaluate_main(
            [*argv, "--suite", "real_motion", "--scenarios", "lift_up", "--out", str(tmp_path / "x")],
            motions=[level],
        )


def test_the_estimates_probe_records_the_true_platform_speed_and_the_estimates_per_motion(
    tmp_path, small_bench
):
    script = load_script("scripts/level_acceleration_estimates.py")
    out = tmp_path / "est"
    shipped = Path(__file__).parents[2] / "resources" / "policies" / "lasmp_a1.pt"
    argv = ["--checkpoint", str(shipped), "--robots-per-scenario", "1"]
    assert script.main([*argv, "--benchmark", str(small_bench), "--out", str(out)]) == 0
    summary = json.loads((out / "estimates.json").read_text())
    assert list(summary["motions"]) == ["level_acceleration", "equivalent_tilt", "slow_ramp"]
    for name, m in summary["motions"].items():
        assert m["falls"] == len(m["fall_times_s"]) <= 1
        last = m["windows"][-1]
        if name == "equivalent_tilt":  # it pitches in place: the platform point barely moves
            assert max(w["v_plf_true"] for w in m["windows"]) < 0.5
            for w in m["windows"]:  # it does not translate: the apparent vertical is the world's
                assert w["tilt_from_apparent_vertical_rad"] == pytest.approx(w["tilt_world_rad"], abs=0.02)
        elif m["falls"] == 0:  # both surges end at 7.5 m/s along x, in whatever frame the trunk faces
            assert last["v_plf_true"] == pytest.approx(7.5, abs=0.1) and last["u_aln_true"] < 0.5
    with pytest.raises(SystemExit):  # the result exists: refused without --force
        script.main([*argv, "--benchmark", str(small_bench), "--out", str(out)])


def test_the_apparent_vertical_stats_see_the_level_push_and_not_the_tilt_and_replay_the_benchmark(
    small_bench, tmp_path
):
    avs = load_script("scripts/apparent_vertical_stats.py")
    over = np.array([[1, 0], [1, 1], [0, 1], [1, 1], [1, 1]], dtype=bool)  # (T, m)
    assert avs.longest_stretch(over).tolist() == [2, 4]
    probe = avs.probe_motion_stats(0.02)
    push, tilt = probe["level_acceleration"], probe["equivalent_tilt"]
    tilt_rad = np.arctan(1.5 / 9.81)
    assert push["world_max_rad"] == pytest.approx(tilt_rad, rel=1e-3) == push["deck_max_rad"]
    assert tilt["deck_max_rad"] == pytest.approx(tilt_rad, rel=1e-3) and tilt["world_max_rad"] < 1e-6
    assert 4.0 < push["world_longest_over_s"] < 5.5 and tilt["world_longest_over_s"] == 0.0
    out = tmp_path / "avs.json"
    assert (
        avs.main(["--episodes", "2", "--batch-envs", "2", "--benchmark", str(small_bench), "--out", str(out)])
        == 0
    )
    xi = json.loads(out.read_text())["xi_eval"]
    assert len(xi["world_max_rad"]) == 2 and all(0.0 <= x < 1.0 for x in xi["world_max_rad"])
    with pytest.raises(SystemExit):  # the result exists: refused without --force
        avs.main(["--episodes", "2", "--benchmark", str(small_bench), "--out", str(out)])
