"""Checkpoints whose running state names the envs' classes or fields otherwise (a `Readout` for the
`SceneReadout`; R-S robots as `Intrinsics` with the platform's factors, the step state as a
`RoughStepState` with `body_contact`) resume exactly: `read_checkpoint` renames them by the table
`lasmp.algo.checkpoint.RENAMED_RUN_STATE`, and the envs carry one name per class."""

from __future__ import annotations

import numpy as np
import torch

from lasmp.algo.checkpoint import CHECKPOINT_FORMAT, read_checkpoint
from lasmp.config.base import build_env_cfg
from lasmp.envs.moving_platform.env import MovingPlatformEnv
from lasmp.envs.rough_static.env import RoughStaticEnv
from lasmp.io.plainstate import pack


def make(cls, n: int, seed: int):
    env = cls(build_env_cfg({"num_envs": n, "seed": seed}, schema=cls.cfg_class))
    env.reset()
    return env


def read_back(saved: dict, task: str, path) -> dict:
    """`saved` (an env's state) through a checkpoint file of `task`, as every command reads one."""
    data = {
        "format": CHECKPOINT_FORMAT,
        "actor_state_dict": {},
        "critic_state_dict": {},
        "config": {"task": task},
        "obs_layout": {},
        "num_actions": 12,
        "iter": 0,
        "env_state": saved,
    }
    torch.save(data, path)
    return read_checkpoint(path)["env_state"]


def resumes_alike(env, saved: dict) -> None:
    """An env of another seed loads `saved` (env's state, as read back) and steps as env does."""
    resumed = make(type(env), env.num_envs, seed=env.cfg.seed + 1)
    assert resumed.load_state_dict(saved)
    resumed.rng.bit_generator.state = env.rng.bit_generator.state  # the runner restores it alike
    np.testing.assert_array_equal(resumed.intrinsics.x_imp(), env.intrinsics.x_imp())
    gen = torch.Generator().manual_seed(0)
    for _ in range(5):
        actions = 0.3 * torch.randn(env.num_envs, 12, generator=gen)
        assert torch.equal(env.step(actions)[0]["critic"], resumed.step(actions)[0]["critic"])


def test_a_moving_platform_checkpoint_holding_a_readout_resumes_exactly(tmp_path):
    env = make(MovingPlatformEnv, 2, seed=0)
    env.step(torch.zeros(2, 12))
    saved = env.state_dict()
    saved["run"]["attrs"]["readout"]["class"] = "Readout"
    resumes_alike(env, read_back(saved, "moving_platform", tmp_path / "model_0.pt"))


def test_a_rough_static_checkpoint_whose_robots_carry_platform_factors_resumes_exactly(tmp_path):
    """R-S robots held as `Intrinsics`, with the platform's gain factors; the step state as a
    `RoughStepState` whose collision field is `body_contact`."""
    env = make(RoughStaticEnv, 3, seed=0)
    env.step(torch.zeros(3, 12))
    saved = env.state_dict()
    step_state = saved["run"]["attrs"]["last_state"]
    step_state["class"] = "RoughStepState"
    step_state["fields"] = {
        ("body_contact" if k == "collision" else k): v for k, v in step_state["fields"].items()
    }
    intrinsics = saved["run"]["attrs"]["intrinsics"]
    intrinsics["class"] = "Intrinsics"  # the robot's fields, then the platform's
    intrinsics["fields"].update(
        platform_kp_factor=pack(np.ones((3, 6))), platform_kd_factor=pack(np.full((3, 6), 0.025))
    )
    resumes_alike(env, read_back(saved, "rough_static", tmp_path / "model_0.pt"))


def test_a_rough_static_step_state_with_body_contact_resumes_exactly(tmp_path):
    env = make(RoughStaticEnv, 2, seed=0)
    env.step(torch.zeros(2, 12))
    saved = env.state_dict()
    fields = saved["run"]["attrs"]["last_state"]["fields"]
    fields["body_contact"] = fields.pop("collision")
    resumes_alike(env, read_back(saved, "rough_static", tmp_path / "model_0.pt"))


def test_the_envs_carry_no_renaming():
    """The renames live in the checkpoint reader alone: the envs restore what they save, by one name."""
    for cls in (MovingPlatformEnv, RoughStaticEnv):
        assert not hasattr(cls, "RENAMED_RUN_STATE") and not hasattr(cls, "_upgrade_run_state")
