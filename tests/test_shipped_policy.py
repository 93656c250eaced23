"""The policy shipped in resources/policies/: it loads on a fresh clone, acts in deployment mode
(estimators only, no privileged input), and its ONNX export computes the same actions."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from lasmp.algo.checkpoint import is_policy_only, read_checkpoint
from lasmp.deploy import load_deploy_env, obs_window

POLICIES = Path(__file__).resolve().parents[1] / "resources" / "policies"
CHECKPOINT = POLICIES / "lasmp_a1.pt"
ONNX = POLICIES / "lasmp_a1.onnx"
PRIVILEGED = ("priv_explicit", "priv_implicit", "alignment", "critic")


def test_shipped_checkpoint_is_a_small_lasmp_policy_checkpoint():
    assert CHECKPOINT.stat().st_size < 3_000_000
    data = read_checkpoint(CHECKPOINT)
    assert is_policy_only(data)
    assert data["config"]["task"] == "moving_platform" and data["config"]["policy"]["name"] == "lasmp"


def test_shipped_policy_runs_in_deployment_mode_without_privileged_inputs():
    env, policy, _, _ = load_deploy_env(CHECKPOINT, num_envs=2, seed=0)
    assert policy.deploy
    obs = env.get_observations()
    with torch.inference_mode():
        for _ in range(10):
            actions = policy(obs)
            assert actions.shape == (2, 12) and torch.isfinite(actions).all()
            scrambled = obs.clone()
            for group in PRIVILEGED:  # deployment must not read them
                scrambled[group] = torch.randn_like(scrambled[group]) * 100
            assert torch.equal(policy(scrambled), actions)
            obs = env.step(actions)[0]
    assert env.fault_count == 0


def test_shipped_onnx_export_matches_the_checkpoint():
    ort = pytest.importorskip("onnxruntime")
    env, policy, _, _ = load_deploy_env(CHECKPOINT, num_envs=1, seed=1)
    sess = ort.InferenceSession(str(ONNX), providers=["CPUExecutionProvider"])
    obs = env.get_observations()
    with torch.inference_mode():
        for _ in range(5):
            obs = env.step(policy(obs))[0]  # a history that is not all o_0
        expected = policy(obs).numpy()
    (actions,) = sess.run(None, {"obs_window": obs_window(obs).numpy()})
    np.testing.assert_allclose(actions, expected, atol=1e-4)
