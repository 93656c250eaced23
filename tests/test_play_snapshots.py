"""play.py's video and snapshot strip: the frames written, and the snapshots showing one episode from
its first state to its last before the reset (a time-out or a collision)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from lasmp.cli.play import main
from lasmp.deploy import load_deploy_env


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
    import lasmp.cli.play as play

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
    from lasmp.cli.play import EpisodeStrip, rollout

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
