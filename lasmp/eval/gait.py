"""The stance of each benchmark episode: the share of its steps on four feet and its longest air phase.

The three-foot stance of the paper's reg4 (docs/method.md, LAS-MP+) shows here: a foot held up for
seconds, often until the episode ends. Every step an env plays is counted, its last one included; an
air phase still open when the episode ends counts with its length so far.
"""

from __future__ import annotations

import numpy as np

GAIT_KEYS = ("four_feet_share", "longest_air_s")
LONG_AIR_S = 2.0  # the screening's threshold: an episode with a foot up longer than this (docs/screening.md)


class GaitTracker:
    def __init__(self, num_envs: int, dt_s: float):
        self.dt_s = dt_s
        self.steps = np.zeros(num_envs)
        self.four = np.zeros(num_envs)
        self.air_s = np.zeros((num_envs, 4))
        self.longest_s = np.zeros(num_envs)

    def start(self, ids: np.ndarray) -> None:
        for buf in (self.steps, self.four, self.air_s, self.longest_s):
            buf[ids] = 0.0

    def step(self, active: np.ndarray, contact: np.ndarray) -> None:
        """`contact` (n, 4) bool: the feet on something after this step; `active`: envs whose step counts."""
        self.steps[active] += 1
        self.four[active] += contact[active].all(axis=1)
        self.air_s = np.where(contact, 0.0, self.air_s + self.dt_s)
        self.longest_s[active] = np.maximum(self.longest_s[active], self.air_s[active].max(axis=1))

    def close(self, ids: np.ndarray) -> dict[str, np.ndarray]:
        return {
            "four_feet_share": self.four[ids] / np.maximum(self.steps[ids], 1),
            "longest_air_s": self.longest_s[ids].copy(),
        }


def summarize_gait(episodes: dict[str, np.ndarray]) -> dict[str, float]:
    """Over all episodes: the share of steps on four feet (steps pooled), the share of episodes with a
    foot up longer than LONG_AIR_S, and the median longest air phase (s)."""
    steps = episodes["steps"] + 1  # `steps` counts up to the collision; the tracker, every step played
    return {
        "four_feet_step_share": float(np.sum(episodes["four_feet_share"] * steps) / np.sum(steps)),
        "episodes_with_foot_up_over_2s": float(np.mean(episodes["longest_air_s"] > LONG_AIR_S)),
        "median_longest_air_s": float(np.median(episodes["longest_air_s"])),
    }
