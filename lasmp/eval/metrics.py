"""Benchmark metrics (SPEC §12), accumulated per env and step, closed per episode.

Definitions (every per-step quantity is counted on the steps *before* the episode's first
collision; the collision step itself and anything after it are not counted):
- collision: 1 if the episode ended in a collision or a fall before T, else 0.
- height violation rate: share of counted steps with |p_body_p,z - h_des| > 0.1 m (h_des in the
  platform frame, as the env resolves it from `rewards.h_des_m` and `rewards.h_des_from`).
- position deviation (m): mean over counted steps of ||p(t) - p(0)||, p the trunk's position
  relative to the platform in the frame POSITION_FRAME names:
  "platform": p = p_body_p, the platform frame (it moves and turns with the platform);
  "translating": p = p_body_w - p_plf_w, a frame that follows the platform's centre but keeps the
  world's axes, so the platform's rotation about its centre moves the trunk in it.
- rotation deviation (rad): mean over counted steps of the angle of R_pb(0)^T R_pb(t), with
  R_pb = R_wp^T R_wb the trunk's orientation relative to the platform.
- power (W): mean over counted steps of sum_j max(tau_j q_dot_j, 0).
An episode with no counted step (a collision on its first step) contributes to the collision
rate only. Mean and std are over `num_batches` equal, consecutive batches of the benchmark's
episodes (per-batch means, then their mean and std), so the std says how much the figure
moves from one slice of the benchmark to another.
"""

from __future__ import annotations

import numpy as np

POSITION_FRAMES = ("platform", "translating")
POSITION_FRAME = "platform"  # the reading of SPEC §12's "relative to the platform" (README, "The paper's world")

METRICS = (
    "collision_rate",
    "height_violation_rate",
    "position_deviation_m",
    "rotation_deviation_rad",
    "power_w",
)


def rotation_angle(r_a: np.ndarray, r_b: np.ndarray) -> np.ndarray:
    """Angle (rad) of the rotation between (n, 3, 3) orientations: |log(R_a^T R_b)|."""
    trace = np.einsum("nji,nji->n", r_a, r_b)
    return np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0))


class EpisodeMetrics:
    """Running sums per env for the episode it plays; `close(ids)` returns finished episodes."""

    def __init__(self, num_envs: int, h_des_m: float, violation_m: float = 0.1):
        self.h_des_m = h_des_m
        self.violation_m = violation_m
        self.steps = np.zeros(num_envs)
        self.violations = np.zeros(num_envs)
        self.pos_dev = np.zeros(num_envs)
        self.rot_dev = np.zeros(num_envs)
        self.power = np.zeros(num_envs)
        self.p0 = np.zeros((num_envs, 3))
        self.r0 = np.tile(np.eye(3), (num_envs, 1, 1))

    def start(self, ids: np.ndarray, p_rel: np.ndarray, r_pb: np.ndarray) -> None:
        """Envs `ids` begin an episode at this relative pose (p_rel: position in POSITION_FRAME)."""
        for buf in (self.steps, self.violations, self.pos_dev, self.rot_dev, self.power):
            buf[ids] = 0.0
        self.p0[ids] = p_rel
        self.r0[ids] = r_pb

    def step(self, active: np.ndarray, collision: np.ndarray, p_body_p, r_pb, tau, q_dot, p_rel=None) -> None:
        """Add one step of every env that is `active` and did not collide on this step.

        `p_rel`: the trunk's position in POSITION_FRAME for the deviation (default: p_body_p)."""
        count = active & ~collision
        p_rel = p_body_p if p_rel is None else p_rel
        self.steps += count
        self.violations += count * (np.abs(p_body_p[:, 2] - self.h_des_m) > self.violation_m)
        self.pos_dev += count * np.linalg.norm(p_rel - self.p0, axis=1)
        self.rot_dev += count * rotation_angle(self.r0, r_pb)
        self.power += count * np.maximum(tau * q_dot, 0.0).sum(axis=1)

    def close(self, ids: np.ndarray, collided: np.ndarray) -> dict[str, np.ndarray]:
        """Per-episode values of envs `ids` (NaN where no step was counted)."""
        n = self.steps[ids]
        with np.errstate(invalid="ignore", divide="ignore"):
            return {
                "collision": collided.astype(float),
                "steps": n.copy(),
                "height_violation_rate": self.violations[ids] / n,
                "position_deviation_m": self.pos_dev[ids] / n,
                "rotation_deviation_rad": self.rot_dev[ids] / n,
                "power_w": self.power[ids] / n,
            }


def summarize(episodes: dict[str, np.ndarray], num_batches: int = 10) -> dict[str, dict[str, float]]:
    """Mean and std over consecutive batches of episodes (in benchmark order) of each metric."""
    num = len(episodes["collision"])
    num_batches = max(1, min(num_batches, num))
    batches = np.array_split(np.arange(num), num_batches)
    source = {
        "collision_rate": "collision",
        "height_violation_rate": "height_violation_rate",
        "position_deviation_m": "position_deviation_m",
        "rotation_deviation_rad": "rotation_deviation_rad",
        "power_w": "power_w",
    }
    out = {}
    for metric, key in source.items():
        per_batch = np.array([np.nanmean(episodes[key][b]) if np.isfinite(episodes[key][b]).any() else np.nan
                              for b in batches])  # fmt: skip
        finite = per_batch[np.isfinite(per_batch)]
        out[metric] = {
            "mean": float(finite.mean()) if len(finite) else float("nan"),
            "std": float(finite.std()) if len(finite) else float("nan"),
        }
    return out
