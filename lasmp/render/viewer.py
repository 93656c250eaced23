"""MuJoCo's interactive (passive) viewer on env 0, in the visual-only world, at real time."""

from __future__ import annotations

import os
import time

from lasmp.render.renderer import (
    FOLLOW_AZIMUTH_DEG,
    FOLLOW_DISTANCE_M,
    FOLLOW_ELEVATION_DEG,
    copy_state,
    followed_body,
)
from lasmp.render.world import build_render_model


def has_display() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


class Viewer:
    """The passive viewer on env 0's state (copied into the render model), synced once per policy
    step. Its camera tracks the platform's position (not its rotation); the mouse can still move it."""

    def __init__(self, env):
        import mujoco
        import mujoco.viewer

        self._mj = mujoco
        self.env = env
        self.dt_s = env.dt_s
        self.model = build_render_model(env)
        self.data = mujoco.MjData(self.model)
        copy_state(env, self.model, self.data, 0)
        self.handle = mujoco.viewer.launch_passive(self.model, self.data)
        with self.handle.lock():
            cam = self.handle.cam
            cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
            cam.trackbodyid = followed_body(self.model)
            cam.distance, cam.elevation, cam.azimuth = (
                FOLLOW_DISTANCE_M,
                FOLLOW_ELEVATION_DEG,
                FOLLOW_AZIMUTH_DEG,
            )
        self._last = time.perf_counter()

    def sync(self) -> bool:
        """Show the current state; False once the window was closed."""
        if not self.handle.is_running():
            return False
        with self.handle.lock():
            copy_state(self.env, self.model, self.data, 0)
        self.handle.sync()
        wait = self.dt_s - (time.perf_counter() - self._last)
        if wait > 0:
            time.sleep(wait)
        self._last = time.perf_counter()
        return True

    def close(self) -> None:
        self.handle.close()
