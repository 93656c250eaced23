"""How an episode fails: the state at its collision step, and the failures a baseline would not have.

An evaluation records, for each episode that ends in a collision, the state at that step
(`FAILURE_KEYS`, NaN in the episodes that survive):
- `feet_on_deck_at_failure`: how many feet touched the platform (0-4): a failure on four feet is a
  push the stance could not hold; one on two or fewer, a step or a stumble that went wrong;
- `deck_tilt_at_failure_rad`: the platform's tilt from the world's vertical, the angle between its
  z axis and the world's, at that step (the record's `platform_tilt_max_rad` is the episode's maximum,
  known only with the platform probe);
- `trunk_tilt_at_failure_rad`: the trunk's tilt from the world's vertical at that step.

`state_tables` breaks an episodes table's failures down by these; `against_baseline` pairs its
episodes with a baseline's evaluation of the same episodes (Stand Still's, say) and counts the
failures in the episodes the baseline survives: those a policy adds, not the world's hard ones.
"""

from __future__ import annotations

import numpy as np

FAILURE_KEYS = ("feet_on_deck_at_failure", "deck_tilt_at_failure_rad", "trunk_tilt_at_failure_rad")
AT_FAILURE_TILT_BINS_RAD = (0.0, 0.1, 0.2, 0.3, 0.4, 0.6, 0.8)  # the last bin is [0.8, inf)


def tilt_from_vertical_rad(r_w: np.ndarray) -> np.ndarray:
    """(n,) the angle (rad) between the z axis of (n, 3, 3) orientations in W and the world's z."""
    return np.arccos(np.clip(r_w[:, 2, 2], -1.0, 1.0))


def failure_state(
    feet_on_deck: np.ndarray, r_wp: np.ndarray, r_wb: np.ndarray, collided: np.ndarray
) -> dict[str, np.ndarray]:
    """FAILURE_KEYS -> (n,) for n episodes ending at this step: `feet_on_deck` (n, 4) bool, the
    platform's and the trunk's orientations in W (n, 3, 3); NaN where the episode did not collide."""

    def only_failed(x: np.ndarray) -> np.ndarray:
        return np.where(collided, x, np.nan)

    return {
        "feet_on_deck_at_failure": only_failed(feet_on_deck.sum(axis=1).astype(float)),
        "deck_tilt_at_failure_rad": only_failed(tilt_from_vertical_rad(r_wp)),
        "trunk_tilt_at_failure_rad": only_failed(tilt_from_vertical_rad(r_wb)),
    }


def bins(values: np.ndarray, edges, fmt: str) -> list[tuple[str, np.ndarray]]:
    """[(label, mask)] for bins [e_i, e_{i+1}), the last one open-ended; NaN falls in none."""
    out = []
    for i, lo in enumerate(edges):
        hi = edges[i + 1] if i + 1 < len(edges) else np.inf
        label = f"[{lo:{fmt}}, {hi:{fmt}})" if np.isfinite(hi) else f">= {lo:{fmt}}"
        out.append((label, (values >= lo) & (values < hi)))
    return out


def _tilt_bins(values: np.ndarray) -> list[tuple[str, int]]:
    return [(label, int(mask.sum())) for label, mask in bins(values, AT_FAILURE_TILT_BINS_RAD, ".1f")]


def state_tables(t: dict[str, np.ndarray]) -> dict | None:
    """The failures counted by feet on the deck and by the deck's and the trunk's tilt at the
    collision step, with the median tilts; None for a record made before these were kept."""
    collided = t["collided"] > 0.5
    if "feet_on_deck_at_failure" not in t:  # a table built without them
        return None
    feet = t["feet_on_deck_at_failure"][collided]
    if not collided.any() or not np.isfinite(feet).any():
        return None
    deck, trunk = t["deck_tilt_at_failure_rad"][collided], t["trunk_tilt_at_failure_rad"][collided]
    return {
        "failures": int(collided.sum()),
        "by_feet": [(str(k), int((feet == k).sum())) for k in range(5)],
        "by_deck_tilt": _tilt_bins(deck),
        "by_trunk_tilt": _tilt_bins(trunk),
        "median_deck_tilt_rad": float(np.nanmedian(deck)),
        "median_trunk_tilt_rad": float(np.nanmedian(trunk)),
    }


def against_baseline(t: dict[str, np.ndarray], baseline: dict[str, np.ndarray]) -> dict:
    """t's failures in the episodes `baseline` survives, and t's collision rate where it survives and
    where it fails; episodes paired by number, refused when the baseline lacks one of t's or pairs it
    with another robot or trajectory (ValueError: the breakdown names the file)."""
    row = {int(k): i for i, k in enumerate(baseline["episode"])}
    missing = [int(k) for k in t["episode"] if int(k) not in row]
    if missing:
        raise ValueError(f"the baseline lacks {len(missing)} of the episodes, e.g. episode {missing[0]}")
    idx = np.array([row[int(k)] for k in t["episode"]], dtype=int)
    for c in ("foot_friction", "n_waypoints"):
        if not np.array_equal(t[c], baseline[c][idx]):
            raise ValueError(f"the baseline holds other episodes: its {c} differs")
    failed = t["collided"] > 0.5
    survives = baseline["collided"][idx] < 0.5
    n_fail = int(failed.sum())
    return {
        "failures": n_fail,
        "in_survived": int((failed & survives).sum()),
        "share_in_survived": float((failed & survives).sum() / n_fail) if n_fail else float("nan"),
        "survived_episodes": int(survives.sum()),
        "rate_where_survived": float(failed[survives].mean()) if survives.any() else float("nan"),
        "rate_where_failed": float(failed[~survives].mean()) if (~survives).any() else float("nan"),
    }


def markdown(state: dict | None, paired: dict | None, baseline_name: str = "the baseline") -> list[str]:
    """The Markdown lines of `state_tables` and `against_baseline` (either may be None)."""
    lines: list[str] = []
    if state is None:
        lines += ["", "No state at failure in this record (evaluated before it was kept)."]
    else:
        n = state["failures"]

        def counts(title: str, head: str, rows):
            lines.extend(["", f"## {title}", "", f"| {head} | failures | share |", "|---|---|---|"])
            lines.extend(f"| {label} | {c} | {c / n:.3f} |" for label, c in rows if c)

        counts("Feet on the deck at the failure", "feet", state["by_feet"])
        counts("The deck's tilt from the vertical at the failure (rad)", "deck tilt", state["by_deck_tilt"])
        counts(
            "The trunk's tilt from the vertical at the failure (rad)", "trunk tilt", state["by_trunk_tilt"]
        )
        lines += [
            "",
            f"Median tilt at the failure: the deck {state['median_deck_tilt_rad']:.3f} rad, "
            f"the trunk {state['median_trunk_tilt_rad']:.3f} rad.",
        ]
    if paired is not None:
        lines += [
            "",
            f"Against {baseline_name}: {paired['in_survived']} of the {paired['failures']} failures "
            f"({paired['share_in_survived']:.3f}) are in the {paired['survived_episodes']} episodes it "
            f"survives; the collision rate there is {paired['rate_where_survived']:.3f}, and "
            f"{paired['rate_where_failed']:.3f} where it fails.",
        ]
    return lines
