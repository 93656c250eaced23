"""The shared robot layer (lasmp.envs.robot): fault screening, and one proprioceptive
observation for both tasks."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from lasmp.envs.moving_platform import env as moving_platform_env
from lasmp.envs.moving_platform.env import MovingPlatformEnv
from lasmp.envs.moving_platform.readout import Readout, read
from lasmp.envs.robot import OBS_DIM, as_slice, proprioception, read_robot, screen_faults, take_columns
from lasmp.envs.rough_static import env as rough_static_env
from lasmp.envs.rough_static.env import RoughStaticEnv
from lasmp.modules.obs_groups import GYRO_Z_COL
from lasmp.robots import a1

MAX_JOINT_VEL_RAD_S = 100.0


@pytest.fixture(scope="module")
def envs() -> tuple[MovingPlatformEnv, RoughStaticEnv]:
    mp, rs = MovingPlatformEnv({"num_envs": 4}), RoughStaticEnv({"num_envs": 4})
    for env in (mp, rs):
        env.reset()
    return mp, rs


def test_screen_faults_returns_the_faulted_envs_and_leaves_its_input_alone(envs):
    mp, _ = envs
    r = read(mp.sim, mp.index)  # a task's readout: the robot's fields and the platform's
    r.q_dot[0, 3] = np.nan  # env 0: a non-finite robot state
    r.v_plf_b[1, 0] = np.inf  # env 1: a non-finite platform quantity
    r.q_dot[2, 5] = 2.0 * MAX_JOINT_VEL_RAD_S  # env 2: a runaway joint, still finite
    before = copy.deepcopy(r)  # env 3: sound

    clean, faulted = screen_faults(r, MAX_JOINT_VEL_RAD_S)

    assert faulted.tolist() == [True, True, True, False]
    for name, value in vars(before).items():
        np.testing.assert_array_equal(getattr(r, name), value, err_msg=name)  # NaNs compare equal
    assert isinstance(clean, Readout)
    assert all(np.isfinite(value).all() for value in vars(clean).values())
    assert clean.q_dot[0, 3] == 0.0 and clean.v_plf_b[1, 0] == 0.0
    assert clean.q_dot[2, 5] == 2.0 * MAX_JOINT_VEL_RAD_S  # finite values are kept
    np.testing.assert_array_equal(clean.q[3], r.q[3])


def test_screen_faults_of_a_sound_readout_is_that_readout(envs):
    _, rs = envs
    r = read_robot(rs.sim, rs.index)
    clean, faulted = screen_faults(r, MAX_JOINT_VEL_RAD_S)
    assert clean is r and not faulted.any()


def test_both_tasks_observe_the_robot_with_the_same_proprioception(envs):
    assert moving_platform_env.proprioception is rough_static_env.proprioception is proprioception
    gen = torch.Generator().manual_seed(0)
    for env in envs:
        obs, _, _, _ = env.step(torch.rand(env.num_envs, 12, generator=gen) - 0.5)
        r = read_robot(env.sim, env.index)
        o = proprioception(r, env.action, torch.tensor(a1.Q_NOMINAL_RAD, dtype=env.dtype)).numpy()
        assert o.shape == (env.num_envs, OBS_DIM)
        np.testing.assert_array_equal(o[:, GYRO_Z_COL], r.gyro_b[:, 2].numpy())  # the column the actor reads
        clip = env.cfg.observations.clip
        np.testing.assert_array_equal(obs["policy"].numpy(), np.clip(o, -clip, clip).astype(np.float32))


def test_take_columns_copies_the_columns_as_a_slice_or_a_gather():
    x = torch.arange(40.0, dtype=torch.float64).view(4, 10)
    for index in (torch.tensor([2, 3, 4, 5]), torch.tensor([1, 3, 5]), torch.tensor([7, 2, 9])):
        cols = as_slice(index)
        assert isinstance(cols, slice) == (index.tolist() != [7, 2, 9])  # even runs become slices
        taken = take_columns(x, cols)
        assert torch.equal(taken, x.index_select(1, index))
        x[:, index] += 100.0  # a copy, not a view of the live array
        assert not torch.equal(taken, x.index_select(1, index))
