"""The evaluation's metrics on constructed episodes: what a collision cuts short, the deviations in
the platform and translating frames, the world tilt against the platform-relative angle, the height
band, and the summary over batches."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from lasmp.eval import benchmark as bm
from lasmp.eval.metrics import ALL_METRICS, EpisodeMetrics, TrunkPose, rotation_angle, summarize

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
    from lasmp.config.base import build_env_cfg
    from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
    from lasmp.envs.moving_platform.env import MovingPlatformEnv
    from lasmp.eval.build import eval_env_overrides
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
