"""The R-S baseline env (static rough terrain): shapes, spawning, standing, pushes, commands,
reward signs, terminations, bad configuration and determinism."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import torch

from lasmp.config.base import build_env_cfg
from lasmp.config.checks import ConfigError
from lasmp.envs.moving_platform.rewards import REWARD_TERMS as MOVING_PLATFORM_TERMS
from lasmp.envs.rewards import RewardManager
from lasmp.envs.robot import read_robot
from lasmp.envs.rough_static import rewards as rw
from lasmp.envs.rough_static.cfg import RoughStaticCfg
from lasmp.envs.rough_static.env import RoughStaticEnv
from lasmp.envs.rough_static.scene import HFIELD_NAME
from lasmp.envs.rough_static.state import StepState
from lasmp.robots import a1


def make(n=4, **cfg) -> RoughStaticEnv:
    env = RoughStaticEnv(build_env_cfg({"num_envs": n, **cfg}, schema=RoughStaticCfg))
    env.reset()
    return env


def zeros(env):
    return torch.zeros(env.num_envs, env.num_actions)


def test_observation_groups_have_the_moving_platform_sizes():
    env = make(3)
    shapes = {k: tuple(v.shape) for k, v in env.get_observations().items()}
    assert shapes == {
        "policy": (3, 44),
        "history": (3, 20, 44),
        "priv_explicit": (3, 13),
        "priv_implicit": (3, 29),
        "command": (3, 3),
        "critic": (3, 44 + 13 + 29 + 3 + 1 + 3),
    }
    obs, _, _, _ = env.step(zeros(env))
    assert torch.all(obs["priv_explicit"][:, 7:] == 0)  # static ground: no platform velocities
    assert torch.equal(obs["command"], torch.as_tensor(env.command, dtype=torch.float32))
    assert env.max_episode_length == 1000 and env.num_actions == 12
    # no curriculum
    assert env.state_dict(run=False) == {} and env.state_dict()["run"]["num_envs"] == env.num_envs


def test_robot_spawns_above_the_terrain_touching_nothing():
    env = make(16, seed=5)
    m = env.sim.model
    terrain = m.geom(HFIELD_NAME).id
    data = mujoco.MjData(m)
    x = env.sim.qpos[:, env.index.root_qpos : env.index.root_qpos + 2].numpy()
    half = np.array([env.terrain.half_x_m, env.terrain.half_y_m]) - env.cfg.terrain.spawn_margin_m
    assert np.all(np.abs(x) <= half)
    for i in range(env.num_envs):
        data.qpos[:] = env.sim.qpos[i].numpy()
        mujoco.mj_forward(m, data)
        for c in data.contact[: data.ncon]:
            assert terrain in (c.geom1, c.geom2)
            assert c.dist >= -1e-9, f"env {i}: geom {m.geom(c.geom1).name}/{m.geom(c.geom2).name} inside"
        feet = np.array([data.site_xpos[m.site(f).id] for f in a1.FOOT_NAMES])
        ground = env.terrain.height_at(torch.from_numpy(feet[:, :2])).numpy()
        gap = feet[:, 2] - a1.FOOT_RADIUS_M - ground
        assert np.all(gap >= -1e-6) and gap.min() < 0.15  # above the ground, and not dropped from high
    assert not read_robot(env.sim, env.index).body_collision.any()


def test_standing_still_on_rough_ground_mostly_survives_2_s():
    env = make(16, seed=2, pushes={"enabled": False})
    ended = np.zeros(env.num_envs, dtype=bool)
    for _ in range(100):
        _, _, done, _ = env.step(zeros(env))
        ended |= done.numpy()
    assert ended.sum() <= 3
    assert env.fault_count == 0


def test_push_adds_the_requested_horizontal_velocity():
    env = make(4, seed=1)
    ids = np.array([0, 2])
    before = env.sim.qvel[:, env.index.root_qvel : env.index.root_qvel + 6].numpy().copy()
    dv = env.push(torch.from_numpy(ids)).numpy()
    after = env.sim.qvel[:, env.index.root_qvel : env.index.root_qvel + 6].numpy()
    assert np.allclose(after[ids, :2] - before[ids, :2], dv)
    assert np.all(np.linalg.norm(dv, axis=1) <= env.cfg.pushes.max_mps)
    assert np.allclose(after[ids, 2:], before[ids, 2:]) and np.allclose(after[[1, 3]], before[[1, 3]])
    lo, hi = env.cfg.pushes.interval_s
    push_time_left_s = env.push_time_left_s.numpy()
    assert np.all((push_time_left_s[ids] >= lo) & (push_time_left_s[ids] <= hi))
    # on schedule: a due env is pushed at the start of the step, the others are not
    env.push_time_left_s[:] = torch.tensor([5.0, 0.0, 5.0, 5.0])
    env.step(zeros(env))
    assert env.pushed.tolist() == [False, True, False, False]
    assert np.linalg.norm(env.push_dv_mps[1].numpy()) > 0


def test_commands_are_resampled_on_schedule_and_a_fifth_are_zero():
    env = make(
        4, seed=0, commands={"resample_s": 0.1, "zero_command_fraction": 0.0}, pushes={"enabled": False}
    )
    changed = []
    prev = env.command.numpy().copy()
    for _ in range(12):
        env.step(zeros(env))
        changed.append(bool(np.all(env.command.numpy() != prev)))
        prev = env.command.numpy().copy()
    assert [i + 1 for i, c in enumerate(changed) if c] == [5, 10]
    cmd = make(1).sample_commands(20000)
    zero = np.all(cmd == 0, axis=1)
    assert abs(zero.mean() - 0.2) < 0.015
    c = RoughStaticCfg().commands
    assert np.all(np.abs(cmd[:, 0]) <= c.lin_vel_x_mps[1]) and np.all(np.abs(cmd[:, 1]) <= c.lin_vel_y_mps[1])
    assert np.abs(cmd[~zero, 2]).max() > 0.9


def _state(**kw) -> StepState:
    n = 1
    base = dict(
        dt_s=0.02,
        v_body_b=torch.zeros(n, 3),
        omega_body_b=torch.zeros(n, 3),
        command=torch.zeros(n, 3),
        gravity_b=torch.tensor([[0.0, 0.0, -1.0]]),
        q_dev=torch.zeros(n, 12),
        tau=torch.zeros(n, 12),
        q_ddot=torch.zeros(n, 12),
        action=torch.zeros(n, 12),
        action_prev=torch.zeros(n, 12),
        collision=torch.zeros(n, dtype=torch.bool),
        touchdown=torch.zeros(n, 4, dtype=torch.bool),
        t_air_s=torch.zeros(n, 4),
    )
    base.update(kw)
    return StepState(**base)


def _total(s: StepState, term: str) -> float:
    m = RewardManager(rw.REWARD_TERMS, {term: rw.DEFAULT_REWARD_WEIGHTS[term]}, rw.RewardsCfg(), 1)
    return float(m.compute(s)[0])


def test_reward_terms_have_the_right_signs():
    cmd = torch.tensor([[0.5, 0.2, 0.3]])
    assert _total(_state(command=cmd, v_body_b=torch.tensor([[0.5, 0.2, 0.0]])), "track_lin_vel_xy") > _total(
        _state(command=cmd), "track_lin_vel_xy"
    )
    assert _total(
        _state(command=cmd, omega_body_b=torch.tensor([[0.0, 0.0, 0.3]])), "track_ang_vel_z"
    ) > _total(_state(command=cmd), "track_ang_vel_z")
    one = torch.ones(1, 12)
    bad = {
        "lin_vel_z": _state(v_body_b=torch.tensor([[0.0, 0.0, 0.5]])),
        "ang_vel_xy": _state(omega_body_b=torch.tensor([[1.0, -1.0, 0.0]])),
        "torques": _state(tau=5 * one),
        "joint_acc": _state(q_ddot=100 * one),
        "action_rate": _state(action=one),
        "body_contact": _state(collision=torch.tensor([True])),
        "orientation": _state(gravity_b=torch.tensor([[0.3, 0.0, -0.95]])),
        "stand_still": _state(q_dev=0.1 * one),
    }
    for term, s in bad.items():
        assert _total(s, term) < 0.0 == _total(_state(), term), term
    assert _total(_state(command=cmd, q_dev=0.1 * one), "stand_still") == 0.0  # only when told to stand
    td = torch.tensor([[True, False, False, False]])
    assert (
        _total(_state(command=cmd, touchdown=td, t_air_s=torch.tensor([[0.7, 0, 0, 0]])), "feet_air_time") > 0
    )
    assert (
        _total(_state(command=cmd, touchdown=td, t_air_s=torch.tensor([[0.1, 0, 0, 0]])), "feet_air_time") < 0
    )
    assert _total(_state(touchdown=td, t_air_s=torch.tensor([[0.7, 0, 0, 0]])), "feet_air_time") == 0.0
    with pytest.raises(ValueError, match="track_lin_vel_xy"):  # the moving-platform registry is unchanged
        RewardManager(MOVING_PLATFORM_TERMS, {"track_lin_vel_xy": 1.0}, None, 1)


def test_body_contact_terminates_and_time_out_is_a_truncation():
    env = make(2, seed=3, pushes={"enabled": False}, domain_rand={"enabled": False})
    q = env.sim.qpos
    ground = env.terrain.max_height_near(q[:1, :2].numpy(), 0.3)[0]
    q[0, env.index.root_qpos + 2] = ground + 0.045  # upside down, trunk on (slightly in) the ground
    q[0, env.index.root_qpos + 3 : env.index.root_qpos + 7] = torch.tensor([0.0, 1.0, 0.0, 0.0])
    env.sim.forward(torch.tensor([0]))
    _, _, done, extras = env.step(zeros(env))
    assert done.tolist() == [True, False] and not extras["time_outs"].any()
    assert extras["log"]["Termination/body_contact"] >= 1 and "Episode_Reward/body_contact" in extras["log"]
    assert extras["log"]["Episode/success_rate"] == 0.0  # the moving platform's tag: none reached the limit

    env = make(2, seed=3, episode_length_s=0.1, pushes={"enabled": False})
    for i in range(5):
        _, _, done, extras = env.step(zeros(env))
        assert done.all() == (i == 4)
    assert extras["time_outs"].all() and extras["log"]["Episode/success_rate"] == 1.0


def test_the_study_rng_stream_switch_only_moves_the_draws_after_the_robots():
    """On (the default), each reset draws 12 unused uniforms per env after the robots' intrinsics;
    off, the same robots, then other spawn places from the same seed."""
    on, off = make(3, seed=5), make(3, seed=5, study_rng_stream=False)
    assert on.cfg.study_rng_stream and not off.cfg.study_rng_stream
    np.testing.assert_array_equal(on.intrinsics.x_imp(), off.intrinsics.x_imp())
    assert not torch.equal(read_robot(on.sim, on.index).p_body_w, read_robot(off.sim, off.index).p_body_w)


@pytest.mark.parametrize(
    "overrides, field",
    [
        ({"terrain": {"resolution_m": -0.1}}, "terrain.resolution_m"),
        ({"terrain": {"size_m": [3.0, 24.0]}}, "terrain.size_m"),
        ({"commands": {"zero_command_fraction": 1.5}}, "commands.zero_command_fraction"),
        ({"commands": {"lin_vel_x_mps": [1.0, -1.0]}}, "commands.lin_vel_x_mps"),
        ({"pushes": {"interval_s": [0.0, 4.0]}}, "pushes.interval_s"),
        ({"pushes": {"max_mps": -1.0}}, "pushes.max_mps"),
        ({"rewards": {"weights": {"track_lin_vel": 1.0}}}, "rewards.weights"),
        ({"episode_length_s": 0.0}, "episode_length_s"),
        ({"domain_rand": {"train": {"joint_kp": [50.0, 40.0]}}}, "domain_rand.train.joint_kp"),
        ({"terrain": {"roughnes_m": 0.02}}, "roughnes_m"),
    ],
)
def test_bad_config_fails_naming_the_field(overrides, field):
    with pytest.raises(ConfigError, match=field.replace(".", r"\.")):
        build_env_cfg(overrides, schema=RoughStaticCfg)


def test_same_seed_gives_identical_observations():
    def run(seed):
        env = make(4, seed=seed)
        gen = torch.Generator().manual_seed(0)
        out = []
        for _ in range(50):
            obs, _, _, _ = env.step(0.3 * torch.randn(4, 12, generator=gen))
            out.append(obs["critic"].clone())
        return torch.stack(out)

    a, b = run(7), run(7)
    assert torch.equal(a, b)
    assert not torch.equal(a[0], run(8)[0])
