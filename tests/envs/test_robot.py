"""The shared robot layer (lasmp.envs.robot): fault screening, and one proprioceptive
observation for both tasks."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from lasmp.config.base import build_env_cfg
from lasmp.envs.moving_platform import env as moving_platform_env
from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
from lasmp.envs.moving_platform.env import MovingPlatformEnv
from lasmp.envs.moving_platform.readout import SceneReadout, read_scene
from lasmp.envs.robot import (
    OBS_DIM,
    as_slice,
    proprioception,
    read_robot,
    screen_faults,
    step_gait_phase,
    take_columns,
)
from lasmp.envs.rough_static import env as rough_static_env
from lasmp.envs.rough_static.cfg import RoughStaticCfg
from lasmp.envs.rough_static.env import RoughStaticEnv
from lasmp.modules.obs_groups import GYRO_Z_COL
from lasmp.robots import a1

MAX_JOINT_VEL_RAD_S = 100.0


@pytest.fixture(scope="module")
def envs() -> tuple[MovingPlatformEnv, RoughStaticEnv]:
    mp = MovingPlatformEnv(build_env_cfg({"num_envs": 4}, schema=MovingPlatformCfg))
    rs = RoughStaticEnv(build_env_cfg({"num_envs": 4}, schema=RoughStaticCfg))
    for env in (mp, rs):
        env.reset()
    return mp, rs


def test_screen_faults_returns_the_faulted_envs_and_leaves_its_input_alone(envs):
    mp, _ = envs
    r = read_scene(mp.sim, mp.index)  # a task's readout: the robot's fields and the platform's
    r.q_dot[0, 3] = np.nan  # env 0: a non-finite robot state
    r.v_plf_b[1, 0] = np.inf  # env 1: a non-finite platform quantity
    r.q_dot[2, 5] = 2.0 * MAX_JOINT_VEL_RAD_S  # env 2: a runaway joint, still finite
    before = copy.deepcopy(r)  # env 3: sound

    clean, faulted = screen_faults(r, MAX_JOINT_VEL_RAD_S)

    assert faulted.tolist() == [True, True, True, False]
    for name, value in vars(before).items():
        np.testing.assert_array_equal(getattr(r, name), value, err_msg=name)  # NaNs compare equal
    assert isinstance(clean, SceneReadout)
    assert all(torch.isfinite(torch.as_tensor(value)).all() for value in vars(clean).values())
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


def test_gait_phase_events_and_the_phases_that_end():
    """One foot (of 4, one env): air 3 steps, contact 2, air 1, contact; dt 0.5 s."""
    dt = 0.5
    contact_prev = torch.zeros(1, 4, dtype=torch.bool)
    t_air, t_contact = torch.zeros(1, 4, dtype=torch.float64), torch.zeros(1, 4, dtype=torch.float64)
    seen = []
    for c in (0, 0, 0, 1, 1, 0, 1):
        contact = torch.tensor([[bool(c), False, True, False]])
        g = step_gait_phase(contact, contact_prev, t_air, t_contact, dt)
        seen.append(
            (
                bool(g.touchdown[0, 0]),
                bool(g.liftoff[0, 0]),
                float(g.t_air_s[0, 0]),
                float(g.t_contact_s[0, 0]),
            )
        )
        assert torch.equal(contact_prev, contact)
    assert seen == [(False, False, 0.0, 0.0)] * 3 + [
        (True, False, 1.5, 0.0),
        (False, False, 0.0, 0.0),
        (False, True, 0.0, 1.0),
        (True, False, 0.5, 0.0),
    ]
    # foot 2 stands from the start: a touchdown at the first step, after no air time; foot 3 never lands
    assert (t_contact[0, 2], t_air[0, 3], t_air[0, 2], t_contact[0, 3]) == (7 * dt, 7 * dt, 0.0, 0.0)
    # a task that does not track contact phases
    assert step_gait_phase(contact, contact_prev, t_air, None, dt).t_contact_s is None


def test_gait_phase_keeps_a_copy_of_the_contacts_not_the_readouts_own():
    """A reset sets rows of the task's `contact_prev` to False, and the moving-platform readout is
    updated in place where envs reset: neither may change the other."""
    contact_prev = torch.zeros(2, 4, dtype=torch.bool)
    contact = torch.ones(2, 4, dtype=torch.bool)  # the readout's foot_contact
    step_gait_phase(contact, contact_prev, torch.zeros(2, 4), torch.zeros(2, 4), 0.02)
    contact_prev[1] = False  # a reset of env 1
    assert contact.all()
    contact[0] = False  # the readout's row 0 read anew
    assert contact_prev[0].all()
