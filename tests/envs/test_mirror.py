"""The sagittal mirror of the moving-platform task: the maps are involutions, and the physics agrees
with them (a state and its mirror image, stepped under an action and its mirror, stay mirror images)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from tensordict import TensorDict

from lasmp.config.base import build_env_cfg
from lasmp.envs import mirror as m
from lasmp.envs.moving_platform import mirror as mm
from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
from lasmp.envs.moving_platform.env import MovingPlatformEnv
from lasmp.eval import benchmark as bm
from lasmp.eval.run import intrinsics_rows
from lasmp.robots import a1

COM_Y = 0.002186


def _random_groups(n: int = 5) -> TensorDict:
    g = torch.Generator().manual_seed(1)
    sizes = {"policy": 44, "priv_explicit": 13, "priv_implicit": 29, "alignment": 3, "critic": 95}
    groups = {k: torch.randn(n, w, generator=g) for k, w in sizes.items()}
    groups["history"] = torch.randn(n, 20, 44, generator=g)
    return TensorDict(groups, batch_size=[n])


def test_mirroring_every_observation_group_and_the_actions_twice_is_the_identity():
    mirror = mm.ObservationMirror(COM_Y)
    obs = _random_groups()
    twice = mirror(mirror(obs))
    for key in obs.keys():
        torch.testing.assert_close(twice[key], obs[key], msg=key)
        assert not torch.allclose(mirror(obs)[key], obs[key]), f"{key}: the mirror changes nothing"
    a = torch.randn(5, 12)
    torch.testing.assert_close(mm.ACTIONS(mm.ACTIONS(a)), a)


def test_the_critic_map_is_the_concatenation_of_the_parts_it_holds():
    mirror = mm.ObservationMirror(COM_Y)
    obs = _random_groups()
    # the critic's columns [o, x_exp, x_imp, u_aln, ...] (env.py) mirror as their groups do
    parts = {"policy": (0, 44), "priv_explicit": (44, 57), "priv_implicit": (57, 86), "alignment": (86, 89)}
    critic = obs["critic"].clone()
    for key, (lo, hi) in parts.items():
        critic[:, lo:hi] = obs[key]
    mirrored = mirror(TensorDict({"critic": critic, **{k: obs[k] for k in parts}}, batch_size=[5]))
    for key, (lo, hi) in parts.items():
        torch.testing.assert_close(mirrored["critic"][:, lo:hi], mirrored[key], msg=key)


def test_the_world_mirror_twice_is_the_identity():
    bench = bm.generate(num_trajectories=3, num_robots=3, seed=0)
    traj = mm.mirror_trajectories(mm.mirror_trajectories(bench.trajectories))
    np.testing.assert_array_equal(traj.coeffs, bench.trajectories.coeffs)
    robots = mm.mirror_intrinsics(mm.mirror_intrinsics(bench.robots, COM_Y), COM_Y)
    for name, value in vars(bench.robots).items():
        np.testing.assert_allclose(getattr(robots, name), value, atol=1e-15, err_msg=name)
    init = MovingPlatformCfg().init_state
    u = bench.initial_pose_draws(np.arange(3))
    np.testing.assert_allclose(mm.mirror_pose_uniforms(mm.mirror_pose_uniforms(u, init), init), u, atol=1e-15)


def test_a_map_that_is_not_a_signed_permutation_and_an_unmapped_group_are_refused():
    with pytest.raises(ValueError, match="signed permutation"):
        m.block((0, 0, 2), (1, 1, 1))
    obs = TensorDict({"policy": torch.zeros(2, 44), "secret": torch.zeros(2, 3)}, batch_size=[2])
    with pytest.raises(KeyError, match="secret"):
        mm.ObservationMirror(COM_Y)(obs)


def test_the_mirror_keeps_the_nominal_stance_and_swaps_each_legs_gains():
    q_nom = torch.tensor(a1.Q_NOMINAL_RAD)  # a copy: the constant is read-only
    torch.testing.assert_close(m.JOINT_ANGLES(q_nom), q_nom)  # hips +-0.1 swap sides and signs
    kp = torch.arange(12.0)
    assert m.JOINT_GAINS(kp)[:3].tolist() == [3.0, 4.0, 5.0]  # FR takes FL's


class _Episodes:
    """Benchmark episodes 0..n-1 for envs 0..n-1, or their mirror images."""

    def __init__(self, bench, mirrored: bool, init, com_y: float):
        self.bench, self.mirrored, self.init, self.com_y = bench, mirrored, init, com_y

    def next_episodes(self, ids):
        k = np.asarray(ids)
        traj = self.bench.trajectories.subset(k)
        robots = intrinsics_rows(self.bench.robots, k)
        pose = self.bench.initial_pose_draws(k)
        if self.mirrored:
            traj = mm.mirror_trajectories(traj)
            robots = mm.mirror_intrinsics(robots, self.com_y)
            pose = mm.mirror_pose_uniforms(pose, self.init)
        return traj, traj.n_waypoints, robots, pose


def test_physics_a_state_and_its_mirror_image_stay_mirror_images_under_mirrored_actions():
    """Two copies of 4 benchmark episodes (test ranges: CoM shifts to 0.25 m, the 2.2 mm nominal CoM y,
    per-joint gains), one mirrored; 80 steps (1.6 s) of smooth random actions, and their mirror images.
    Every observation column must agree within 0.5 % of its range over the run (the solver's tolerance:
    measured up to 0.15 % on the accelerometer), and every column must vary enough that a wrong sign
    or a wrong swap in any slot of the map would break that."""
    bench = bm.generate(num_trajectories=4, num_robots=4, seed=0)
    envs = []
    for mirrored in (False, True):
        env = MovingPlatformEnv(build_env_cfg({"num_envs": 4, "seed": 0}, schema=MovingPlatformCfg))
        env.episode_source = _Episodes(bench, mirrored, env.cfg.init_state, env.nominal_com_y_m)
        env.reset()
        envs.append(env)
    original, mirrored = envs
    g = torch.Generator().manual_seed(0)
    a = torch.zeros(4, 12)
    expected, got = [], []
    for _ in range(80):
        a = 0.8 * a + 0.1 * torch.randn(4, 12, generator=g)
        obs_a, _, done_a, _ = original.step(a)
        obs_b, _, done_b, _ = mirrored.step(original.mirror_actions(a))
        assert torch.equal(done_a, done_b)
        assert not done_a.any(), "an episode ended: the comparison needs all 80 steps"
        expected.append(original.mirror_observations(obs_a)["critic"])
        got.append(obs_b["critic"])
    expected, got = torch.stack(expected), torch.stack(got)  # (T, n, 95): every group is a part of it
    scale = got.abs().amax(dim=(0, 1))
    err = (expected - got).abs().amax(dim=(0, 1))
    tol = 0.005 * scale + 1e-6
    bad = torch.nonzero(err > tol).flatten().tolist()
    assert not bad, f"critic columns {bad} are not mirror images: errors {err[bad]}, scale {scale[bad]}"
    # a wrong sign in column c would give errors of 2 |x_c|; a wrong swap, |x_c - x_c'|
    flipped = (expected + got).abs().amax(dim=(0, 1))
    assert torch.all(flipped > tol), (
        f"columns {torch.nonzero(flipped <= tol).flatten().tolist()} cannot catch a sign"
    )


def test_a_training_hold_lengthens_the_episode_and_evaluation_plays_xi_eval_at_t():
    from lasmp.eval.build import deep_merge, eval_env_overrides

    held = {"num_envs": 2, "trajectory": {"hold_s": 2.0}}
    env = MovingPlatformEnv(build_env_cfg(held, schema=MovingPlatformCfg))
    assert env.max_episode_length == 600  # (10 s + 2 s) / 0.02 s
    pose, vel = env.traj_dev.evaluate(torch.tensor([10.0, 11.5]), torch.tensor([0, 0]))
    torch.testing.assert_close(pose[1], pose[0])  # after T the reference holds its last pose
    assert torch.all(vel[1] == 0)
    evaluated = MovingPlatformEnv(
        build_env_cfg(deep_merge(held, eval_env_overrides(2, 0)), schema=MovingPlatformCfg)
    )
    assert evaluated.max_episode_length == 500
