"""play.py as a careless user runs it: the files it writes (video, snapshots, export) onto existing
files, read-only and full disks and unknown extensions; flags that cannot go together; numbers that
mean nothing; a Ctrl-C. Each is refused in one line before the env is built (no "loaded" line), or
fails in one line naming the file and leaves nothing behind.

The checkpoint is the shipped policy; rollouts are a few steps; the disks are real small tmpfs mounts."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from badkit import ROOT, call, files, refused, remount, succeeded

import lasmp.cli.play as play
from lasmp.cli.play import main

CHECKPOINT = str(ROOT / "resources" / "policies" / "lasmp_a1.pt")


def played(*args: str):
    return call(main, ["--checkpoint", CHECKPOINT, *args])


def refused_up_front(out, *patterns: str) -> None:
    """A clear refusal (exit 2) before the checkpoint was loaded and the env built."""
    refused(out, *patterns)
    assert out.code == 2, out.text
    assert not any(line.startswith("loaded ") for line in out.text.splitlines()), out.text


def one_error_line(out, *needles: str) -> str:
    refused(out)
    lines = [line for line in out.text.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and all(n in lines[0] for n in needles), out.text
    return lines[0]


# ---------------------------------------------------------------------------------------------
# Export (P14, P15, P16)
# ---------------------------------------------------------------------------------------------
def test_an_export_onto_an_older_one_is_refused_and_replaced_only_with_force(tmp_path):
    out = tmp_path / "deploy"
    out.mkdir()
    (out / "policy.onnx").write_bytes(b"an export of another checkpoint")
    (out / "policy.json").write_text("{}\n")
    before = files(out)
    refused_up_front(played("--steps", "1", "--export", "onnx", "--out", str(out)), "policy.onnx", "--force")
    assert files(out) == before

    succeeded(played("--steps", "0", "--export", "onnx", "--out", str(out), "--force"))
    after = files(out)
    assert sorted(after) == ["policy.json", "policy.onnx"]  # no staging directory left
    assert after["policy.onnx"] != before["policy.onnx"] and '"action_scale"' in after["policy.json"].decode()


def test_an_export_onto_a_read_only_disk_is_refused_before_the_env_is_built(tmpfs):
    ro = tmpfs(read_only=True)
    refused_up_front(
        played("--steps", "1", "--export", "onnx", "--out", str(ro / "deploy")), "policy.onnx", "not writable"
    )


def test_an_export_onto_a_path_that_is_a_file_is_refused(tmp_path):
    target = tmp_path / "deploy"
    target.write_text("a file, not a directory")
    refused_up_front(played("--export", "onnx", "--out", str(target)), "not a directory")
    assert target.read_text() == "a file, not a directory"


def test_an_export_on_a_full_disk_is_one_line_naming_the_file_and_leaves_nothing(tmpfs):
    full = tmpfs(size="64k")  # the model alone is about 1 MB
    out = played("--steps", "0", "--export", "onnx", "--out", str(full / "deploy"))
    assert out.code == 1
    one_error_line(out, str(full / "deploy" / "policy.onnx"), "No space left on device")
    assert list(full.iterdir()) == []  # neither a file, a staging directory nor the --out directory


# ---------------------------------------------------------------------------------------------
# Video and snapshots (P08, P12, P25)
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("option", ["--video", "--snapshots"])
def test_a_video_or_snapshots_on_a_read_only_disk_is_refused_before_the_rollout(tmpfs, option):
    ro = tmpfs(read_only=True)
    name = "play.mp4" if option == "--video" else "strip.png"
    refused_up_front(played("--steps", "1", option, str(ro / name)), name, "not writable")


@pytest.mark.parametrize(
    ("option", "name", "known"), [("--video", "play.avi", ".mp4"), ("--snapshots", "s.jpg", ".png")]
)
def test_an_unknown_extension_is_refused_naming_the_option_and_the_known_one(tmp_path, option, name, known):
    refused_up_front(played("--steps", "1", option, str(tmp_path / name)), option, "unknown extension", known)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("option", "name"), [("--video", "play.mp4"), ("--snapshots", "strip.png")])
def test_an_existing_video_or_strip_is_not_replaced_without_force(tmp_path, option, name):
    (tmp_path / name).write_bytes(b"yesterday's")
    refused_up_front(played("--steps", "1", option, str(tmp_path / name)), name, "already exists", "--force")
    assert (tmp_path / name).read_bytes() == b"yesterday's"


def test_a_video_that_fills_the_disk_is_one_line_naming_it_and_leaves_nothing(tmpfs, gl):
    full = tmpfs(size="8k")  # three frames of H.264 are about 10 kB
    video = full / "clips" / "play.mp4"
    out = played("--steps", "3", "--video", str(video))
    assert out.code == 1
    one_error_line(out, str(video), "No space left on device")
    assert list(full.iterdir()) == []  # no partial video, no temporary file, no clips/ directory


def test_snapshots_that_fill_the_disk_after_the_rollout_fail_in_one_line_and_leave_nothing(tmpfs, gl):
    full = tmpfs(size="8k")  # the strip of six 640x480 frames is about 200 kB
    strip = full / "strip.png"
    out = played("--steps", "2", "--snapshots", str(strip))
    assert out.code == 1
    one_error_line(out, str(strip), "No space left on device")
    assert list(full.iterdir()) == []


def test_a_video_with_force_replaces_the_old_one_whole(tmp_path, gl):
    video = tmp_path / "play.mp4"
    video.write_bytes(b"yesterday's")
    succeeded(played("--steps", "3", "--video", str(video), "--force"))
    assert video.read_bytes()[4:8] == b"ftyp"  # an mp4
    assert sorted(p.name for p in tmp_path.iterdir()) == ["play.mp4"]  # no temporary file left
    imageio = pytest.importorskip("imageio.v2")
    with imageio.get_reader(str(video)) as reader:
        assert reader.count_frames() == 3


# ---------------------------------------------------------------------------------------------
# Flags that cannot go together (P33, P34) and numbers that mean nothing
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("args", "pattern"),
    [
        (["--benchmark-episode", "0", "--trajectories", "mine.npz"], "--benchmark-episode.*--trajectories"),
        (["--benchmark-episode", "0", "--scenario", "bus_stop_and_go"], "--benchmark-episode.*--scenario"),
        (["--benchmark", "other.npz"], "--benchmark is read only with --benchmark-episode"),
        (["--out", "deploy"], "--out is the directory of --export"),
        (["--export", "onnx"], "--export needs --out"),
        (["--video", "v.mp4", "--steps", "0"], "--video needs --steps >= 1"),
    ],
)
def test_flags_that_would_be_ignored_or_mixed_are_refused(tmp_path, args, pattern):
    (tmp_path / "mine.npz").write_bytes(b"")
    refused_up_front(played(*args), pattern)


@pytest.mark.parametrize(
    ("option", "value"),
    [
        ("--seed", "-1"),
        ("--seed", str(2**64)),
        ("--seed", "1.5"),
        ("--steps", "-1"),
        ("--steps", "ten"),
        ("--num-envs", "0"),
        ("--benchmark-episode", "-2"),
    ],
)
def test_a_number_out_of_its_range_is_refused_naming_the_option(option, value):
    refused_up_front(played(option, value), f"argument {option}", "must be an integer")


def test_steps_0_plays_no_step_rather_than_the_default():
    out = played("--steps", "0")
    succeeded(out)
    assert "played 0 steps x 1 envs" in out.text


# ---------------------------------------------------------------------------------------------
# Ctrl-C (P05)
# ---------------------------------------------------------------------------------------------
def _interrupt_at_step(monkeypatch, k: int) -> None:
    """The env's k-th step raises KeyboardInterrupt, as a Ctrl-C there would."""
    load = play.load_deploy_env

    def loading(*args, **kwargs):
        env, policy, cfg, data = load(*args, **kwargs)
        step, calls = env.step, [0]

        def stepping(actions):
            calls[0] += 1
            if calls[0] == k:
                raise KeyboardInterrupt
            return step(actions)

        env.step = stepping
        return env, policy, cfg, data

    monkeypatch.setattr(play, "load_deploy_env", loading)


def test_ctrl_c_in_the_rollout_says_nothing_was_written(monkeypatch):
    _interrupt_at_step(monkeypatch, 4)
    out = played("--steps", "50")
    assert out.code == 130 and "Traceback" not in out.text, out.text
    assert "interrupted after 3 of 50 steps: nothing written" in out.text


def test_ctrl_c_after_the_export_says_which_files_were_written_and_which_not(monkeypatch, tmp_path, gl):
    _interrupt_at_step(monkeypatch, 3)
    deploy, video = tmp_path / "deploy", tmp_path / "clips" / "play.mp4"
    out = played("--steps", "50", "--export", "onnx", "--out", str(deploy), "--video", str(video))
    assert out.code == 130 and "Traceback" not in out.text, out.text
    line = f"interrupted after 2 of 50 steps: wrote {deploy / 'policy.onnx'}, {deploy / 'policy.json'}; not written: {video}"
    assert line in out.text
    assert sorted(files(tmp_path)) == [
        "deploy/policy.json",
        "deploy/policy.onnx",
    ]  # no clips/, no partial video


def test_a_real_ctrl_c_ends_play_in_one_line_with_exit_130_and_no_partial_video(tmp_path, gl):
    video = tmp_path / "play.mp4"
    proc = subprocess.Popen(
        [sys.executable, str(ROOT / "play.py"), "--checkpoint", CHECKPOINT, "--steps", "100000"]
        + ["--video", str(video)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        assert proc.stdout.readline().startswith("loaded "), proc.stderr.read()
        deadline = time.monotonic() + 120
        while not list(tmp_path.glob(".play.mp4.*")) and time.monotonic() < deadline:
            time.sleep(0.1)  # the video's temporary file: the rollout starts next
        time.sleep(0.5)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert "of 100000 steps: nothing written" in err
    assert list(tmp_path.iterdir()) == []  # ffmpeg stopped, its temporary file removed


# ---------------------------------------------------------------------------------------------
# The video writer itself: ffmpeg stopping mid-stream (the Broken pipe of P08)
# ---------------------------------------------------------------------------------------------
FRAME = np.zeros((480, 640, 3), np.uint8)


def test_ffmpeg_stopping_mid_stream_is_a_write_error_naming_the_video_not_a_broken_pipe(tmp_path, gl):
    from lasmp.io.atomic import AtomicWriteError
    from lasmp.render.renderer import VideoWriter

    writer = VideoWriter(tmp_path / "play.mp4", fps=50.0)
    writer.add(FRAME)
    writer._proc.kill()  # as a full disk or a signal would end it
    with pytest.raises(AtomicWriteError) as err:
        for _ in range(50):
            writer.add(FRAME)
        writer.close()
    assert str(tmp_path / "play.mp4") in str(err.value) and "ffmpeg stopped: killed by signal 9" in str(
        err.value
    )
    assert list(tmp_path.iterdir()) == []  # its temporary file removed


def test_a_disk_turning_read_only_under_the_video_is_reported_as_such(tmpfs, gl):
    from lasmp.io.atomic import AtomicWriteError
    from lasmp.render.renderer import VideoWriter

    disk = tmpfs(size="1m")
    writer = VideoWriter(disk / "play.mp4", fps=50.0)
    remount(disk, read_only=True)
    with pytest.raises(AtomicWriteError) as err:
        for _ in range(50):
            writer.add(FRAME)
        writer.close()
    assert str(disk / "play.mp4") in str(err.value) and "Read-only file system" in str(err.value)


def test_rendering_without_offscreen_opengl_is_refused_before_the_env_is_built(monkeypatch, tmp_path):
    import mujoco

    def no_context(*args, **kwargs):
        raise mujoco.FatalError("an OpenGL platform library has not been loaded into this process")

    monkeypatch.setattr(mujoco, "Renderer", no_context)
    out = played("--steps", "1", "--snapshots", str(tmp_path / "strip.png"))
    refused_up_front(out, "need offscreen OpenGL", "MUJOCO_GL=egl", "libosmesa6")
    assert list(tmp_path.iterdir()) == []
