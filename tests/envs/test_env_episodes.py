"""How the batched moving-platform env's episodes start and end: the reset's start state, body
contact, falling off and time-outs, a diverging env's fault, and the actions it refuses."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from testkit import platform_env as make
from testkit import static_platform

from lasmp.envs.robot import as_numpy
from lasmp.robots import a1


def test_reset_places_robot_at_centre_with_random_yaw_feet_touching_not_inside():
    env = make(16)
    r = as_numpy(env.readout)
    assert np.abs(r.p_body_p[:, :2]).max() < 1e-9
    yaws = r.phi_body_w[:, 2]
    assert yaws.std() > 0.5 and np.abs(yaws).max() <= math.pi
    # lowest point of every foot sphere: above the top surface by the clearance, never below it
    feet_z = env.sim.site_xpos[:, env.index.foot_site, 2].numpy() - a1.FOOT_RADIUS_M
    gap = feet_z.min(axis=1) - env.plf_top_m
    assert np.all(gap >= 0.0) and np.all(gap <= 0.002), gap
    assert np.allclose(r.q, a1.Q_NOMINAL_RAD)
    assert not r.body_collision.any()


def test_off_centre_start_is_uniform_in_its_disc():
    env = make(64, init_state={"xy_offset_max_m": 0.5})
    r_xy = np.linalg.norm(env.readout.p_body_p[:, :2], axis=1)
    assert r_xy.max() <= 0.5 + 1e-6 and r_xy.min() < 0.25 and r_xy.max() > 0.35
    assert not env.readout.body_collision.any()


def test_reset_clears_the_previous_contacts_of_the_reset_envs_only():
    """A reset env starts with no previous contact; the previous contacts are the env's own buffer,
    not a view of the step's readout, whose reset rows are written anew with the envs' new state."""
    env = make(4, domain_rand={"enabled": False})
    static_platform(env)
    env.reset()
    for _ in range(30):
        env.step(torch.zeros(4, 12))
    assert env.contact_prev.all()  # standing
    none = torch.zeros(1, dtype=torch.bool)
    env._reset_envs(torch.tensor([1]), none, none)
    env._observations()  # reads env 1's new state into the readout
    env.readout.foot_contact[:] = True
    assert not env.contact_prev[1].any()
    assert env.contact_prev[[0, 2, 3]].all()


def test_body_contact_terminates_and_is_not_a_time_out():
    env = make(2, domain_rand={"enabled": False})
    static_platform(env)
    env.reset()
    # put env 1's trunk on the surface: a body contact
    env.sim.qpos[1, env.index.root_qpos + 2] = env.plf_top_m + 0.05
    env.sim.forward()
    _, rew, done, extras = env.step(torch.zeros(2, 12))
    assert done.tolist() == [False, True]
    assert not extras["time_outs"].any()
    assert extras["log"]["Termination/body_contact"] >= 1
    assert rew[1] < 0  # the collision penalty dominates


def test_the_readout_seen_at_an_ending_step_stays_the_ended_episodes_state_after_the_reset():
    """Evaluation records the state an episode ended in from `on_step` (the trunk's height and tilt,
    the feet down); the env then resets that row of its readout in place, so the host copy must not
    follow it: it was a view, and every failure read as the reset's level, feet-up start."""
    env = make(2, domain_rand={"enabled": False})
    static_platform(env)
    env.reset()
    seen = {}
    env.on_step = lambda readout, collision: seen.update(r=as_numpy(readout))
    env.sim.qpos[1, env.index.root_qpos + 2] = env.plf_top_m + 0.05  # env 1's trunk on the deck
    env.sim.forward()
    _, _, done, _ = env.step(torch.zeros(2, 12))
    assert done.tolist() == [False, True]
    ended, restarted = seen["r"].p_body_p[1, 2], float(env.readout.p_body_p[1, 2])
    assert restarted - ended > 0.15, (ended, restarted)  # the trunk down on the deck, up at the restart


def test_falling_off_the_platform_terminates():
    env = make(2, domain_rand={"enabled": False})
    static_platform(env)
    env.reset()
    env.sim.qpos[0, env.index.root_qpos] = 1.5  # trunk beyond the 1-m half width
    env.sim.forward()
    _, _, done, extras = env.step(torch.zeros(2, 12))
    assert done[0] and not done[1]
    assert extras["log"]["Termination/fell"] >= 1


def test_time_out_is_a_truncation_after_the_trajectory_duration():
    env = make(2, domain_rand={"enabled": False}, trajectory={"duration_s": 0.1})
    static_platform(env)
    env.reset()
    assert env.max_episode_length == 5
    for i in range(5):
        _, _, done, extras = env.step(torch.zeros(2, 12))
        assert bool(done.all()) == (i == 4)
    assert extras["time_outs"].all()
    assert extras["log"]["Episode/success_rate"] == 1.0
    assert (env.episode_length_buf == 0).all()


def test_random_actions_for_100_steps_cause_no_fault_and_finite_observations():
    env = make(16, seed=5)
    gen = torch.Generator().manual_seed(1)
    for _ in range(100):
        obs, reward, done, extras = env.step(torch.rand(16, 12, generator=gen) * 2.0 - 1.0)
        for key, value in obs.items():
            assert torch.isfinite(value).all(), key
        assert torch.isfinite(reward).all()
        assert extras["log"]["/faults/count"] == 0.0
        assert extras["log"]["/faults/nonfinite_obs_values"] == 0.0
    assert env.fault_count == 0 and env.nonfinite_obs_values == 0


def test_diverging_env_is_terminated_reset_alone_and_no_nan_reaches_observations(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo writes its warning to MUJOCO_LOG.TXT in the working directory
    env = make(4, domain_rand={"enabled": False})
    static_platform(env)
    env.reset()
    # env 2: a joint velocity far beyond anything physical -> MuJoCo's instability check fires
    env.sim.qvel[2, env.index.joint_qvel[4]] = 1e12
    faults = 0
    for _ in range(20):
        obs, rew, done, extras = env.step(torch.zeros(4, 12))
        faults += extras["log"]["/faults/count"]
        assert all(torch.isfinite(v).all() for v in obs.values())
        assert torch.isfinite(rew).all()
        assert not done[[0, 1, 3]].any()
        if done[2]:
            break
    assert done[2] and not extras["time_outs"][2]
    assert faults >= 1 and env.fault_count >= 1
    # after its reset the env is healthy again
    for _ in range(20):
        obs, rew, done, extras = env.step(torch.zeros(4, 12))
    assert extras["log"]["/faults/count"] == 0 and not done.any()


def test_actions_of_wrong_shape_or_nan_are_refused():
    env = make(2)
    with pytest.raises(ValueError, match="shape"):
        env.step(torch.zeros(3, 12))
    bad = torch.zeros(2, 12)
    bad[1, 4] = float("nan")
    with pytest.raises(ValueError, match=r"NaN.*\[1\]"):
        env.step(bad)
