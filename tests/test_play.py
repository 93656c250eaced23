"""play.py: deployment-mode rollouts from a checkpoint's own config, rendering, export, errors."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from omegaconf import OmegaConf

from lasmp.play import load_deploy_policy, main, obs_window
from lasmp.train import train

ROOT = Path(__file__).resolve().parents[1]
LATENT_DIM = 8  # not the default (16): play must take it from the checkpoint
PRIVILEGED = ("priv_explicit", "priv_implicit", "alignment", "critic")


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    """One tiny trained run (model_0.pt) with a non-default policy shape."""
    log_dir = tmp_path_factory.mktemp("play_run")
    cfg = {
        "env": {"num_envs": 4},
        "runner": {"max_iterations": 1, "log_dir": str(log_dir)},
        "policy": {
            "latent_dim": LATENT_DIM,
            "actor_hidden_dims": [32, 32, 32],
            "critic_hidden_dims": [32, 32],
        },
        "algo": {"num_mini_batches": 2, "num_learning_epochs": 1},
        "torch_threads": 1,
    }
    train(OmegaConf.create(cfg))
    assert list(log_dir.glob("model_*.pt"))
    return log_dir


@pytest.fixture(scope="module")
def loaded(run_dir):
    return load_deploy_policy(run_dir, num_envs=1, seed=3)


def test_play_runs_and_prints_summary(run_dir, capsys):
    assert main(["--checkpoint", str(run_dir), "--steps", "50", "--num-envs", "2"]) == 0
    out = capsys.readouterr().out
    assert "played 50 steps x 2 envs" in out
    assert "episodes ended" in out and "collisions" in out and "mean reward per step" in out


def test_policy_from_checkpoint_config_and_deploy_ignores_privileged(loaded):
    env, policy, cfg = loaded
    assert cfg.policy.latent_dim == LATENT_DIM and cfg.env.num_envs == 1 and cfg.seed == 3
    assert policy.latent_dim == LATENT_DIM and policy.deploy and not policy.training
    assert policy.mlp[0].out_features == 32  # the checkpoint's hidden dims, not today's 512
    obs = env.get_observations()
    nan_obs = obs.clone()
    for group in PRIVILEGED:
        nan_obs[group] = torch.full_like(nan_obs[group], float("nan"))
    with torch.inference_mode():
        actions = policy(obs)
        assert torch.isfinite(actions).all()
        torch.testing.assert_close(policy(nan_obs), actions, rtol=0, atol=0)


def test_export_onnx_matches_torch(run_dir, loaded, tmp_path, capsys):
    ort = pytest.importorskip("onnxruntime")
    assert (
        main(["--checkpoint", str(run_dir), "--steps", "0", "--export", "onnx", "--out", str(tmp_path)]) == 0
    )
    path = tmp_path / "policy.onnx"
    assert str(path) in capsys.readouterr().out
    assert os.listdir(tmp_path) == ["policy.onnx"]  # self-contained, no temp file left
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    assert [i.name for i in sess.get_inputs()] == ["obs_window"]
    env, policy, _ = loaded
    with torch.inference_mode():
        obs, *_ = env.step(torch.zeros(1, env.num_actions))  # a history that is not all o_0
        expected = policy(obs).numpy()
    (actions,) = sess.run(None, {"obs_window": obs_window(obs).numpy()})
    np.testing.assert_allclose(actions, expected, atol=1e-5)


def test_export_jit_matches_torch(run_dir, loaded, tmp_path):
    assert (
        main(["--checkpoint", str(run_dir), "--steps", "0", "--export", "jit", "--out", str(tmp_path)]) == 0
    )
    scripted = torch.jit.load(str(tmp_path / "policy.pt"))
    env, policy, _ = loaded
    with torch.inference_mode():
        obs = env.get_observations()
        torch.testing.assert_close(scripted(obs_window(obs)), policy(obs), atol=1e-5, rtol=1e-5)


def test_video_and_snapshots(run_dir, tmp_path):
    video, snaps = tmp_path / "play.mp4", tmp_path / "snaps.png"
    args = ["--checkpoint", str(run_dir), "--steps", "10", "--video", str(video), "--snapshots", str(snaps)]
    assert main(args) == 0
    assert video.stat().st_size > 0
    imageio = pytest.importorskip("imageio.v2")
    with imageio.get_reader(str(video)) as reader:
        assert reader.count_frames() == 10
    from matplotlib import image

    strip = image.imread(str(snaps))
    assert strip.shape[:2] == (480, 6 * 640)
    assert strip[..., :3].std() > 0  # not a blank image


def test_truncated_checkpoint_exits_2(run_dir, tmp_path, capsys):
    bad = tmp_path / "model_5.pt"
    data = (run_dir / "model_0.pt").read_bytes()
    bad.write_bytes(data[: len(data) // 2])
    assert main(["--checkpoint", str(bad), "--steps", "1"]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "Traceback" not in err


def test_missing_checkpoint_exits_2_without_traceback(tmp_path):
    missing = tmp_path / "nope" / "model_3.pt"
    proc = subprocess.run(
        [sys.executable, str(ROOT / "play.py"), "--checkpoint", str(missing)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    assert proc.returncode == 2
    assert str(missing) in proc.stderr
    assert "Traceback" not in proc.stderr


def test_viewer_without_display_exits_with_message(run_dir, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["--checkpoint", str(run_dir), "--viewer"]) == 2
    assert "display" in capsys.readouterr().err.lower()


def test_export_needs_out(run_dir):
    with pytest.raises(SystemExit) as exc:
        main(["--checkpoint", str(run_dir), "--export", "onnx"])
    assert exc.value.code == 2


def test_benchmark_episode_plays_that_trajectory_and_robot(run_dir, tmp_path, capsys):
    from lasmp.eval import benchmark as bm
    from lasmp.play import load_deploy_policy, use_benchmark_episodes

    bench_path = tmp_path / "bench.npz"
    bench = bm.generate(num_trajectories=6, num_robots=2, seed=0)
    bm.save(bench_path, bench)
    env, _, _ = load_deploy_policy(str(run_dir), num_envs=1)
    use_benchmark_episodes(env, str(bench_path), 3)
    pose_env, _, _ = env.traj.evaluate(np.array([2.0]))
    pose_bench, _, _ = bench.trajectories.evaluate(np.array([2.0]), rows=[3])
    assert np.array_equal(pose_env, pose_bench)
    assert env.intrinsics.trunk_mass_kg[0] == bench.robots.trunk_mass_kg[3 % 2]
    assert main(["--checkpoint", str(run_dir), "--benchmark", str(bench_path), "--benchmark-episode", "9",
                 "--steps", "1"]) == 2  # fmt: skip
    assert "--benchmark-episode must be in [0, 5]" in capsys.readouterr().err
