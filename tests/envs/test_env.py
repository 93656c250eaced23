"""The batched moving-platform env: shapes, frames and signs, resets, randomization, faults,
determinism, equality with a serial mj_step loop, and bad configuration."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
import torch

from lasmp.config import ConfigError, build_env_cfg
from lasmp.envs import trajectories as trj
from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
from lasmp.envs.moving_platform.domain_rand import nominal_intrinsics
from lasmp.envs.moving_platform.env import MovingPlatformEnv
from lasmp.envs.robot import as_numpy
from lasmp.robots import a1

G = 9.81


def static_platform(env: MovingPlatformEnv) -> None:
    """Make every later reset use a platform that does not move."""

    def hold(ids):
        return trj.from_samples(np.array([0.0, 10.0]), np.zeros((len(ids), 2, 6))), np.full(len(ids), -1)

    env._next_trajectories = hold


def make(n=4, **cfg) -> MovingPlatformEnv:
    env = MovingPlatformEnv(build_env_cfg({"num_envs": n, **cfg}, schema=MovingPlatformCfg))
    env.reset()
    return env


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


def test_env_builds_and_steps_each_trajectory_kind():
    for kind in ("approximating", "interpolating"):
        env = make(4, trajectory={"kind": kind})
        assert np.all(env.traj.kind == trj.KIND_NAMES.index(kind))
        for _ in range(5):
            obs, _, _, _ = env.step(torch.zeros(4, 12))
        assert torch.isfinite(obs["policy"]).all()


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


def test_domain_randomization_writes_per_env_model_parameters_within_ranges():
    for split, lo_mass, hi_mass in (("train", 4.0, 5.0), ("test", 3.5, 5.5)):
        env = make(64, domain_rand={"split": split})
        p = env.intrinsics
        assert lo_mass <= p.trunk_mass_kg.min() and p.trunk_mass_kg.max() <= hi_mass
        assert p.trunk_mass_kg.std() > 0.1
        trunk = env.sim.model.body("trunk").id
        assert np.allclose(env.sim.batch.expanded("body_mass")[:, trunk], p.trunk_mass_kg)
        ipos = env.sim.batch.expanded("body_ipos")[:, trunk]
        assert np.allclose(ipos - env.sim.model.body_ipos[trunk], p.com_shift_m)
        act = env.sim.model.actuator("FL_thigh_joint").id
        j = a1.JOINT_NAMES.index("FL_thigh_joint")
        assert np.allclose(env.sim.batch.expanded("actuator_gainprm")[:, act, 0], p.joint_kp[:, j])
        assert np.allclose(env.sim.batch.expanded("actuator_biasprm")[:, act, 2], -p.joint_kd[:, j])
        foot = env.sim.model.geom("RR_foot").id
        assert np.allclose(env.sim.batch.expanded("geom_friction")[:, foot, 0], p.foot_friction)
        x_imp = env.get_observations()["priv_implicit"].double().numpy()
        assert np.allclose(x_imp[:, 0], p.trunk_mass_kg, atol=1e-5)
        assert np.allclose(x_imp[:, 5:17], p.joint_kp, atol=1e-4)


def test_randomized_joint_gains_change_the_dynamics():
    """The per-env Kp written through Batch.expand is the one the physics uses."""
    env = make(2, domain_rand={"enabled": False})
    static_platform(env)
    env.reset()
    params = nominal_intrinsics(1, env.cfg.platform.kd_factor_ref)
    params.joint_kp[:] = 80.0
    env.writer.write(np.array([1]), params)
    for _ in range(50):
        env.step(torch.zeros(2, 12))
    h = env.readout.p_body_p[:, 2]
    assert h[1] > h[0] + 0.005, h  # stiffer joints sag less


def test_same_seed_gives_identical_observations_over_100_steps():
    def run(seed):
        env = make(8, seed=seed)
        gen = torch.Generator().manual_seed(0)
        out = []
        for _ in range(100):
            obs = env.step(0.3 * torch.randn(8, 12, generator=gen))[0]
            out.append(obs["critic"].clone())
        return torch.stack(out)

    a, b, c = run(3), run(3), run(4)
    assert torch.equal(a, b)
    assert not torch.equal(a, c)


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


def test_batched_step_equals_a_serial_mj_step_loop():
    env = make(4)
    for _ in range(10):
        env.step(0.5 * torch.randn(4, 12))
    actions = torch.from_numpy(0.5 * np.random.default_rng(0).standard_normal((4, 12)))  # float64
    env._apply_actions(actions)  # ctrl and act set
    batch = env.sim.batch
    models = [batch.get_model(i) for i in range(4)]  # with each env's randomized parameters
    datas = [batch.get_data(i) for i in range(4)]  # state, controls and servo targets
    assert not env.sim.step(env.cfg.sim.decimation).any()
    for i in range(4):
        for _ in range(env.cfg.sim.decimation):
            mujoco.mj_step(models[i], datas[i])
        assert np.array_equal(datas[i].qpos, env.sim.qpos[i].numpy()), i
        assert np.array_equal(datas[i].qvel, env.sim.qvel[i].numpy()), i


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


def test_curriculum_state_round_trips_through_the_env():
    env = make(2)
    env.curriculum._level = 9
    state = env.state_dict()
    other = make(2)
    other.load_state_dict(state)
    assert other.curriculum.level == 9


def test_actions_of_wrong_shape_or_nan_are_refused():
    env = make(2)
    with pytest.raises(ValueError, match="shape"):
        env.step(torch.zeros(3, 12))
    bad = torch.zeros(2, 12)
    bad[1, 4] = float("nan")
    with pytest.raises(ValueError, match=r"NaN.*\[1\]"):
        env.step(bad)


@pytest.mark.parametrize(
    "overrides, field",
    [
        ({"num_envs": 0}, "env.num_envs"),
        ({"sim": {"dt_s": -0.1}}, "env.sim.dt_s"),
        ({"domain_rand": {"split": "val"}}, "env.domain_rand.split"),
        ({"domain_rand": {"train": {"trunk_mass_kg": [5.0, 4.0]}}}, "env.domain_rand.train.trunk_mass_kg"),
        ({"rewards": {"weights": {"task9_dance": 1.0}}}, "task9_dance"),
        ({"platform": {"mass_kg": 0}}, "env.platform.mass_kg"),
        ({"curriculum": {"promote_success_rate": 1.5}}, "env.curriculum.promote_success_rate"),
        ({"sim": {"dt": 0.01}}, "dt"),  # a typo of dt_s: unknown key
        ({"trajectory": {"kind": "bezier"}}, "env.trajectory.kind"),
        ({"trajectory": {"degree": 2}}, "env.trajectory.degree"),
        ({"sim": {"cone": "round"}}, "env.sim.cone"),
        ({"sim": {"noslip_iterations": -1}}, "env.sim.noslip_iterations"),
        ({"init_state": {"xy_offset_max_m": 0.9}}, "env.init_state.xy_offset_max_m"),
        ({"platform": {"omega_n_rad_s": 0.0}}, "env.platform.omega_n_rad_s"),
        ({"rewards": {"h_des_from": "floor"}}, "env.rewards.h_des_from"),
    ],
)
def test_invalid_config_fails_at_start_up_naming_the_field(overrides, field):
    with pytest.raises(ConfigError, match=field.replace(".", r"\.")):
        build_env_cfg(overrides, schema=MovingPlatformCfg)


def test_unknown_reward_error_lists_the_valid_terms():
    with pytest.raises(ConfigError, match="task1_center"):
        build_env_cfg({"rewards": {"weights": {"task1_centre": 1.0}}}, schema=MovingPlatformCfg)


def test_missing_trajectory_file_fails_with_its_name(tmp_path):
    missing = tmp_path / "nope.npz"
    with pytest.raises(trj.TrajectoryFileError, match="nope.npz"):
        MovingPlatformEnv(
            build_env_cfg({"num_envs": 1, "trajectory": {"file": str(missing)}}, schema=MovingPlatformCfg)
        )


def test_trajectory_file_rows_are_replayed_in_order(tmp_path):
    path = tmp_path / "set.npz"
    traj = trj.sample(3, trj.ranges_for_split("test"), np.random.default_rng(0))
    trj.save(path, traj)
    env = make(2, trajectory={"file": str(path)})
    assert env.curriculum is None
    assert env.traj_level.tolist() == traj.n_waypoints[:2].tolist()
    pose_env, _, _ = env.traj.evaluate(np.full(2, 3.0))
    pose_file, _, _ = traj.evaluate(np.full(2, 3.0), rows=[0, 1])
    assert np.array_equal(pose_env, pose_file)


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
