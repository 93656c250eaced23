"""The deployable export (`play.py --export onnx --out DIR`): the model and the metadata a robot
runtime needs without this repo (docs/deploy.md), checked against the checkpoint, the A1's constants,
the env that trained the policy and the torch policy itself."""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path

import numpy as np
import pytest
import torch
from omegaconf import OmegaConf

from lasmp.algo.checkpoint import read_checkpoint
from lasmp.cli.play import main
from lasmp.cli.train import train
from lasmp.deploy import load_deploy_env, obs_window
from lasmp.envs.robot import OBS_DIM
from lasmp.modules.export import METADATA_VERSION, SIDECAR_HASH_KEY, read_onnx_metadata
from lasmp.robots import a1

# not the defaults (20, 0.25, 4): the metadata must come from the checkpoint's config
HISTORY_LENGTH, ACTION_SCALE, DECIMATION = 12, 0.3, 5
DOC = Path(__file__).resolve().parents[2] / "docs" / "deploy.md"


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    """One tiny trained run with a non-default history length, action scale and decimation."""
    log_dir = tmp_path_factory.mktemp("export_run")
    cfg = {
        "env": {
            "num_envs": 4,
            "observations": {"history_length": HISTORY_LENGTH},
            "control": {"action_scale": ACTION_SCALE},
            "sim": {"decimation": DECIMATION},
        },
        "runner": {"max_iterations": 1, "log_dir": str(log_dir)},
        "policy": {"actor_hidden_dims": [32, 32], "critic_hidden_dims": [32, 32]},
        "algo": {"num_mini_batches": 2, "num_learning_epochs": 1},
        "torch_threads": 1,
    }
    train(OmegaConf.create(cfg))
    return log_dir


@pytest.fixture(scope="module")
def exported(run_dir, tmp_path_factory) -> Path:
    """The directory `play.py --export onnx` wrote, `deploy/` as in docs/deploy.md."""
    out = tmp_path_factory.mktemp("export_onnx") / "deploy"
    args = ["--checkpoint", str(run_dir), "--steps", "0", "--export", "onnx", "--out", str(out)]
    assert main(args) == 0
    return out


@pytest.fixture(scope="module")
def meta(exported) -> dict:
    return read_onnx_metadata(exported / "policy.onnx")


@pytest.fixture(scope="module")
def loaded(run_dir):
    return load_deploy_env(run_dir, num_envs=1, seed=5)


def recorded_window(env, policy, steps: int = 8):
    """(obs after `steps` policy steps, its window (1, H+1, 44)): a history that is not all o_0."""
    obs = env.get_observations()
    with torch.inference_mode():
        for _ in range(steps):
            obs = env.step(policy(obs))[0]
    return obs, obs_window(obs)


def test_export_writes_the_model_and_a_json_sidecar_holding_the_same_metadata(exported, meta):
    assert sorted(p.name for p in exported.iterdir()) == ["policy.json", "policy.onnx"]
    onnx = pytest.importorskip("onnx")
    props = onnx.load(str(exported / "policy.onnx")).metadata_props
    assert all(isinstance(p.value, str) for p in props)  # ONNX holds strings: each value is JSON
    sidecar = json.loads((exported / "policy.json").read_text())
    # the sidecar ties itself to the exact bytes of its ONNX file (docs/deploy.md's loader checks it)
    assert (
        sidecar.pop(SIDECAR_HASH_KEY) == hashlib.sha256((exported / "policy.onnx").read_bytes()).hexdigest()
    )
    assert meta == sidecar
    assert meta["metadata_version"] == METADATA_VERSION and meta["lasmp_version"]


def test_metadata_comes_from_the_checkpoint_and_the_a1_constants(run_dir, meta):
    data = read_checkpoint(run_dir)
    env_cfg = data["config"]["env"]
    assert meta["checkpoint_iteration"] == data["iter"]
    assert meta["checkpoint_file"] == Path(data["path"]).name
    assert meta["task"] == data["config"]["task"] == "moving_platform"
    assert meta["policy_name"] == data["config"]["policy"]["name"]
    assert meta["joint_names"] == list(a1.JOINT_NAMES)
    np.testing.assert_array_equal(meta["default_joint_pos_rad"], a1.Q_NOMINAL_RAD)
    np.testing.assert_array_equal(meta["joint_pos_limits_rad"], a1.JOINT_RANGE_RAD)
    assert meta["kp_nm_per_rad"] == [a1.KP_NOMINAL_NM_PER_RAD] * 12
    assert meta["kd_nm_s_per_rad"] == [a1.KD_NOMINAL_NM_S_PER_RAD] * 12
    assert meta["kp_training_range_nm_per_rad"] == env_cfg["domain_rand"]["train"]["joint_kp"]
    assert meta["kd_training_range_nm_s_per_rad"] == env_cfg["domain_rand"]["train"]["joint_kd"]
    assert meta["torque_limit_nm"] == [a1.TORQUE_LIMIT_NM] * 12
    assert meta["action_scale"] == ACTION_SCALE and meta["action_clip"] == env_cfg["control"]["action_clip"]
    assert meta["physics_dt_s"] == env_cfg["sim"]["dt_s"] and meta["decimation"] == DECIMATION
    assert meta["control_dt_s"] == pytest.approx(env_cfg["sim"]["dt_s"] * DECIMATION)
    assert meta["history_length"] == HISTORY_LENGTH
    assert meta["input_shape"] == [1, HISTORY_LENGTH + 1, OBS_DIM] and meta["output_shape"] == [1, 12]
    assert meta["obs_dim"] == OBS_DIM and meta["obs_clip"] == env_cfg["observations"]["clip"]


def test_obs_layout_slots_are_contiguous_and_sum_to_the_observation_size(meta):
    layout = meta["obs_layout"]
    assert [s["name"] for s in layout] == [
        "accelerometer",
        "gyro",
        "roll_pitch",
        "joint_pos",
        "joint_vel",
        "last_action",
    ]
    assert [s["size"] for s in layout] == [3, 3, 2, 12, 12, 12]
    assert sum(s["size"] for s in layout) == OBS_DIM
    assert [s["start"] for s in layout] == [0, 3, 6, 8, 20, 32]
    assert all(len(s["components"]) == s["size"] and s["unit"] and s["frame"] for s in layout)
    assert layout[3]["components"] == list(a1.JOINT_NAMES)


def test_obs_layout_describes_what_the_env_observes(loaded, meta):
    env, _, _, _ = loaded
    action = torch.linspace(-1.0, 1.0, 12).unsqueeze(0)
    with torch.inference_mode():
        obs = env.step(action)[0]
    o, r = obs["policy"][0].double(), env.readout
    slot = {s["name"]: o[s["start"] : s["start"] + s["size"]] for s in meta["obs_layout"]}
    q_default = torch.tensor(meta["default_joint_pos_rad"], dtype=torch.float64)
    close = {"rtol": 1e-6, "atol": 1e-6}
    torch.testing.assert_close(slot["accelerometer"], r.acc_imu_b[0], **close)
    torch.testing.assert_close(slot["gyro"], r.gyro_b[0], **close)
    torch.testing.assert_close(slot["roll_pitch"], r.phi_body_w[0, :2], **close)
    # relative to the default pose, as the metadata says
    torch.testing.assert_close(slot["joint_pos"], r.q[0] - q_default, **close)
    torch.testing.assert_close(slot["joint_vel"], r.q_dot[0], **close)
    torch.testing.assert_close(slot["last_action"], action[0].double(), **close)
    assert meta["joint_pos_convention"].startswith("relative")


def test_action_to_target_and_pd_gains_are_those_the_simulated_robot_uses(loaded, meta):
    env, _, _, _ = loaded
    action = torch.full((1, 12), 0.5)
    action[0, :3] = 3 * meta["action_clip"]  # beyond the clip
    with torch.inference_mode():
        env.step(action)
    a = np.clip(action[0].double().numpy(), -meta["action_clip"], meta["action_clip"])
    target = np.asarray(meta["default_joint_pos_rad"]) + meta["action_scale"] * a
    act = env.index.joint_act.numpy()
    np.testing.assert_allclose(env.sim.ctrl[0, act].cpu().numpy(), target, rtol=0, atol=1e-12)
    model = env.sim.model  # the nominal model (per-env gains are randomized around it in training)
    np.testing.assert_array_equal(model.actuator_ctrlrange[act], meta["joint_pos_limits_rad"])
    np.testing.assert_array_equal(model.actuator_forcerange[act, 1], meta["torque_limit_nm"])
    np.testing.assert_array_equal(model.actuator_gainprm[act, 0], meta["kp_nm_per_rad"])
    np.testing.assert_array_equal(-model.actuator_biasprm[act, 2], meta["kd_nm_s_per_rad"])
    assert env.dt_s == pytest.approx(meta["control_dt_s"])


def test_normalizer_is_folded_into_the_graph_and_given_for_reference(loaded, meta):
    _, policy, _, _ = loaded
    norm = meta["obs_normalization"]
    assert norm["folded_into_graph"] is True
    np.testing.assert_allclose(norm["mean"], policy.obs_normalizer._mean[0, :OBS_DIM].numpy(), rtol=1e-6)
    np.testing.assert_allclose(norm["std"], policy.obs_normalizer._std[0, :OBS_DIM].numpy(), rtol=1e-6)
    assert norm["eps"] == policy.obs_normalizer.eps


def test_onnx_model_on_a_recorded_window_matches_the_torch_policy(exported, loaded, meta):
    ort = pytest.importorskip("onnxruntime")
    sess = ort.InferenceSession(str(exported / "policy.onnx"), providers=["CPUExecutionProvider"])
    (inp,), (out,) = sess.get_inputs(), sess.get_outputs()
    assert (inp.name, list(inp.shape)) == (meta["input_name"], meta["input_shape"])
    assert (out.name, list(out.shape)) == (meta["output_name"], meta["output_shape"])
    env, policy, _, _ = loaded
    obs, window = recorded_window(env, policy)
    assert window.shape == tuple(meta["input_shape"])
    assert torch.equal(window[0, 0], obs["policy"][0]) and torch.equal(window[0, 1], obs["history"][0, 0])
    with torch.inference_mode():
        expected = policy(obs).numpy()
    (actions,) = sess.run(None, {meta["input_name"]: window.numpy()})
    np.testing.assert_allclose(actions, expected, rtol=0, atol=1e-5)
    # raw observations go in (the normalizer is inside): a normalized window gives other actions
    norm = meta["obs_normalization"]
    normalized = (window.numpy() - np.float32(norm["mean"])) / (np.float32(norm["std"]) + norm["eps"])
    (other,) = sess.run(None, {meta["input_name"]: normalized.astype(np.float32)})
    assert not np.allclose(other, expected, atol=1e-3)


def documented_loop(export_dir: Path, monkeypatch) -> dict:
    """The namespace of docs/deploy.md's Python block, run as written beside `export_dir` (deploy/)."""
    (code,) = re.findall(r"^```python\n(.*?)^```", DOC.read_text(), re.S | re.M)
    monkeypatch.chdir(export_dir.parent)
    namespace = {"__name__": "deploy_md"}
    exec(compile(code, str(DOC), "exec"), namespace)
    return namespace


def test_the_documented_loop_builds_the_simulators_window_and_sends_the_simulators_targets(
    exported, run_dir, monkeypatch
):
    ns = documented_loop(exported, monkeypatch)
    env, policy, _, _ = load_deploy_env(run_dir, num_envs=1, seed=7)  # a fresh episode: the loop starts
    act = env.index.joint_act.numpy()
    obs = env.get_observations()
    for _ in range(6):
        sent = ns["control_step"](obs["policy"][0].numpy())
        np.testing.assert_array_equal(ns["window"], obs_window(obs).numpy())
        with torch.inference_mode():
            obs, _, dones, _ = env.step(policy(obs))
        assert not dones.any()  # one episode: the window is never restarted
        # the target the simulator's PD tracks, from the torch policy's action
        np.testing.assert_allclose(sent, env.sim.ctrl[0, act].cpu().numpy(), rtol=0, atol=1e-5 * ACTION_SCALE)
        np.testing.assert_allclose(ns["last_action"], obs["policy"][0, -12:].numpy(), rtol=0, atol=1e-5)
