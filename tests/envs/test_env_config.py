"""The batched moving-platform env's configuration and trajectory source: each trajectory kind,
a trajectory file replayed row by row, the curriculum's state, and bad configuration refused naming
the field."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from testkit import platform_env as make

from lasmp.config.base import build_env_cfg
from lasmp.config.checks import ConfigError
from lasmp.envs import trajectories as trj
from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
from lasmp.envs.moving_platform.env import MovingPlatformEnv


def test_env_builds_and_steps_each_trajectory_kind():
    for kind in ("approximating", "interpolating"):
        env = make(4, trajectory={"kind": kind})
        assert np.all(env.traj.kind == trj.KIND_NAMES.index(kind))
        for _ in range(5):
            obs, _, _, _ = env.step(torch.zeros(4, 12))
        assert torch.isfinite(obs["policy"]).all()


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


def test_missing_trajectory_file_fails_with_its_name(tmp_path):
    missing = tmp_path / "nope.npz"
    with pytest.raises(trj.TrajectoryFileError, match="nope.npz"):
        MovingPlatformEnv(
            build_env_cfg({"num_envs": 1, "trajectory": {"file": str(missing)}}, schema=MovingPlatformCfg)
        )


def test_curriculum_state_round_trips_through_the_env():
    env = make(2)
    env.curriculum._level = 9
    state = env.state_dict()
    other = make(2)
    other.load_state_dict(state)
    assert other.curriculum.level == 9


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
