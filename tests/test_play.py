"""play.py: deployment-mode rollouts from a checkpoint's own config, rendering, export, errors; the curriculum probe."""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch
from omegaconf import OmegaConf
from testkit import load_script

from lasmp.deploy import load_deploy_env, obs_window
from lasmp.play import main
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
    return load_deploy_env(run_dir, num_envs=1, seed=3)


def test_play_runs_and_prints_summary(run_dir, capsys):
    from lasmp.algo.checkpoint import latest_checkpoint

    assert main(["--checkpoint", str(run_dir), "--steps", "50", "--num-envs", "2"]) == 0
    out = capsys.readouterr().out
    newest = latest_checkpoint(run_dir)  # the file the run directory stands for
    assert f"loaded {newest} (iteration 0, task moving_platform)" in out
    assert "played 50 steps x 2 envs" in out
    assert "episodes ended" in out and "collisions" in out and "mean reward per step" in out


def test_a_seed_gives_other_episodes_and_no_seed_continues_the_checkpoints_own_streams(run_dir):
    def first_episode(seed):
        env, _, cfg, _ = load_deploy_env(run_dir, num_envs=1, seed=seed)
        pose, _, _ = env.traj.evaluate(np.array([2.0]))
        return cfg.seed, pose, env.intrinsics.trunk_mass_kg.copy()

    (s1, pose1, mass1), (_, pose1b, mass1b), (s2, pose2, mass2) = map(first_episode, (1, 1, 2))
    assert (s1, s2) == (1, 2)
    assert np.array_equal(pose1, pose1b) and np.array_equal(mass1, mass1b)
    assert not np.array_equal(pose1, pose2) and not np.array_equal(mass1, mass2)
    (own, pose_own, _), (_, pose_own_b, _) = first_episode(None), first_episode(None)
    assert own == 0 and np.array_equal(pose_own, pose_own_b)  # the run's seed, its streams at the save
    assert not np.array_equal(pose_own, first_episode(0)[1])  # not its seed's fresh streams


def test_policy_from_checkpoint_config_and_deploy_ignores_privileged(loaded):
    env, policy, cfg, _ = loaded
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


def test_export_onnx_matches_torch_and_says_nothing_else(run_dir, loaded, tmp_path, capsys):
    ort = pytest.importorskip("onnxruntime")
    from lasmp.modules.export import _TORCH_ONNX_REGISTRY_LOGGER

    logged = []
    registry = logging.getLogger(_TORCH_ONNX_REGISTRY_LOGGER)  # "torchvision is not installed" x 4
    handler = logging.Handler()
    handler.emit = logged.append
    registry.addHandler(handler)
    try:
        with warnings.catch_warnings(record=True) as warned:
            warnings.simplefilter("always")
            args = ["--checkpoint", str(run_dir), "--steps", "0", "--export", "onnx", "--out", str(tmp_path)]
            assert main(args) == 0
    finally:
        registry.removeHandler(handler)
    assert not logged and not warned, (logged, [str(w.message) for w in warned])
    path = tmp_path / "policy.onnx"
    out = capsys.readouterr().out
    assert str(path) in out
    assert "played" not in out  # an export alone plays no step, and says nothing of playing
    assert sorted(os.listdir(tmp_path)) == [
        "policy.json",
        "policy.onnx",
    ]  # the model and its sidecar, no temp file
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    assert [i.name for i in sess.get_inputs()] == ["obs_window"]
    env, policy, _, _ = loaded
    with torch.inference_mode():
        obs, *_ = env.step(torch.zeros(1, env.num_actions))  # a history that is not all o_0
        expected = policy(obs).numpy()
    (actions,) = sess.run(None, {"obs_window": obs_window(obs).numpy()})
    np.testing.assert_allclose(actions, expected, atol=1e-5)


def test_video_and_snapshots(run_dir, tmp_path, gl):
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
    white = (strip[:20, :640, :3] > 0.9).all(axis=-1)
    assert white.sum() > 50  # the caption's text in the first frame


class CaptionRenderer:
    """EnvRenderer's stand-in: a tiny blank frame for each call, its caption recorded (no OpenGL)."""

    captions: list[str] = []

    def __init__(self, env, follow=True):
        CaptionRenderer.captions = []

    def frame(self, caption=None, state=None):
        CaptionRenderer.captions.append(caption)
        return np.zeros((2, 2, 3), np.uint8)

    def close(self):
        pass


def _times_s(captions: list[str]) -> list[float]:
    return [float(c.split()[1]) for c in captions]  # "t  1.50 s   N 7 ..."


def test_snapshots_show_one_episode_from_its_first_state_to_its_last_before_the_reset(
    run_dir, tmp_path, monkeypatch, capsys
):
    import lasmp.play as play

    # the episode play.py shows (no --seed: the same every time), played here first: where it ends
    env, policy, _, _ = load_deploy_env(run_dir, num_envs=1)
    steps = env.max_episode_length + 5  # past the time limit: the run goes on into the next episode
    obs, kept = env.get_observations(), 1  # the states of env 0's episode: the first, then one a step
    with torch.inference_mode():
        while kept < steps + 1:
            obs, _, dones, _ = env.step(policy(obs))
            if dones[0]:  # the env now holds the next episode's first state
                break
            kept += 1
    last = (kept - 1) * env.dt_s  # its last state before the reset (time limit or collision)

    monkeypatch.setattr(play, "EnvRenderer", CaptionRenderer)
    snaps = tmp_path / "snaps.png"
    assert main(["--checkpoint", str(run_dir), "--steps", str(steps), "--snapshots", str(snaps)]) == 0
    times = _times_s(CaptionRenderer.captions)
    assert len(times) == 6 and times == sorted(times)
    assert times[0] == 0.0 and times[-1] == pytest.approx(last)
    assert snaps.exists() and f"t 0.00 to {last:.2f} s" in capsys.readouterr().out


class CollidingEnv:
    """One env whose episodes end in a collision after `length` steps; qpos[0] counts the steps."""

    num_envs, dt_s = 1, 0.02

    def __init__(self, length: int):
        self.length = length
        self.episode_length_buf = torch.zeros(1, dtype=torch.long)
        self.sim = type("Sim", (), {"qpos": np.zeros((1, 3)), "qvel": np.zeros((1, 2))})()

    def get_observations(self):
        return None

    def step(self, actions):
        self.episode_length_buf += 1
        done = self.episode_length_buf >= self.length
        self.episode_length_buf[done] = 0  # reset: the env holds the next episode's first state
        self.sim.qpos[0, 0] = float(self.episode_length_buf[0])
        return None, torch.zeros(1), done, {"time_outs": torch.zeros(1, dtype=torch.bool)}


def test_snapshots_of_an_episode_cut_short_end_with_its_last_state_before_the_collision():
    from lasmp.play import EpisodeStrip, rollout

    env = CollidingEnv(length=9)
    strip = EpisodeStrip(env)
    assert rollout(env, lambda obs: None, 30, strip=strip)["collisions"] == 3
    kept = [int(qpos[0]) for qpos, _ in strip.states]
    assert kept == list(range(9)) and strip.ended  # steps 0..8 of the first episode, none after
    assert strip.picks() == [0, 2, 3, 5, 6, 8]
    assert _times_s(strip.captions)[-1] == pytest.approx(8 * env.dt_s)
    assert len(strip.frames(CaptionRenderer(env))) == 6 and CaptionRenderer.captions == [
        strip.captions[k] for k in strip.picks()
    ]


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


def test_benchmark_episode_on_a_fresh_clone_makes_the_default_benchmark_as_evaluate_does(
    run_dir, tmp_path, monkeypatch
):
    from lasmp.deploy import load_deploy_env
    from lasmp.eval import benchmark as bm
    from lasmp.play import use_benchmark_episodes

    monkeypatch.chdir(tmp_path)  # no benchmarks/ here
    env, _, _, _ = load_deploy_env(str(run_dir), num_envs=1)
    use_benchmark_episodes(env, "benchmarks/xi_eval.npz", 3)
    bench = bm.load(tmp_path / "benchmarks" / "xi_eval.npz")
    assert bench.num_episodes == 10_000
    assert env.intrinsics.trunk_mass_kg[0] == bench.robots.trunk_mass_kg[3]


def test_benchmark_episode_plays_that_trajectory_and_robot(run_dir, tmp_path, capsys):
    from lasmp.deploy import load_deploy_env
    from lasmp.eval import benchmark as bm
    from lasmp.play import use_benchmark_episodes

    bench_path = tmp_path / "bench.npz"
    bench = bm.generate(num_trajectories=6, num_robots=2, seed=0)
    bm.save(bench_path, bench)
    env, _, _, _ = load_deploy_env(str(run_dir), num_envs=1)
    use_benchmark_episodes(env, str(bench_path), 3)
    pose_env, _, _ = env.traj.evaluate(np.array([2.0]))
    pose_bench, _, _ = bench.trajectories.evaluate(np.array([2.0]), rows=[3])
    assert np.array_equal(pose_env, pose_bench)
    assert env.intrinsics.trunk_mass_kg[0] == bench.robots.trunk_mass_kg[3 % 2]
    assert (
        main(
            [
                "--checkpoint",
                str(run_dir),
                "--benchmark",
                str(bench_path),
                "--benchmark-episode",
                "9",
                "--steps",
                "1",
            ]
        )
        == 2
    )
    assert "--benchmark-episode must be in [0, 5]" in capsys.readouterr().err


def test_scenario_plays_the_real_motion_on_the_close_drive(run_dir, capsys, monkeypatch):
    import lasmp.play as play
    from lasmp.eval.real_motion import suite as rm

    seen = {}
    real_load = play.load_deploy_env

    def spy(*args):
        out = real_load(*args)
        seen.update(env=out[0], file=args[3])
        return out

    monkeypatch.setattr(play, "load_deploy_env", spy)
    assert main(["--checkpoint", str(run_dir), "--scenario", "lift_up", "--steps", "3"]) == 0
    assert "played 3 steps x 1 envs" in capsys.readouterr().out
    env = seen["env"]
    (lift,) = rm.build_motions(["lift_up"])
    assert env.max_episode_length == round(lift.duration_s / env.dt_s)  # the scenario's length, not 10 s
    assert env.cfg.platform.velocity_feedforward and env.cfg.platform.omega_n_rad_s == pytest.approx(25.13)
    pose, _, _ = env.traj.evaluate(np.array([8.0]))
    np.testing.assert_allclose(pose[0], lift.pose[800], atol=1e-9)
    assert not Path(seen["file"]).exists()  # the temporary file is removed once loaded
    assert main(["--checkpoint", str(run_dir), "--scenario", "rocket"]) == 2
    assert "unknown scenario(s) ['rocket']" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--checkpoint", str(run_dir), "--scenario", "lift_up", "--trajectories", "x.npz"])


def test_policy_checkpoint_is_small_plays_the_same_and_refuses_to_resume(run_dir, tmp_path):
    from lasmp.algo.checkpoint import CheckpointError, latest_checkpoint, read_checkpoint
    from lasmp.algo.checkpoint import main as ckpt_main
    from lasmp.deploy import load_deploy_env
    from lasmp.train import make_runner
    from lasmp.train_cfg import to_train_cfg

    full = latest_checkpoint(run_dir)
    slim = tmp_path / "policy.pt"
    assert ckpt_main(["policy", str(run_dir), str(slim)]) == 0
    data = read_checkpoint(slim)
    assert data["kind"] == "policy" and "optimizer_state_dict" not in data
    assert "estimator_optimizer_state_dict" not in data and slim.stat().st_size < 0.6 * full.stat().st_size
    env_a, pol_a, _, _ = load_deploy_env(full, num_envs=2, seed=1)
    env_b, pol_b, _, _ = load_deploy_env(slim, num_envs=2, seed=1)
    with torch.inference_mode():
        for _ in range(5):
            act_a, act_b = pol_a(env_a.get_observations()), pol_b(env_b.get_observations())
            assert torch.equal(act_a, act_b)
            env_a.step(act_a)
            env_b.step(act_b)
    runner = make_runner(to_train_cfg(OmegaConf.create(data["config"])), None)
    with pytest.raises(CheckpointError, match="policy checkpoint.*to resume training"):
        runner.load(str(slim))
    assert ckpt_main(["policy", str(tmp_path / "nope"), str(tmp_path / "x.pt")]) == 2


# ---------------------------------------------------------------------------------------------
# The visual-only render world
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def plain_env():
    """An env of its own (the render tests move its state)."""
    from lasmp.config import build_env_cfg
    from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
    from lasmp.envs.moving_platform.env import MovingPlatformEnv

    env = MovingPlatformEnv(build_env_cfg({"num_envs": 1, "seed": 0}, schema=MovingPlatformCfg))
    env.reset()
    return env


def _geom_names(model) -> list[str]:
    return [model.geom(i).name for i in range(model.ngeom)]


def test_render_model_has_physics_layout_and_visual_only_decorations(plain_env):
    from lasmp.render.world import DECOR_GROUP, DECOR_PREFIX, build_render_model

    phys = plain_env.sim.model
    model = build_render_model(plain_env)
    assert (model.nq, model.nv, model.na, model.nbody) == (phys.nq, phys.nv, phys.na, phys.nbody)
    np.testing.assert_array_equal(model.qpos0, phys.qpos0)
    assert [model.joint(i).name for i in range(model.njnt)] == [phys.joint(i).name for i in range(phys.njnt)]
    decor = [i for i, name in enumerate(_geom_names(model)) if name.startswith(DECOR_PREFIX)]
    assert len(decor) > 10  # the ground and the pillars' bands
    assert (model.geom_contype[decor] == 0).all() and (model.geom_conaffinity[decor] == 0).all()
    assert (model.geom_group[decor] == DECOR_GROUP).all() and (model.geom_bodyid[decor] == 0).all()
    assert model.ngeom == phys.ngeom + len(decor)  # nothing else added
    assert model.ntex >= 2 and "decor_sun" in [model.light(i).name for i in range(model.nlight)]


def test_physics_model_is_unchanged_by_rendering(plain_env):
    from lasmp.envs.moving_platform.scene import build_model
    from lasmp.render.world import DECOR_PREFIX, build_render_model

    phys = plain_env.sim.model
    before = (phys.ngeom, phys.nlight, phys.ntex, phys.nmat)
    build_render_model(plain_env)
    fresh = build_model(plain_env.cfg.platform, plain_env.cfg.sim)
    for m in (phys, fresh):
        assert (m.ngeom, m.nlight, m.ntex, m.nmat) == before
        assert not any(name.startswith(DECOR_PREFIX) for name in _geom_names(m))
        assert m.ntex == 0 and m.nlight == 1  # the robot, the platform and one light, no world


def test_ground_is_below_the_platforms_reach(plain_env):
    from lasmp.render.world import platform_layout

    size = plain_env.cfg.platform.size_m
    layout = platform_layout(size)
    # any rotation: the box's lowest point is at most its half-diagonal below its centre (z >= 0)
    assert layout.ground_z_m < -0.5 * float(np.linalg.norm(size)) - 0.5
    assert layout.ring_radius_m > 3.0  # pillars clear of the platform's |x|, |y| <= 1 m + half-diagonal


def _place(env, plf_pose, above_m: float = 0.45) -> None:
    """Platform joints (x, y, z, yaw, pitch, roll); the robot upright on it, trunk `above_m` over its centre."""
    import mujoco

    ix = env.index
    qpos = env.sim.qpos
    qpos[0, ix.plf_qpos] = torch.tensor(plf_pose, dtype=qpos.dtype)
    data = mujoco.MjData(env.sim.model)
    data.qpos[:] = qpos[0].numpy()
    mujoco.mj_kinematics(env.sim.model, data)
    plf = env.sim.model.body("platform").id
    qpos[0, ix.root_qpos : ix.root_qpos + 3] = torch.from_numpy(
        data.xpos[plf] + data.xmat[plf].reshape(3, 3) @ [0, 0, above_m]
    )
    qpos[0, ix.root_qpos + 3 : ix.root_qpos + 7] = torch.from_numpy(data.xquat[plf].copy())


def test_rendered_frame_shows_a_world_not_a_void(plain_env, gl):
    from lasmp.render.renderer import EnvRenderer

    r = EnvRenderer(plain_env)
    try:
        img = r.frame().astype(float)
    finally:
        r.close()
    assert img.mean() > 60  # not mostly black
    rows = img.mean(axis=(1, 2))
    assert abs(rows[: len(rows) // 8].mean() - rows[-len(rows) // 8 :].mean()) > 10  # sky above, ground below
    assert img[: len(rows) // 3].std() > 10  # the background itself is not uniform (grid, pillars)


def test_caption_changes_only_its_band():
    from lasmp.render.caption import caption_text, draw_caption

    text = caption_text(1.5, 7, 0.83, 2)
    assert text == "t  1.50 s   N 7   v_plf 0.83 m/s   collisions 2"
    assert caption_text(0.0, None, None, 0) == "t  0.00 s   collisions 0"
    img = np.full((480, 640, 3), 120, dtype=np.uint8)
    out = draw_caption(img.copy(), text)
    changed = (out != img).any(axis=-1)
    assert changed[:40].mean() > 0.5 and not changed[60:].any()  # a band at the top, nothing below
    assert (out[:40] > 200).all(axis=-1).sum() > 100  # white text on it


def test_frame_caption_reads_the_env(plain_env):
    from lasmp.render.renderer import frame_caption

    text = frame_caption(plain_env, 3)
    assert f"N {plain_env.traj_level[0]}" in text and "v_plf" in text and text.endswith("collisions 3")


@pytest.mark.parametrize(
    "plf_pose",
    [(0.0, 0.0, 0.0, 0.0, 0.0, 0.0), (1.0, -1.0, 4.5, 0.5, 0.3, -0.4), (-1.0, 0.8, 2.0, -2.0, -0.35, 0.35)],
)
def test_follow_camera_keeps_robot_in_frame(plain_env, gl, plf_pose):
    import mujoco

    from lasmp.render.renderer import EnvRenderer

    _place(plain_env, plf_pose)
    r = EnvRenderer(plain_env)
    try:
        r.renderer.enable_segmentation_rendering()
        seg = r.frame()  # (H, W, 2): object id, object type
        m = r.model
        robot_geoms = np.flatnonzero(m.body_rootid[m.geom_bodyid] == m.body("trunk").id)
        is_geom = seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM)
        robot = is_geom & np.isin(seg[..., 0], robot_geoms)
        platform = is_geom & (seg[..., 0] == m.geom("platform").id)
    finally:
        r.close()
    assert robot.mean() > 0.015, f"robot covers {robot.mean():.1%} of the frame"
    assert platform.mean() > 0.1
    ys, xs = np.nonzero(robot)
    h, w = robot.shape
    assert 0.15 * w < xs.mean() < 0.85 * w and 0.1 * h < ys.mean() < 0.9 * h  # well inside


def test_render_model_of_rough_static_task():
    from lasmp.config import build_env_cfg
    from lasmp.envs.rough_static.cfg import RoughStaticCfg
    from lasmp.envs.rough_static.env import RoughStaticEnv
    from lasmp.render.world import DECOR_PREFIX, build_render_model

    env = RoughStaticEnv(build_env_cfg({"num_envs": 1}, schema=RoughStaticCfg))
    model = build_render_model(env)
    assert (model.nq, model.nv) == (env.sim.model.nq, env.sim.model.nv)
    decor = [i for i, name in enumerate(_geom_names(model)) if name.startswith(DECOR_PREFIX)]
    assert decor and (model.geom_contype[decor] == 0).all() and (model.geom_conaffinity[decor] == 0).all()
    assert not any(name.startswith(DECOR_PREFIX) for name in _geom_names(env.sim.model))


def test_tilt_probe_plays_the_first_benchmark_episodes_and_splits_their_world_tilt(run_dir, tmp_path):
    from lasmp.eval import benchmark as bm

    probe = load_script("scripts/tilt_probe.py")
    bench, out = tmp_path / "bench.npz", tmp_path / "tilt.json"
    bm.save(bench, bm.generate(2, 2))
    assert probe.main([str(run_dir), "--episodes", "2", "--benchmark", str(bench), "--json", str(out)]) == 0
    figures = json.loads(out.read_text())
    assert figures["episodes"] == 2 and 0 <= figures["episodes_to_time_out"] <= 2
    # the lean and the swing bound the tilt (a triangle inequality per step, averaged)
    assert figures["tilt"] <= figures["lean"] + figures["swing"] + 1e-9
    assert np.isfinite(figures["gain_on_deck_tilt"])  # Xi_eval's decks tilt
    with pytest.raises(SystemExit) as err:
        probe.main([str(run_dir), "--episodes", "0"])
    assert err.value.code == 2


def test_curriculum_probe_plays_one_episode_per_env_and_zero_noise_sampling_equals_the_mean(
    run_dir, tmp_path
):
    probe = load_script("scripts/curriculum_probe.py")
    out = tmp_path / "probe.json"
    assert probe.main([str(run_dir), "--envs", "2", "--std-scales", "0", "--json", str(out)]) == 0
    results = json.loads(out.read_text())
    modes = ("mean", "sampled", "sampled_std_x0", "stand_still")
    assert all(results[m]["episodes"] == 2 and results[m]["level"] == 5 for m in modes)
    # the same envs and seed in every mode: with the std scaled to 0 the draws are the mean actions
    assert results["sampled_std_x0"] == results["mean"]
    with pytest.raises(SystemExit) as err:
        probe.main([str(run_dir), "--envs", "0"])
    assert err.value.code == 2


def test_the_studys_r_s_checkpoint_plays_and_its_export_is_refused_in_one_line(tmp_path, capsys):
    # the rough-static config has no trajectory hold: play sets it for moving-platform checkpoints only
    rs = ROOT / "results" / "study" / "rs" / "seed0" / "policy_449.pt"
    assert main(["--checkpoint", str(rs), "--steps", "5"]) == 0
    out = capsys.readouterr().out
    assert "task rough_static" in out and "played 5 steps" in out
    # the deployable policy takes the proprioceptive window alone; R-S also needs a velocity command
    assert main(["--checkpoint", str(rs), "--steps", "0", "--export", "onnx", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --export: ") and "command" in err and "Traceback" not in err
    assert not any(tmp_path.iterdir())
