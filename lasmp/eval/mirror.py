"""The mirror evaluation: play the mirror twins of benchmark episodes and compare the failures.

Episode k's twin is its image under the sagittal mirror (lasmp/envs/moving_platform/mirror.py): the
platform's y, roll and yaw negated, the robot's CoM mirrored, its legs' gains swapped, its heading
negated. A left-right symmetric controller fails the same episodes in both sets, and where one set
fails on a leg, the other fails on that leg's mirror image. Stand Still is such a controller, so its
overlap is 1.0: the check that the mirrored world is exact.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2_contingency

from lasmp.envs.moving_platform.mirror import mirror_intrinsics, mirror_pose_uniforms, mirror_trajectories
from lasmp.robots import a1


class MirroredBenchmark:
    """The mirror twins of a benchmark's episodes, with its pairing (a bench for `run_benchmark`)."""

    def __init__(self, bench, nominal_com_y_m: float, init_state):
        self.bench = bench
        self.trajectories = mirror_trajectories(bench.trajectories)
        self.robots = mirror_intrinsics(bench.robots, nominal_com_y_m)
        self.init_state = init_state

    @property
    def num_episodes(self) -> int:
        return self.bench.num_episodes

    def pairing(self, episodes):
        return self.bench.pairing(episodes)

    def initial_pose_draws(self, episodes) -> np.ndarray:
        return mirror_pose_uniforms(self.bench.initial_pose_draws(episodes), self.init_state)


def legs_in_cause(causes) -> np.ndarray:
    """(K, 4) bool: the legs (a1.LEG_NAMES order) whose hip, thigh or calf touched at each collision."""
    parts = [set(str(c).split("+")) for c in causes]
    return np.array(
        [[any(p.startswith(f"{leg}_") for p in bodies) for leg in a1.LEG_NAMES] for bodies in parts],
        dtype=bool,
    ).reshape(len(parts), 4)


def mirror_report(original: dict[str, np.ndarray], mirrored: dict[str, np.ndarray]) -> dict:
    """Compare the first K episodes (`run_benchmark`'s per-episode arrays) with their K mirror twins.

    - `failure_overlap`: |A ∩ B| / |A ∪ B| of the two sets of failed episodes (1.0 when both are empty);
    - per leg, the failures whose collision involves it, in each set; the twins' counts are compared
      leg by leg with their mirror legs' (`mirrored_legs_as_original`: the twins' counts relabelled by
      the mirror, equal to `original_legs` for a symmetric controller), with the p-value of a chi-squared
      test of one distribution over the legs for both (None when there are too few failures)."""
    k = len(mirrored["collision"])
    a = original["collision"][:k] > 0
    b = mirrored["collision"] > 0
    union = int(np.sum(a | b))
    legs_a = legs_in_cause(original["collision_cause"][:k][a]).sum(axis=0)
    legs_b = legs_in_cause(mirrored["collision_cause"][b]).sum(axis=0)
    relabelled = legs_b[list(a1.MIRROR_LEGS)]  # the twin's FL failure is the original's FR
    table = np.array([legs_a, relabelled])
    table = table[:, table.sum(axis=0) > 0]
    p = None
    if table.shape[1] >= 2 and table.sum() >= 10:
        p = float(chi2_contingency(table).pvalue)
    names = list(a1.LEG_NAMES)
    return {
        "episodes": k,
        "collision_rate_original": float(a.mean()),
        "collision_rate_mirrored": float(b.mean()),
        "failed_in_both": int(np.sum(a & b)),
        "failure_overlap": 1.0 if union == 0 else float(np.sum(a & b) / union),
        "original_legs": dict(zip(names, legs_a.tolist(), strict=True)),
        "mirrored_legs": dict(zip(names, legs_b.tolist(), strict=True)),
        "mirrored_legs_as_original": dict(zip(names, relabelled.tolist(), strict=True)),
        "legs_chi2_p": p,
    }


def mirror_markdown(report: dict) -> list[str]:
    legs = list(a1.LEG_NAMES)
    lines = [
        "",
        f"## Mirror evaluation (the first {report['episodes']} episodes and their mirror twins)",
        "",
        f"Collision rate {report['collision_rate_original']:.3f} / mirrored {report['collision_rate_mirrored']:.3f}; "
        f"failed in both {report['failed_in_both']}; overlap of the failure sets (IoU) "
        f"**{report['failure_overlap']:.3f}** (1.0 for a left-right symmetric controller).",
        "",
        "| failures touching leg | " + " | ".join(legs) + " |",
        "|---|" + "---|" * len(legs),
        "| original | " + " | ".join(str(report["original_legs"][g]) for g in legs) + " |",
        "| mirror twins | " + " | ".join(str(report["mirrored_legs"][g]) for g in legs) + " |",
        "| mirror twins, relabelled by the mirror | "
        + " | ".join(str(report["mirrored_legs_as_original"][g]) for g in legs)
        + " |",
    ]
    if report["legs_chi2_p"] is not None:
        lines += [
            "",
            f"χ² test, original against relabelled twins over the legs: p = {report['legs_chi2_p']:.2g}.",
        ]
    return lines
