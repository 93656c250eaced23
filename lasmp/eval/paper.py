"""The paper's Table II: its row for each method we evaluate, to print beside ours (as in
docs/results.md#the-three-seed-study).

Means with the paper's std (it does not say over what). Keys: Stand Still, the R-S baselines
(`--controller`) and the policy names of `cfg/policy/` (the LAS-MP ablations).
"""

from __future__ import annotations

import re

PAPER_COLUMNS = (
    "collision_rate",
    "height_violation_rate",
    "position_deviation_m",
    "rotation_deviation_rad",
    "power_w",
)

# method -> (its name in the paper, ((mean, std) per PAPER_COLUMNS))
PAPER_ROWS: dict[str, tuple[str, tuple[tuple[float, float], ...]]] = {
    "lasmp": ("LAS-MP", ((0.029, 0.03), (0.009, 0.01), (0.366, 0.01), (0.071, 0.01), (2.904, 0.45))),
    "stand_still": (
        "Stand Still",
        ((0.612, 0.29), (0.142, 0.07), (0.394, 0.04), (0.182, 0.07), (1.031, 0.17)),
    ),
    "rs": ("R-S policy", ((0.922, 0.12), (0.232, 0.07), (0.478, 0.06), (0.241, 0.05), (8.121, 2.86))),
    "rs_oracle": (
        "R-S policy w/ oracle command",
        ((0.891, 0.18), (0.198, 0.01), (0.452, 0.05), (0.201, 0.04), (7.817, 2.95)),
    ),
    "no_alignment_command": (
        "w/o AC",
        ((0.287, 0.27), (0.327, 0.12), (0.367, 0.05), (0.195, 0.08), (4.658, 1.55)),
    ),
    "no_platform_velocity_estimates": (
        "w/o EE{PLV, PAV} & w/o AC",
        ((0.634, 0.37), (0.454, 0.29), (0.376, 0.04), (0.122, 0.06), (3.388, 0.83)),
    ),
    "no_explicit_estimator": (
        "w/o EE & w/o AC",
        ((0.359, 0.13), (0.534, 0.16), (0.496, 0.03), (0.159, 0.04), (6.614, 2.63)),
    ),
    "no_explicit_estimator_history": (
        "w/o EE & w/o AC & w/ history",
        ((0.314, 0.19), (0.525, 0.29), (0.456, 0.07), (0.177, 0.09), (6.139, 4.36)),
    ),
}


def paper_key(controller: str | None, method: str) -> str | None:
    """The PAPER_ROWS key of an evaluation: its baseline, or the policy name that `lasmp.eval.build.build` puts at
    the end of a checkpoint's method string ("LAS-MP+ checkpoint PATH (name)", the recipe's name first);
    None if neither."""
    if controller is not None:
        return controller
    match = re.search(r"\((\w+)\)$", method)
    return match.group(1) if match and match.group(1) in PAPER_ROWS else None


def paper_row(key: str | None) -> dict | None:
    """{"method": the paper's name, "metrics": {column: {"mean", "std"}}} or None."""
    if key not in PAPER_ROWS:
        return None
    name, values = PAPER_ROWS[key]
    return {
        "method": name,
        "metrics": {c: {"mean": m, "std": s} for c, (m, s) in zip(PAPER_COLUMNS, values, strict=True)},
    }
