"""Offscreen frames of one env (video, snapshot strip) in the visual-only world, with a caption.

Rendering uses its own model (`lasmp.render.world.build_render_model`: the env's scene plus a
ground grid, sky, lights and pillars) and its own MjData; each frame copies env 0's qpos/qvel
from the physics batch into it. The physics model is never modified.

`mujoco.Renderer` needs an OpenGL backend without a display: `MUJOCO_GL=egl` (a GPU driver, or
Mesa's EGL; the default set here) or `MUJOCO_GL=osmesa` with libosmesa6 installed (slow, software).
"""

from __future__ import annotations

import errno
import importlib
import math
import os
import subprocess
import tempfile
import warnings
from fractions import Fraction
from pathlib import Path

import numpy as np

from lasmp.io.atomic import TEMPORARY_SUFFIX, AtomicWriteError, atomic_open
from lasmp.render.caption import caption_text, draw_caption
from lasmp.render.world import build_render_model

VIDEO_SIZE = (640, 480)  # width, height (px)
SNAPSHOT_COUNT = 6
# Follow camera: looks at the platform centre raised by LOOKAT_UP_M (the robot's mid-height), from
# FOLLOW_DISTANCE_M away (the 0.5 m robot then covers ~2 % of the frame's pixels, the platform most
# of its lower half); it tracks the platform's position, never its rotation, so the tilt shows. From
# FOLLOW_ELEVATION_DEG above, a platform tilted more than ~28 deg away from the camera hides the robot
# behind it for that moment (a higher camera shows less of the world around).
FOLLOW_DISTANCE_M = 2.2
FOLLOW_ELEVATION_DEG = -28.0
FOLLOW_AZIMUTH_DEG = 135.0
LOOKAT_UP_M = 0.3


class RenderError(RuntimeError):
    """A user-facing rendering problem (a missing optional package, ...); the message says what to do."""


def select_gl_backend() -> None:
    """Headless OpenGL for `mujoco.Renderer`: MUJOCO_GL (default egl), even if mujoco came in first.

    mujoco picks its GL backend when it is imported; the env imports it long before anything is
    rendered, usually with MUJOCO_GL unset (= GLFW, which needs a display). Switch the choice to
    the requested headless backend then.
    """
    os.environ.setdefault("MUJOCO_GL", "egl")
    want = os.environ["MUJOCO_GL"].lower().strip()
    from mujoco.rendering.classic import gl_context

    if want in ("egl", "osmesa") and getattr(gl_context, "_MUJOCO_GL", want) != want:
        gl_context.GLContext = importlib.import_module(f"mujoco.{want}").GLContext
        gl_context._MUJOCO_GL = want


def check_offscreen_gl() -> None:
    """RenderError, saying what to install or set, where no offscreen OpenGL context can be made.

    A command that renders checks this before its long work: without it, the first frame (after the
    env is built) failed in a PyOpenGL traceback that named neither MUJOCO_GL nor a remedy."""
    try:
        select_gl_backend()
        import mujoco

        with warnings.catch_warnings():  # GLFW warns before it fails: the error below says it all
            warnings.simplefilter("ignore")
            mujoco.Renderer(mujoco.MjModel.from_xml_string("<mujoco/>"), 8, 8).close()
    except Exception as err:  # no EGL/OSMesa library, no device: PyOpenGL raises whatever it meets
        why = (str(err).strip().splitlines() or [""])[0]
        raise RenderError(
            f"--video and --snapshots need offscreen OpenGL, and MUJOCO_GL={os.environ.get('MUJOCO_GL')} "
            f"failed ({type(err).__name__}: {why}); use MUJOCO_GL=egl (a GPU driver or Mesa's EGL) or "
            "MUJOCO_GL=osmesa with libosmesa6 installed"
        ) from err


def _row(x, i: int) -> np.ndarray:
    """Row i of a per-env state array (numpy view or torch tensor) as a float64 numpy array (a copy:
    the batch moves on)."""
    if hasattr(x, "detach"):
        x = x.detach().cpu().numpy()
    return np.array(x[i], dtype=np.float64)


def env_state(env, i: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Env i's (qpos, qvel): all a frame of it is rendered from, so a state kept now renders later."""
    return _row(env.sim.qpos, i), _row(env.sim.qvel, i)


def copy_state(env, model, data, i: int = 0, state: tuple[np.ndarray, np.ndarray] | None = None) -> None:
    """Env i's qpos/qvel (or `state`, an `env_state` kept earlier) into `data` (of the render model:
    same layout) and its derived quantities."""
    import mujoco

    data.qpos[:], data.qvel[:] = env_state(env, i) if state is None else state
    mujoco.mj_forward(model, data)


def followed_body(model) -> int:
    """The body the camera follows: the platform, or the trunk in a scene without one."""
    from lasmp.robots import a1

    for name in ("platform", a1.TRUNK_BODY_NAME):
        try:
            return model.body(name).id
        except KeyError:
            continue
    return 0


def frame_caption(env, collisions: int, i: int = 0) -> str:
    """Env i's caption: episode time (s), N (waypoints), platform speed (m/s), collisions so far."""
    t_s = float(env.episode_length_buf[i]) * env.dt_s
    levels = getattr(env, "traj_level", None)
    n = int(levels[i]) if levels is not None and levels[i] >= 0 else None
    v_plf_w = getattr(getattr(env, "readout", None), "v_plf_w", None)
    speed = float(np.linalg.norm(v_plf_w[i])) if v_plf_w is not None else None
    return caption_text(t_s, n, speed, collisions)


class EnvRenderer:
    """Offscreen frames of env 0 in the visual-only world: a camera following the platform, or a
    fixed world camera."""

    def __init__(self, env, follow: bool = True, width: int = VIDEO_SIZE[0], height: int = VIDEO_SIZE[1]):
        select_gl_backend()
        import mujoco

        self.env = env
        self.model = build_render_model(env)
        self.data = mujoco.MjData(self.model)
        self.renderer = mujoco.Renderer(self.model, height=height, width=width)
        self.follow = follow
        self.body = followed_body(self.model)
        self.lookat_up_m = LOOKAT_UP_M if self.model.body(self.body).name == "platform" else 0.0
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        if follow:
            cam.distance, cam.elevation, cam.azimuth = (
                FOLLOW_DISTANCE_M,
                FOLLOW_ELEVATION_DEG,
                FOLLOW_AZIMUTH_DEG,
            )
        else:  # fixed: from about (7, -7, 5.5) m at (0, 0, 2) m, so the 0..5 m platform path stays in view
            eye, target = np.array([7.0, -7.0, 5.5]), np.array([0.0, 0.0, 2.0])
            d = target - eye
            cam.lookat[:] = target
            cam.distance = float(np.linalg.norm(d))
            cam.elevation = math.degrees(math.asin(d[2] / cam.distance))
            cam.azimuth = math.degrees(math.atan2(d[1], d[0]))
        self.camera = cam

    def update(self, state: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        """Copy env 0's current state (or `state`, its `env_state` kept earlier) into the render data
        and aim the camera."""
        copy_state(self.env, self.model, self.data, 0, state)
        if self.follow:
            self.camera.lookat[:] = self.data.xpos[self.body] + [0.0, 0.0, self.lookat_up_m]
        self.renderer.update_scene(self.data, self.camera)

    def frame(
        self, caption: str | None = None, state: tuple[np.ndarray, np.ndarray] | None = None
    ) -> np.ndarray:
        """(height, width, 3) uint8 image of env 0's current state (or `state`, as `update`), with
        `caption` drawn on top."""
        self.update(state)
        image = self.renderer.render()
        return draw_caption(image, caption) if caption else image

    def close(self) -> None:
        self.renderer.close()


def ffmpeg_exe() -> str:
    """The ffmpeg binary `--video` streams frames to (imageio-ffmpeg's); RenderError if it is missing,
    so a command can check it before any work."""
    try:
        import imageio_ffmpeg
    except ImportError as err:
        raise RenderError(
            f"--video needs imageio and imageio-ffmpeg ({err}); install them with: pip install -e .[video]"
        ) from err
    return imageio_ffmpeg.get_ffmpeg_exe()


class VideoWriter:
    """mp4 (H.264) at one frame per policy step, streamed to an ffmpeg process.

    Written the way lasmp.io.atomic writes: into a hidden temporary file beside `path`, renamed over it
    by `close()` only once ffmpeg has finished without error; `abort()` (and any failure) removes it.
    So an interrupted or failed run leaves no half-written video, and an older file at `path` as it
    was. ffmpeg is driven directly (not through imageio's writer) because imageio neither reports
    ffmpeg's exit status (a full disk at the last flush went unnoticed) nor says why a frame's write
    failed (a bare Broken pipe): here a failure is an AtomicWriteError naming `path` and ffmpeg's reason.
    ffmpeg runs in its own session, so a Ctrl-C reaches this process only, which then aborts it.
    """

    CRF = 25  # H.264 quality: imageio's default ("quality 5"), which this writer replaced

    def __init__(self, path: str | os.PathLike, fps: float):
        self.exe = ffmpeg_exe()
        self.path = Path(path)
        self.fps = fps
        self.frames = 0
        self._proc: subprocess.Popen | None = None
        try:
            self._log = tempfile.TemporaryFile()  # ffmpeg's messages, read back for the error line
            self.path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(
                prefix=f".{self.path.name}.", suffix=TEMPORARY_SUFFIX, dir=self.path.parent
            )
            os.close(fd)
        except OSError as err:
            raise AtomicWriteError(self.path, err) from err
        self._tmp = Path(tmp)

    def _start(self, shape: tuple[int, ...]) -> None:
        height, width = shape[:2]
        fps = str(Fraction(self.fps).limit_denominator())
        source = f"-f rawvideo -pix_fmt rgb24 -s {width}x{height} -r {fps} -i -".split()
        # H.264 in yuv420p (what players take); the format by name: the temporary file ends in .tmp
        encode = f"-an -vcodec libx264 -pix_fmt yuv420p -crf {self.CRF} -f mp4".split()
        self._proc = subprocess.Popen(
            [self.exe, "-y", "-v", "error", *source, *encode, str(self._tmp)],
            stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            stderr=self._log,
            start_new_session=True,
        )

    def _failed(self, err: OSError | None) -> AtomicWriteError:
        """The error of a failed ffmpeg (the temporary file removed): its last message says why."""
        code = self._proc.wait() if self._proc is not None else None
        self._log.seek(0)
        lines = [ln.strip() for ln in self._log.read().decode(errors="replace").splitlines() if ln.strip()]
        if lines:  # "[out#0/mp4 @ 0x...] Error closing file: No space left on device": its reason
            reason = lines[-1].split("] ", 1)[-1]
        else:
            reason = f"killed by signal {-code}" if code is not None and code < 0 else f"exit status {code}"
        self.abort()
        number = errno.ENOSPC if "No space left" in reason else getattr(err, "errno", None) or errno.EIO
        return AtomicWriteError(self.path, OSError(number, f"ffmpeg stopped: {reason}"))

    def add(self, frame: np.ndarray) -> None:
        """Append one (height, width, 3) uint8 frame; AtomicWriteError if ffmpeg has stopped."""
        if self._proc is None:
            self._start(frame.shape)
        try:
            self._proc.stdin.write(np.ascontiguousarray(frame, dtype=np.uint8).tobytes())
        except OSError as err:  # a broken pipe: ffmpeg exited (a full disk, ...)
            raise self._failed(err) from err
        self.frames += 1

    def close(self) -> None:
        """Finish the file and rename it over `path`; AtomicWriteError (nothing written) if ffmpeg fails."""
        if self._proc is None:
            self.abort()
            raise ValueError(f"{self.path}: no frames to write")
        try:
            self._proc.stdin.close()
        except OSError as err:
            raise self._failed(err) from err
        if self._proc.wait() != 0:
            raise self._failed(None)
        try:
            os.chmod(self._tmp, 0o644)  # mkstemp makes 0600
            os.replace(self._tmp, self.path)
        except OSError as err:
            self.abort()
            raise AtomicWriteError(self.path, err) from err
        self._log.close()

    def abort(self) -> None:
        """Stop ffmpeg and remove the temporary file: nothing written, an older `path` untouched."""
        if self._proc is not None and self._proc.poll() is None:
            self._proc.kill()
            self._proc.wait()
        if self._proc is not None and self._proc.stdin and not self._proc.stdin.closed:
            try:
                self._proc.stdin.close()
            except OSError:  # the pipe's buffered bytes cannot go anywhere now
                pass
        try:
            self._tmp.unlink(missing_ok=True)
        except OSError:  # a disk turned read-only: the error that brought us here is the one to report
            pass
        self._log.close()


def save_snapshots(frames: list[np.ndarray], path: str | os.PathLike) -> None:
    """The frames side by side, left to right in time, as one PNG, written atomically
    (AtomicWriteError naming `path` if it cannot be)."""
    from matplotlib import image

    strip = np.concatenate(frames, axis=1)
    with atomic_open(path) as f:
        image.imsave(f, strip, format="png")


def snapshot_steps(steps: int, count: int = SNAPSHOT_COUNT) -> set[int]:
    """`count` indices evenly spaced over `steps` states (state k: k policy steps in), first and last
    included; fewer where there are fewer states."""
    return {int(s) for s in np.linspace(0, max(steps - 1, 0), count).round()}
