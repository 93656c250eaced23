"""Checkpoints written before the envs' classes moved or were renamed (the robot layer lost the
platform, the tasks' parts were named alike) still resume exactly: each task's
`_upgrade_run_state` reads the older form of its running state."""

from __future__ import annotations

import numpy as np
import torch

from lasmp.config import build_env_cfg
from lasmp.envs.moving_platform.env import MovingPlatformEnv
from lasmp.envs.rough_static.env import RoughStaticEnv
from lasmp.plainstate import pack


def make(cls, n: int, seed: int):
    env = cls(build_env_cfg({"num_envs": n, "seed": seed}, schema=cls.cfg_class))
    env.reset()
    return env


def resumes_alike(env, saved: dict) -> None:
    """An env of another seed loads `saved` (env's state, in an older form) and steps as env does."""
    resumed = make(type(env), env.num_envs, seed=env.cfg.seed + 1)
    assert resumed.load_state_dict(saved)
    resumed.rng.bit_generator.state = env.rng.bit_generator.state  # the runner restores it alike
    np.testing.assert_array_equal(resumed.intrinsics.x_imp(), env.intrinsics.x_imp())
    gen = torch.Generator().manual_seed(0)
    for _ in range(5):
        actions = 0.3 * torch.randn(env.num_envs, 12, generator=gen)
        assert torch.equal(env.step(actions)[0]["critic"], resumed.step(actions)[0]["critic"])


def test_a_moving_platform_checkpoint_holding_a_readout_resumes_exactly():
    """The readout was a `Readout` before it was named `SceneReadout`, for the scene it reads."""
    env = make(MovingPlatformEnv, 2, seed=0)
    env.step(torch.zeros(2, 12))
    saved = env.state_dict()
    saved["run"]["attrs"]["readout"]["class"] = "Readout"
    resumes_alike(env, saved)


def test_a_rough_static_checkpoint_whose_robots_carry_platform_factors_resumes_exactly():
    """While the robot layer drew the platform's gain factors for both tasks, R-S checkpoints held the
    robots as `Intrinsics`, with those factors, and the step state as a `RoughStepState`."""
    env = make(RoughStaticEnv, 3, seed=0)
    env.step(torch.zeros(3, 12))
    saved = env.state_dict()
    saved["run"]["attrs"]["last_state"]["class"] = "RoughStepState"
    intrinsics = saved["run"]["attrs"]["intrinsics"]
    intrinsics["class"] = "Intrinsics"  # the older form: the robot's fields, then the platform's
    intrinsics["fields"].update(
        platform_kp_factor=pack(np.ones((3, 6))), platform_kd_factor=pack(np.full((3, 6), 0.025))
    )
    resumes_alike(env, saved)
