"""Waypoint curriculum (docs/environment.md#curriculum-lasmpenvscurriculumpy): the task level is the
number of trajectory waypoints N.

Training starts at N = level_min and the level rises by one when the success rate at the
current level reaches `promote_success_rate`, up to level_max. Our choices (the paper leaves them open):
- Success = the episode reached the time-out T without a collision.
- The rate is measured over the last `window_episodes` episodes that ended while the env
  played the current level; episodes of replayed lower levels do not count.
- The window is cleared at each promotion, and promotion needs a full window.
- After a promotion, a fraction `replay_lower_fraction` of new episodes draws N uniformly
  from the mastered levels [level_min, level - 1] (against forgetting); the rest use N = level.
- The level and the window survive a resume via `state_dict()` / `load_state_dict()`.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import numpy as np

from lasmp.config.checks import check_config
from lasmp.envs.moving_platform.cfg import CurriculumCfg


class WaypointCurriculum:
    """Success-rate-driven scheduler of the number of waypoints N."""

    def __init__(
        self,
        level_min: int = 5,
        level_max: int = 15,
        promote_success_rate: float = 0.8,
        window_episodes: int = 200,
        replay_lower_fraction: float = 0.2,
    ) -> None:
        # the config's rules (CurriculumCfg's, ConfigError: a ValueError), one place for them
        check_config(
            CurriculumCfg(
                True, level_min, level_max, promote_success_rate, window_episodes, replay_lower_fraction
            ),
            "curriculum",
        )
        self.level_min = int(level_min)
        self.level_max = int(level_max)
        self.promote_success_rate = float(promote_success_rate)
        self.window_episodes = int(window_episodes)
        self.replay_lower_fraction = float(replay_lower_fraction)
        self._level = self.level_min
        self._window: deque[bool] = deque(maxlen=self.window_episodes)

    @property
    def level(self) -> int:
        """Current task level N."""
        return self._level

    @property
    def success_rate(self) -> float:
        """Success rate over the current window; nan if it is empty."""
        if not self._window:
            return math.nan
        return sum(self._window) / len(self._window)

    def sample_levels(self, num: int, rng: np.random.Generator) -> np.ndarray:
        """N for `num` new episodes (int64 array)."""
        levels = np.full(num, self._level, dtype=np.int64)
        if self._level > self.level_min and self.replay_lower_fraction > 0.0:
            replay = rng.random(num) < self.replay_lower_fraction
            levels[replay] = rng.integers(self.level_min, self._level, size=int(replay.sum()))
        return levels

    @staticmethod
    def _episodes(levels, success) -> tuple[np.ndarray, np.ndarray]:
        """Finished episodes' N and success flags as flat arrays of one length."""
        levels = np.asarray(levels).reshape(-1)
        success = np.asarray(success, dtype=bool).reshape(-1)
        if levels.shape != success.shape:
            raise ValueError(
                f"levels and success must have the same length, got {levels.shape} and {success.shape}"
            )
        return levels, success

    def update(self, levels: np.ndarray, success: np.ndarray) -> bool:
        """Feed finished episodes (their N and success flag); True if the level rose."""
        levels, success = self._episodes(levels, success)
        self._window.extend(success[levels == self._level].tolist())
        if self._level >= self.level_max or len(self._window) < self.window_episodes:
            return False
        # integer comparison with a small tolerance, so 160/200 promotes at 0.8 exactly
        if sum(self._window) >= self.promote_success_rate * self.window_episodes - 1e-9:
            self._level += 1
            self._window.clear()
            return True
        return False

    def state_dict(self) -> dict[str, Any]:
        """Level and window contents (plain Python types, safe for torch.save)."""
        return {"level": self._level, "window": list(self._window)}

    def load_state_dict(self, d: dict[str, Any]) -> None:
        """Restore `state_dict()` output; a malformed dict raises ValueError naming the key."""
        if not isinstance(d, dict):
            raise ValueError(f"curriculum state must be a dict, got {type(d).__name__}")
        for key in ("level", "window"):
            if key not in d:
                raise ValueError(f"curriculum state is missing key {key!r}")
        level = d["level"]
        if (
            isinstance(level, bool)
            or not isinstance(level, (int, np.integer))
            or not (self.level_min <= level <= self.level_max)
        ):
            raise ValueError(
                f"curriculum state 'level' must be an int in "
                f"[{self.level_min}, {self.level_max}], got {level!r}"
            )
        window = d["window"]
        if not isinstance(window, (list, tuple)) or not all(isinstance(x, (bool, np.bool_)) for x in window):
            raise ValueError("curriculum state 'window' must be a list of bools")
        if len(window) > self.window_episodes:
            raise ValueError(
                f"curriculum state 'window' has {len(window)} entries, more than "
                f"window_episodes={self.window_episodes}"
            )
        self._level = int(level)
        self._window = deque((bool(x) for x in window), maxlen=self.window_episodes)


class SharedCurriculum(WaypointCurriculum):
    """The curriculum of a data-parallel run (torchrun): one level for all ranks, promoted on the
    success rate over every rank's episodes (ours).

    `update` only collects a rank's finished episodes; `sync()`, which every rank calls at the same
    point of each iteration, gathers them from all ranks and feeds them in rank order, so every
    rank's level and window stay identical. The level can therefore rise only between iterations."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._pending: list[tuple[list[int], list[bool]]] = []

    def update(self, levels: np.ndarray, success: np.ndarray) -> bool:
        levels, success = self._episodes(levels, success)
        self._pending.append((levels.tolist(), success.tolist()))
        return False

    def sync(self) -> bool:
        """Feed every rank's episodes since the last sync (a collective); True if the level rose."""
        import torch.distributed as dist

        mine = (sum((lv for lv, _ in self._pending), []), sum((s for _, s in self._pending), []))
        self._pending = []
        everyone: list = [None] * dist.get_world_size()
        dist.all_gather_object(everyone, mine)
        rose = False
        for levels, success in everyone:
            rose |= WaypointCurriculum.update(
                self, np.asarray(levels, dtype=np.int64), np.asarray(success, dtype=bool)
            )
        return rose
