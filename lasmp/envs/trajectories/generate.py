"""Generated trajectory sets (docs/trajectories.md): the waypoint ranges of each split, and :func:`sample`.

A generated trajectory is N waypoints drawn uniformly in the split's ranges (the paper's Table B, docs/environment.md), over
T = ``duration_s``; the nominal time of waypoint k is ``k T / N``. The waypoints, with the initial
pose (zeros) as knot 0 at t = 0, become a spline by the construction of a :class:`SplineSpec`
(:mod:`lasmp.envs.trajectories.splines`; default: the approximating B-spline of degree 10).
:func:`sample` draws all N first, then all waypoints, from the generator it is given.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lasmp.envs.trajectories.splines import PiecewisePoly, SplineSpec


@dataclass(frozen=True)
class TrajectoryRanges:
    """Waypoint coordinate ranges (pose order x, y, z, roll, pitch, yaw; m and rad) and N range."""

    low: tuple[float, ...] = (-1.0, -1.0, 0.0, -0.7, -0.7, -2.6)
    high: tuple[float, ...] = (1.0, 1.0, 5.0, 0.7, 0.7, 2.6)
    n_waypoints_min: int = 5
    n_waypoints_max: int = 15
    duration_s: float = 10.0

    def __post_init__(self):
        lo, hi = np.asarray(self.low, float), np.asarray(self.high, float)
        if lo.shape != (6,) or hi.shape != (6,) or not np.all(lo <= hi):
            raise ValueError(
                f"TrajectoryRanges: low/high must be 6 values with low <= high, got {self.low}, {self.high}"
            )
        if not 1 <= self.n_waypoints_min <= self.n_waypoints_max:
            raise ValueError(
                "TrajectoryRanges: need 1 <= n_waypoints_min <= n_waypoints_max, "
                f"got {self.n_waypoints_min}..{self.n_waypoints_max}"
            )
        if not self.duration_s > 0:
            raise ValueError(f"TrajectoryRanges: duration_s must be > 0, got {self.duration_s}")


TRAIN_RANGES = TrajectoryRanges(n_waypoints_min=5, n_waypoints_max=15)
TEST_RANGES = TrajectoryRanges(n_waypoints_min=4, n_waypoints_max=16)


def ranges_for_split(split: str) -> TrajectoryRanges:
    """Ranges of the "train" or "test" split (the paper's Table B, docs/environment.md)."""
    if split == "train":
        return TRAIN_RANGES
    if split == "test":
        return TEST_RANGES
    raise ValueError(f"unknown trajectory split {split!r}; valid: 'train', 'test'")


def sample(
    num: int,
    ranges: TrajectoryRanges,
    rng: np.random.Generator,
    n_waypoints=None,
    spline: SplineSpec | None = None,
) -> PiecewisePoly:
    """Draw ``num`` trajectories (see the module docstring); reproducible from ``rng``.

    ``n_waypoints``: None (uniform in the ranges' N), an int, or a (num,) int array.
    ``spline``: the construction (default: the approximating B-spline of degree DEFAULT_DEGREE).
    """
    spline = spline or SplineSpec()
    if n_waypoints is None:
        n = rng.integers(ranges.n_waypoints_min, ranges.n_waypoints_max + 1, size=num)
    else:
        n = np.broadcast_to(np.asarray(n_waypoints, dtype=np.int64), (num,)).copy()
    n = n.astype(np.int64)
    if num and n.min() < 1:
        raise ValueError(f"sample: n_waypoints must be >= 1, got {n.min()}")
    n_max = max(int(n.max()) if num else 0, ranges.n_waypoints_max)
    wp = rng.uniform(np.asarray(ranges.low), np.asarray(ranges.high), size=(num, n_max, 6))
    k = np.arange(n_max + 1, dtype=np.float64)
    times = (k[None, :] * ranges.duration_s) / n[:, None]
    poses = np.concatenate([np.zeros((num, 1, 6)), wp], axis=1)
    pad = k[None, :] > n[:, None]
    times[pad] = np.nan
    poses[pad] = np.nan
    kmax = n_max + 1 if n_waypoints is None else int(n.max(initial=0)) + 1
    return PiecewisePoly.from_knots(times[:, :kmax], poses[:, :kmax], n + 1, spline.code, spline.degree, n)


PROBE_ROWS = 64


def sample_bytes(num: int, ranges: TrajectoryRanges, spline: SplineSpec | None = None) -> tuple[int, int]:
    """A lower bound of the memory :func:`sample` of ``num`` trajectories takes, in bytes, and its share
    per trajectory: the waypoints it draws first (float64, the split's largest N) and the arrays of the
    result, measured on a sample of PROBE_ROWS (its own generator: the caller's draws are untouched)."""
    probe = sample(PROBE_ROWS, ranges, np.random.default_rng(0), spline=spline)
    held = sum(a.nbytes for a in vars(probe).values() if isinstance(a, np.ndarray))
    per_row = -(-held // PROBE_ROWS) + ranges.n_waypoints_max * 6 * 8
    return num * per_row, per_row
