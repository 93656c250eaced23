"""What the batched moving-platform env observes: the groups' shapes and critic columns, the
history, the IMU at rest, the readout's frames and signs, the feet's contacts and loads, and what
becomes of a non-finite value."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from testkit import platform_env as make
from testkit import static_platform

from lasmp.config.base import build_env_cfg
from lasmp.envs import trajectories as trj
from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
from lasmp.envs.moving_platform.env import MovingPlatformEnv
from lasmp.envs.robot import as_numpy
from lasmp.robots import a1

G = 9.81


def test_observation_groups_have_the_documented_shapes():
    env = make(3)
    obs = env.get_observations()
    shapes = {k: tuple(v.shape) for k, v in obs.items()}
    assert shapes == {
        "policy": (3, 44),
        "history": (3, 20, 44),
        "priv_explicit": (3, 13),
        "priv_implicit": (3, 29),
        "alignment": (3, 3),
        "critic": (3, 95),
    }
    obs, rew, done, extras = env.step(torch.zeros(3, 12))
    assert rew.shape == (3,) and done.shape == (3,) and extras["time_outs"].shape == (3,)
    assert all(v.dtype == torch.float32 for v in obs.values())


def test_history_holds_past_observations_newest_first():
    env = make(2)
    o0 = env.get_observations()["policy"].clone()
    assert torch.equal(env.get_observations()["history"][:, 0], o0)  # filled with o_0 at reset
    o1 = env.step(torch.zeros(2, 12))[0]
    o2 = env.step(torch.zeros(2, 12))[0]
    assert torch.equal(o2["history"][:, 0], o1["policy"])
    assert torch.equal(o2["history"][:, 1], o0)
    assert torch.equal(o1["history"][:, 0], o0)


def test_accelerometer_reads_plus_g_on_body_z_when_standing_still():
    env = make(2, domain_rand={"enabled": False})
    static_platform(env)
    env.reset()
    for _ in range(60):  # 1.2 s to settle
        obs = env.step(torch.zeros(2, 12))[0]
    acc = obs["policy"][:, :3]
    assert torch.allclose(acc[:, 2], torch.full((2,), G), atol=0.15), acc
    assert acc[:, :2].abs().max() < 0.5, acc
    gyro_roll_pitch = obs["policy"][:, 3:8]
    assert gyro_roll_pitch.abs().max() < 0.05


def test_yawed_robot_sees_platform_velocity_in_its_own_frame():
    env = make(1, domain_rand={"enabled": False})
    sim, ix = env.sim, env.index
    # set the platform moving along world x at 1 m/s and the robot yawed by 90 deg, at rest
    yaw = math.pi / 2
    quat = torch.tensor([math.cos(yaw / 2), 0, 0, math.sin(yaw / 2)])
    sim.qpos[0, ix.root_qpos + 3 : ix.root_qpos + 7] = quat
    sim.qvel[0, env.sim.model.joint("plf_x").dofadr[0]] = 1.0
    sim.forward()
    from lasmp.envs.moving_platform.readout import read_scene

    r = as_numpy(read_scene(sim, ix))
    # world +x is the body's -y when the body faces world +y
    assert np.allclose(r.v_plf_b[0], [0.0, -1.0, 0.0], atol=1e-9), r.v_plf_b
    # the robot is at rest: it must speed up along body -y to move with the platform
    assert np.allclose(r.u_aln[0], [0.0, -1.0, 0.0], atol=1e-9), r.u_aln


def test_foot_contacts_match_contact_forces():
    env = make(4, domain_rand={"enabled": False})
    static_platform(env)
    env.reset()
    for _ in range(30):
        env.step(torch.zeros(4, 12))
    r = as_numpy(env.readout)
    assert r.foot_contact.all()
    f = r.f_feet_w
    # forces on the feet push up and carry the robot's weight
    assert (f[:, :, 2] > 5.0).all(), f[:, :, 2]
    total_mass = env.sim.model.body_subtreemass[env.sim.model.body("trunk").id]
    assert np.allclose(f[:, :, 2].sum(axis=1), total_mass * G, rtol=0.05)
    # lift the robot off: no contact, zero force
    env.sim.qpos[:, env.index.root_qpos + 2] += 0.3
    env.sim.forward()
    from lasmp.envs.moving_platform.readout import read_scene

    r = as_numpy(read_scene(env.sim, env.index))
    assert not r.foot_contact.any() and np.all(r.f_feet_w == 0.0)


def test_on_a_rolled_deck_the_feet_loads_in_the_platform_frame_lean_downhill_and_the_margin_shrinks():
    from lasmp.envs.moving_platform.rewards import support_margin_m

    def margin_and_cop(roll_rad: float):
        # facing the deck's +x: the roll tips the robot over its side, across the stance's narrow width
        env = make(4, domain_rand={"enabled": False}, init_state={"yaw_range_rad": [0.0, 0.0]})

        def tilt(ids):  # ramp the deck to `roll_rad` over 1 s, then hold it
            poses = np.zeros((len(ids), 4, 6))
            poses[:, 2:, 3] = roll_rad
            poses[:, 1, 3] = roll_rad * 0.5
            return trj.from_samples(np.array([0.0, 0.5, 1.0, 10.0]), poses), np.full(len(ids), -1)

        env._next_trajectories = tilt
        env.reset()
        for _ in range(100):  # 2 s: the deck has reached its roll and the robot has settled
            env.step(torch.zeros(4, 12))
        r = env.readout
        f_n = r.f_feet_p[:, :, 2]
        cop_y = (f_n * r.p_feet_p[:, :, 1]).sum(dim=1) / f_n.sum(dim=1)
        total_mass = env.sim.model.body_subtreemass[env.sim.model.body("trunk").id]
        # at rest, the feet carry the weight: (0, 0, m g) in the world, seen in the deck's frame as it
        # stands (its roll, as the drive holds it under the robot's load); rolled, partly along its +y
        weight_p = torch.einsum(
            "nji,j->ni", r.r_wp, torch.tensor([0.0, 0.0, total_mass * G], dtype=r.r_wp.dtype)
        )
        np.testing.assert_allclose(r.f_feet_p.sum(dim=1), weight_p, atol=0.03 * total_mass * G)
        deck_roll = torch.atan2(r.r_wp[:, 2, 1], r.r_wp[:, 2, 2])
        assert (torch.abs(deck_roll - roll_rad) < 0.1).all(), deck_roll
        # the feet stand on the deck's top, in its frame
        np.testing.assert_allclose(r.p_feet_p[:, :, 2], env.plf_top_m + a1.FOOT_RADIUS_M, atol=0.01)
        return support_margin_m(r.p_feet_p, r.f_feet_p, r.foot_contact), cop_y

    level_margin, level_cop_y = margin_and_cop(0.0)
    rolled_margin, rolled_cop_y = margin_and_cop(0.25)
    # a positive roll lifts the deck's +y side: the CoP moves to -y, downhill, nearer the feet's edge
    assert (rolled_cop_y < level_cop_y - 0.03).all(), (level_cop_y, rolled_cop_y)
    assert (level_margin > 0.08).all() and (rolled_margin < level_margin - 0.03).all(), (
        level_margin,
        rolled_margin,
    )


def test_observations_handed_out_stay_unchanged_through_the_next_step():
    """rsl_rl copies a step's observations into its storage only after the following env.step: the
    tensors handed out (history included, whose buffers the env reuses) must not change meanwhile."""
    env = MovingPlatformEnv(
        build_env_cfg({"num_envs": 4, "seed": 0, "sim": {"num_threads": 1}}, schema=MovingPlatformCfg)
    )
    obs, _ = env.reset()
    for _ in range(4):
        handed_out, snapshot = obs, obs.clone()
        obs, _, _, _ = env.step(0.3 * torch.randn(4, 12))
        for key, value in snapshot.items():
            assert torch.equal(handed_out[key], value), key
        assert torch.equal(obs["history"][:, 0], handed_out["policy"])  # the newest entry: the last o


def test_groups_are_the_critic_columns_they_document():
    env = make(3)
    obs, _, _, _ = env.step(0.2 * torch.randn(3, 12))
    r, critic = env.readout, obs["critic"]
    f32 = lambda x: x.to(torch.float32)  # noqa: E731
    assert torch.equal(obs["policy"], critic[:, :44])
    x_exp = torch.cat([f32(r.foot_contact), f32(r.v_body_b), f32(r.v_plf_b), f32(r.omega_plf_b)], dim=1)
    assert torch.equal(obs["priv_explicit"], x_exp) and torch.equal(critic[:, 44:57], x_exp)
    assert torch.equal(obs["priv_implicit"], f32(env.x_imp)) and torch.equal(critic[:, 57:86], f32(env.x_imp))
    assert torch.equal(obs["alignment"], f32(r.u_aln)) and torch.equal(critic[:, 86:89], f32(r.u_aln))
    assert torch.equal(critic[:, 89:], torch.cat([f32(r.p_body_p), f32(r.phi_body_w)], dim=1))


def test_a_non_finite_observation_value_becomes_0_is_counted_once_and_the_rest_is_clipped():
    env = make(3, observations={"clip": 5.0})
    env.x_imp[1, 0] = torch.nan  # the trunk mass of env 1, in priv_implicit and in the critic
    env.x_imp[2, 1] = -1e9
    obs, _, _, extras = env.step(torch.zeros(3, 12))
    assert env.nonfinite_obs_values == 1 and extras["log"]["/faults/nonfinite_obs_values"] == 1.0
    assert all(torch.isfinite(v).all() and v.abs().max() <= 5.0 for v in obs.values())
    assert obs["priv_implicit"][1, 0] == 0.0 and obs["critic"][1, 57] == 0.0
    assert obs["priv_implicit"][2, 1] == -5.0 and obs["priv_implicit"][0, 0] == pytest.approx(
        min(env.x_imp[0, 0], 5.0)
    )
