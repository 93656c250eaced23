"""Benchmark metrics (docs/method.md, Evaluation), accumulated per env and step, closed per episode.

Every per-step quantity is counted on the steps *before* the episode's first collision (the
collision step itself and anything after it are not counted). Columns:
- collision_rate: 1 if the episode ended in a collision, a fall or a physics fault before T.
- height_violation_rate: share of counted steps with |p_body_p,z - h_des_p| > 0.1 m, where
  h_des_p = top + H_DES_ABOVE_TOP_M is 0.37 m above the platform's TOP surface in the platform
  frame, whatever height the policy was rewarded for (`rewards.h_des_from`): every method is scored
  against the same band (docs/method.md, Evaluation).
- position_deviation_m: mean over counted steps of ||p_body_p(t) - p_body_p(0)||, the trunk's
  position in the platform frame (it moves and turns with the platform).
- position_deviation_translating_m (extra column): the same in the translating frame,
  p_body_t = p_body_w - p_plf_w, which follows the platform's centre but keeps the world's axes, so
  the platform's rotation about its centre moves the trunk in it.
- rotation_deviation_rad: mean over counted steps of the trunk's tilt change in the world frame:
  the angle between its z axis at t and at the episode's start, each seen from the trunk's own
  heading frame (yaw removed), so turning about the vertical counts nothing. This is docs/method.md's (Evaluation)
  decided reading: a policy that keeps its trunk level while the platform tilts (task3) turns
  relative to the platform, so only the world reading ranks it below Stand Still, as the paper does.
- rotation_deviation_platform_rad (extra column): mean over counted steps of the angle of
  R_pb(0)^T R_pb(t), R_pb = R_wp^T R_wb the trunk's full orientation relative to the platform
  (the platform-relative reading of the paper's metric: docs/evaluation.md#the-metrics).
- power_w: mean over counted steps of sum_j max(tau_j q_dot_j, 0).
An episode with no counted step (a collision on its first step) contributes to the collision
rate only. Mean and std are over `num_batches` equal, consecutive batches of the benchmark's
episodes (per-batch means, then their mean and std), so the std says how much the figure
moves from one slice of the benchmark to another.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# the paper's five columns (Table II), in its order; the extra columns are other readings of two of them
METRICS = (
    "collision_rate",
    "height_violation_rate",
    "position_deviation_m",
    "rotation_deviation_rad",
    "power_w",
)
EXTRA_METRICS = ("position_deviation_translating_m", "rotation_deviation_platform_rad")
ALL_METRICS = METRICS + EXTRA_METRICS
# per-episode keys of `EpisodeMetrics.close` that feed each metric (the collision rate reads "collision")
EPISODE_KEY = {m: ("collision" if m == "collision_rate" else m) for m in ALL_METRICS}

H_DES_ABOVE_TOP_M = (
    0.37  # the paper's desired trunk height, above the platform's top surface (docs/method.md, Evaluation)
)
VIOLATION_M = 0.1  # half-width of the height band


def metric_h_des_p_m(plf_top_m: float) -> float:
    """The height band's centre in the platform frame (origin at its CoM), m: 0.37 m above the top.

    Independent of the reward's reading (`rewards.h_des_from`) so that a policy trained to crouch is
    scored by the same band as every other method."""
    return plf_top_m + H_DES_ABOVE_TOP_M


@dataclass
class TrunkPose:
    """The trunk's pose relative to the platform and the world, per env (host arrays)."""

    p_body_p: np.ndarray  # (n, 3) trunk origin in the platform frame, m
    p_body_t: np.ndarray  # (n, 3) trunk origin in the translating frame (world axes, platform centre), m
    r_wb: np.ndarray  # (n, 3, 3) trunk orientation in W
    r_wp: np.ndarray  # (n, 3, 3) platform orientation in W

    @classmethod
    def from_readout(cls, r) -> TrunkPose:
        """From a (numpy) readout with p_body_p, p_body_w, p_plf_w, r_wb and r_wp."""
        return cls(r.p_body_p, r.p_body_w - r.p_plf_w, r.r_wb, r.r_wp)

    def rows(self, ids: np.ndarray) -> TrunkPose:
        return TrunkPose(*(x[ids] for x in (self.p_body_p, self.p_body_t, self.r_wb, self.r_wp)))

    @property
    def r_pb(self) -> np.ndarray:
        """(n, 3, 3) the trunk's orientation relative to the platform, R_wp^T R_wb."""
        return np.einsum("nji,njk->nik", self.r_wp, self.r_wb)


def rotation_angle(r_a: np.ndarray, r_b: np.ndarray) -> np.ndarray:
    """Angle (rad) of the rotation between (n, 3, 3) orientations: |log(R_a^T R_b)|."""
    trace = np.einsum("nji,nji->n", r_a, r_b)
    return np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0))


def in_heading(v_w: np.ndarray, r_wb: np.ndarray) -> np.ndarray:
    """(n, 3) world vectors v_w in the trunk's heading frame: world axes turned by the trunk's yaw (ZYX)."""
    yaw = np.arctan2(r_wb[:, 1, 0], r_wb[:, 0, 0])
    c, s = np.cos(yaw), np.sin(yaw)
    return np.stack([c * v_w[:, 0] + s * v_w[:, 1], -s * v_w[:, 0] + c * v_w[:, 1], v_w[:, 2]], axis=1)


def z_axis_h(r_wb: np.ndarray) -> np.ndarray:
    """(n, 3) the trunk's z axis in its heading frame.

    Removing the yaw makes a turn about the world vertical leave it unchanged, whatever the tilt."""
    return in_heading(r_wb[:, :, 2], r_wb)


def angle_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(n,) angle (rad) between (n, 3) vectors; atan2 keeps small angles exact (arccos does not)."""
    return np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), np.einsum("ni,ni->n", u, v))


class EpisodeMetrics:
    """Running sums per env for the episode it plays; `close(ids)` returns finished episodes."""

    SUMS = ("steps", "violations", "pos_dev_p", "pos_dev_t", "tilt_w", "rot_p", "power")

    def __init__(self, num_envs: int, h_des_p_m: float, violation_m: float = VIOLATION_M):
        self.h_des_p_m = h_des_p_m
        self.violation_m = violation_m
        self.sums = {k: np.zeros(num_envs) for k in self.SUMS}
        self.p0_p = np.zeros((num_envs, 3))
        self.p0_t = np.zeros((num_envs, 3))
        self.z0_h = np.tile([0.0, 0.0, 1.0], (num_envs, 1))
        self.r0_pb = np.tile(np.eye(3), (num_envs, 1, 1))

    def start(self, ids: np.ndarray, pose: TrunkPose) -> None:
        """Envs `ids` begin an episode at `pose` (its rows are those envs, in that order)."""
        for buf in self.sums.values():
            buf[ids] = 0.0
        self.p0_p[ids] = pose.p_body_p
        self.p0_t[ids] = pose.p_body_t
        self.z0_h[ids] = z_axis_h(pose.r_wb)
        self.r0_pb[ids] = pose.r_pb

    def step(self, active: np.ndarray, collision: np.ndarray, pose: TrunkPose, tau, q_dot) -> None:
        """Add one step of every env that is `active` and did not collide on this step."""
        count = active & ~collision
        s = self.sums
        s["steps"] += count
        s["violations"] += count * (np.abs(pose.p_body_p[:, 2] - self.h_des_p_m) > self.violation_m)
        s["pos_dev_p"] += count * np.linalg.norm(pose.p_body_p - self.p0_p, axis=1)
        s["pos_dev_t"] += count * np.linalg.norm(pose.p_body_t - self.p0_t, axis=1)
        s["tilt_w"] += count * angle_between(self.z0_h, z_axis_h(pose.r_wb))
        s["rot_p"] += count * rotation_angle(self.r0_pb, pose.r_pb)
        s["power"] += count * np.maximum(tau * q_dot, 0.0).sum(axis=1)

    def close(self, ids: np.ndarray, collided: np.ndarray) -> dict[str, np.ndarray]:
        """Per-episode values of envs `ids` (NaN where no step was counted)."""
        s = {k: v[ids] for k, v in self.sums.items()}
        n = s["steps"]
        with np.errstate(invalid="ignore", divide="ignore"):
            return {
                "collision": collided.astype(float),
                "steps": n.copy(),
                "height_violation_rate": s["violations"] / n,
                "position_deviation_m": s["pos_dev_p"] / n,
                "position_deviation_translating_m": s["pos_dev_t"] / n,
                "rotation_deviation_rad": s["tilt_w"] / n,
                "rotation_deviation_platform_rad": s["rot_p"] / n,
                "power_w": s["power"] / n,
            }


def summarize(
    episodes: dict[str, np.ndarray], num_batches: int = 10, columns: tuple[str, ...] = METRICS
) -> dict[str, dict[str, float]]:
    """Mean and std over consecutive batches of episodes (in benchmark order) of each metric in
    `columns` (default the paper's five; `ALL_METRICS` adds the extra readings)."""
    num = len(episodes["collision"])
    num_batches = max(1, min(num_batches, num))
    batches = np.array_split(np.arange(num), num_batches)
    out = {}
    for metric in columns:
        values = np.asarray(episodes[EPISODE_KEY[metric]], dtype=float)
        per_batch = np.array(
            [np.nanmean(values[b]) if np.isfinite(values[b]).any() else np.nan for b in batches]
        )
        finite = per_batch[np.isfinite(per_batch)]
        out[metric] = {
            "mean": float(finite.mean()) if len(finite) else float("nan"),
            "std": float(finite.std()) if len(finite) else float("nan"),
        }
    return out
