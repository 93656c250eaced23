"""6-DoF platform reference trajectories (SPEC §4): generation, evaluation, files, statistics.

Pose
    Everywhere a pose is ``[x, y, z, roll, pitch, yaw]`` (m, m, m, rad, rad, rad): the platform's
    joint displacement from its initial pose, so the initial pose is all zeros. The rotational
    joints compose as ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``; nothing here rotates anything.

Representation
    Every trajectory set is a :class:`PiecewiseCubic`: per row, knot times ``t_0 = 0 < ... <
    t_{K-1}`` and, per segment, power-basis coefficients in local time ``tau = t - t_k``
    (ascending order: ``c0 + c1 tau + c2 tau^2 + c3 tau^3``). Rows may have different knot
    counts (padding: +inf breaks, zero coefficients). Before 0 the time clamps to 0; past the
    last knot the last pose holds with zero velocity and acceleration.

Generated trajectories (:func:`sample`)
    Knot 0 is the initial pose (zeros) at t = 0, then N waypoints drawn uniformly in the ranges
    at ``t_k = k T / N`` (k = 1..N, the last at T). Interpolated by a cubic spline (a cubic
    B-spline with knots at the waypoints, written in power basis) with *clamped* ends: zero
    velocity at t = 0 (the platform starts at rest) and at t = T (it ends at rest, so holding
    the last pose afterwards is C1). Inside, the spline is C2: position and velocity are
    smooth for the platform PD, acceleration is continuous.

User-made trajectories (:func:`from_samples`)
    An interpolating cubic spline through sampled poses with *not-a-knot* ends (the most
    faithful to the samples; no zero-velocity condition is imposed: the data decide). 2 samples
    give a line, 3 a parabola. ``poses[:, 0]`` must be the initial pose (zeros).

Spline coefficients are computed by our own tridiagonal (Thomas) solve with element-wise numpy
operations, so a row's coefficients do not depend on which other rows are built with it: a set
rebuilt from its knots (file load, subsets) evaluates bit-identically.

File format (``.npz``, written by :func:`save`, read by :func:`load`)
    ``format`` = "lasmp-trajectories", ``version`` = 1, ``kind`` = one of

    * "waypoints" (generated sets, compact): ``knot_times_s`` (M, Kmax) float64 and
      ``waypoints`` (M, Kmax, 6) float64 — the knots *including* knot 0 (t = 0, zero pose) —
      padded at the end of each row with NaN; ``n_waypoints`` (M,) int (row m has
      ``n_waypoints[m] + 1`` knots). The clamped spline is rebuilt on load.
    * "samples" (user-made): ``t_s`` (K,) shared times, or (M, K) per-row times padded at the
      end with NaN, and ``poses`` (M, K, 6) (NaN where the times are NaN). Rebuilt with
      not-a-knot ends.

    Optional ``meta_json``: a JSON string (e.g. split and seed), available as ``traj.meta``.

CLI: ``python -m lasmp.envs.trajectories {stats,plot,generate} --help``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import zipfile
from dataclasses import dataclass, field

import numpy as np

from lasmp.atomic import atomic_open

FORMAT_NAME = "lasmp-trajectories"
FORMAT_VERSION = 1
POSE_NAMES = ("x", "y", "z", "roll", "pitch", "yaw")
_CLAMPED, _NOT_A_KNOT = 0, 1  # end conditions, per row
_START_TOL = 1e-6  # |pose| at t = 0 must be below this (the platform's initial pose)


class TrajectoryFileError(ValueError):
    """A trajectory file or a user-made trajectory is malformed; the message names the problem."""


# --------------------------------------------------------------------------------------------
# Ranges
# --------------------------------------------------------------------------------------------
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
    """Ranges of the "train" or "test" split (SPEC Table B)."""
    if split == "train":
        return TRAIN_RANGES
    if split == "test":
        return TEST_RANGES
    raise ValueError(f"unknown trajectory split {split!r}; valid: 'train', 'test'")


# --------------------------------------------------------------------------------------------
# Spline construction (vectorized over rows with the same knot count)
# --------------------------------------------------------------------------------------------
def _slopes(x: np.ndarray, y: np.ndarray, end: int) -> np.ndarray:
    """Knot velocities of the cubic spline through (x (G,n), y (G,n,6)); Thomas solve, no pivoting."""
    g, n = x.shape
    h = np.diff(x, axis=1)  # (G, n-1)
    d = np.diff(y, axis=1) / h[:, :, None]  # (G, n-1, 6) secant slopes
    if end == _NOT_A_KNOT and n == 2:
        return np.concatenate([d, d], axis=1)
    if end == _NOT_A_KNOT and n == 3:  # the parabola through the 3 points
        c = (d[:, 1] - d[:, 0]) / (h[:, 0] + h[:, 1])[:, None]
        return np.stack([d[:, 0] - c * h[:, :1], d[:, 0] + c * h[:, :1], d[:, 1] + c * h[:, 1:2]], axis=1)
    a = np.zeros((g, n))  # sub-diagonal
    b = np.ones((g, n))  # diagonal
    c = np.zeros((g, n))  # super-diagonal
    r = np.zeros((g, n, 6))
    a[:, 1:-1] = h[:, 1:]
    b[:, 1:-1] = 2.0 * (h[:, :-1] + h[:, 1:])
    c[:, 1:-1] = h[:, :-1]
    r[:, 1:-1] = 3.0 * (h[:, 1:, None] * d[:, :-1] + h[:, :-1, None] * d[:, 1:])
    if end == _NOT_A_KNOT:  # third derivative continuous across the second and last-but-one knots
        s0 = h[:, 0] + h[:, 1]
        b[:, 0], c[:, 0] = h[:, 1], s0
        r[:, 0] = (
            (h[:, 0] + 2.0 * s0)[:, None] * h[:, 1, None] * d[:, 0] + (h[:, 0] ** 2)[:, None] * d[:, 1]
        ) / s0[:, None]
        s1 = h[:, -1] + h[:, -2]
        a[:, -1], b[:, -1] = s1, h[:, -2]
        r[:, -1] = (
            (h[:, -1] ** 2)[:, None] * d[:, -2] + (2.0 * s1 + h[:, -1])[:, None] * h[:, -2, None] * d[:, -1]
        ) / s1[:, None]
    # clamped: rows 0 and n-1 stay "1 * s = 0" (zero velocity at both ends)
    for i in range(1, n):
        w = a[:, i] / b[:, i - 1]
        b[:, i] = b[:, i] - w * c[:, i - 1]
        r[:, i] = r[:, i] - w[:, None] * r[:, i - 1]
    s = np.empty_like(r)
    s[:, -1] = r[:, -1] / b[:, -1, None]
    for i in range(n - 2, -1, -1):
        s[:, i] = (r[:, i] - c[:, i, None] * s[:, i + 1]) / b[:, i, None]
    return s


def _coefficients(x: np.ndarray, y: np.ndarray, end: int) -> np.ndarray:
    """Power-basis coefficients (G, n-1, 4, 6), ascending order, of the spline through the knots."""
    s = _slopes(x, y, end)
    h = np.diff(x, axis=1)[:, :, None]
    d = np.diff(y, axis=1) / h
    s0, s1 = s[:, :-1], s[:, 1:]
    c2 = (3.0 * d - 2.0 * s0 - s1) / h
    c3 = (s0 + s1 - 2.0 * d) / (h * h)
    return np.stack([y[:, :-1], s0, c2, c3], axis=2)


# --------------------------------------------------------------------------------------------
# The representation
# --------------------------------------------------------------------------------------------
@dataclass
class PiecewiseCubic:
    """M piecewise-cubic 6-DoF trajectories, evaluable for thousands of rows at once.

    Attributes: ``knot_times_s`` (M, K) and ``knot_poses`` (M, K, 6), NaN-padded; ``n_knots`` (M,);
    ``end_condition`` (M,) (0 clamped / generated, 1 not-a-knot / user-made); ``n_waypoints`` (M,)
    (-1 for user-made rows); derived ``breaks_s`` (M, K) (+inf padded) and ``coeffs``
    (M, K-1, 4, 6) (zero padded). Build with :meth:`from_knots`, :func:`sample`, :func:`from_samples`.
    """

    knot_times_s: np.ndarray
    knot_poses: np.ndarray
    n_knots: np.ndarray
    end_condition: np.ndarray
    n_waypoints: np.ndarray
    breaks_s: np.ndarray
    coeffs: np.ndarray
    meta: dict = field(default_factory=dict)

    @classmethod
    def from_knots(cls, knot_times_s, knot_poses, n_knots, end_condition, n_waypoints) -> PiecewiseCubic:
        """Build the splines from (validated) NaN-padded knots; vectorized per (knot count, end) group."""
        t = np.asarray(knot_times_s, dtype=np.float64)
        p = np.asarray(knot_poses, dtype=np.float64)
        nk = np.asarray(n_knots, dtype=np.int64)
        end = np.asarray(end_condition, dtype=np.int8)
        m, k = t.shape
        breaks = np.full((m, k), np.inf)
        coeffs = np.zeros((m, max(k - 1, 1), 4, 6))
        for n, e in sorted({(int(a), int(b)) for a, b in zip(nk, end, strict=True)}):
            rows = np.flatnonzero((nk == n) & (end == e))
            breaks[rows, :n] = t[rows, :n]
            if n == 1:  # a single knot: hold it
                coeffs[rows, 0, 0] = p[rows, 0]
                continue
            coeffs[rows, : n - 1] = _coefficients(t[rows, :n], p[rows, :n], e)
        return cls(t, p, nk, end, np.asarray(n_waypoints, dtype=np.int64).copy(), breaks, coeffs)

    def __len__(self) -> int:
        return self.knot_times_s.shape[0]

    @property
    def duration_s(self) -> np.ndarray:
        """(M,) time of each row's last knot, s."""
        return self.knot_times_s[np.arange(len(self)), self.n_knots - 1]

    def evaluate(self, t_s, rows=None):
        """Pose, velocity, acceleration (n, 6) each, at t_s (n,) (or a scalar), one time per row.

        ``rows=None`` means all M rows in order; otherwise an index array of length n.
        """
        rows = np.arange(len(self)) if rows is None else np.asarray(rows, dtype=np.int64).reshape(-1)
        t = np.broadcast_to(np.asarray(t_s, dtype=np.float64), rows.shape)
        nk = self.n_knots[rows]
        b = self.breaks_s[rows]  # (n, K)
        t_end = b[np.arange(len(rows)), nk - 1]
        past = t >= t_end
        tc = np.clip(t, 0.0, t_end)
        seg = np.minimum(np.sum(b[:, 1:] <= tc[:, None], axis=1), np.maximum(nk - 2, 0))
        tau = (tc - b[np.arange(len(rows)), seg])[:, None]
        c = self.coeffs[rows, seg]  # (n, 4, 6)
        pos = c[:, 0] + tau * (c[:, 1] + tau * (c[:, 2] + tau * c[:, 3]))
        vel = c[:, 1] + tau * (2.0 * c[:, 2] + 3.0 * tau * c[:, 3])
        acc = 2.0 * c[:, 2] + 6.0 * tau * c[:, 3]
        vel[past] = 0.0
        acc[past] = 0.0
        return pos, vel, acc

    def subset(self, rows) -> PiecewiseCubic:
        """A new set holding the given rows (copies)."""
        rows = np.asarray(rows, dtype=np.int64).reshape(-1)
        return PiecewiseCubic(
            self.knot_times_s[rows],
            self.knot_poses[rows],
            self.n_knots[rows],
            self.end_condition[rows],
            self.n_waypoints[rows],
            self.breaks_s[rows],
            self.coeffs[rows],
            dict(self.meta),
        )

    def _pad_to(self, k: int) -> None:
        cur = self.knot_times_s.shape[1]
        if k <= cur:
            return
        m, extra = len(self), k - cur
        self.knot_times_s = np.concatenate([self.knot_times_s, np.full((m, extra), np.nan)], axis=1)
        self.knot_poses = np.concatenate([self.knot_poses, np.full((m, extra, 6), np.nan)], axis=1)
        self.breaks_s = np.concatenate([self.breaks_s, np.full((m, extra), np.inf)], axis=1)
        nseg = self.coeffs.shape[1]
        self.coeffs = np.concatenate([self.coeffs, np.zeros((m, max(k - 1, 1) - nseg, 4, 6))], axis=1)

    def replace_rows(self, rows, other: PiecewiseCubic) -> None:
        """In place: rows of self get other's rows (len(other) == len(rows)); pads K as needed."""
        rows = np.asarray(rows, dtype=np.int64).reshape(-1)
        if len(other) != len(rows):
            raise ValueError(f"replace_rows: {len(rows)} rows but other has {len(other)}")
        k = max(self.knot_times_s.shape[1], other.knot_times_s.shape[1])
        self._pad_to(k)
        if other.knot_times_s.shape[1] < k:
            other = other.subset(np.arange(len(other)))
            other._pad_to(k)
        for name in (
            "knot_times_s",
            "knot_poses",
            "n_knots",
            "end_condition",
            "n_waypoints",
            "breaks_s",
            "coeffs",
        ):
            getattr(self, name)[rows] = getattr(other, name)


# --------------------------------------------------------------------------------------------
# Generation and user-made trajectories
# --------------------------------------------------------------------------------------------
def sample(num: int, ranges: TrajectoryRanges, rng: np.random.Generator, n_waypoints=None) -> PiecewiseCubic:
    """Draw ``num`` trajectories (see the module docstring); reproducible from ``rng``.

    ``n_waypoints``: None (uniform in the ranges' N), an int, or a (num,) int array.
    """
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
    return PiecewiseCubic.from_knots(
        times[:, :kmax], poses[:, :kmax], n + 1, np.full(num, _CLAMPED, np.int8), n
    )


def _check_knots(t: np.ndarray, p: np.ndarray, where: str) -> np.ndarray:
    """Validate NaN-padded knots t (M,K), p (M,K,6); return the per-row knot counts."""
    if t.ndim != 2 or p.shape != t.shape + (6,):
        raise TrajectoryFileError(
            f"{where}: times must be (M, K) and poses (M, K, 6), got {t.shape} and {p.shape}"
        )
    if t.shape[1] < 1:
        raise TrajectoryFileError(f"{where}: no samples (K = 0)")
    valid = ~np.isnan(t)
    nk = valid.sum(axis=1)
    if not np.all(valid == (np.arange(t.shape[1])[None, :] < nk[:, None])):
        raise TrajectoryFileError(
            f"{where}: NaN in the times (NaN is only allowed as padding at the end of a row)"
        )
    if np.any(nk < 1):
        raise TrajectoryFileError(f"{where}: a row has no knots")
    if not np.all(np.isfinite(t[valid])):
        raise TrajectoryFileError(f"{where}: times must be finite")
    pv = p[valid]
    if np.isnan(pv).any():
        raise TrajectoryFileError(f"{where}: NaN in the poses")
    if not np.all(np.isfinite(pv)):
        raise TrajectoryFileError(f"{where}: poses must be finite")
    if not np.all(np.isnan(p[~valid])):
        raise TrajectoryFileError(f"{where}: poses present where the times are padding (NaN)")
    if np.any(t[:, 0] != 0.0):
        raise TrajectoryFileError(
            f"{where}: times must start at 0 s (got first time {t[:, 0][t[:, 0] != 0][0]!r})"
        )
    dt = np.diff(t, axis=1)
    if np.any(dt[valid[:, 1:]] <= 0.0):
        raise TrajectoryFileError(f"{where}: times must be strictly increasing")
    if np.any(np.abs(p[:, 0]) > _START_TOL):
        bad = int(np.flatnonzero(np.any(np.abs(p[:, 0]) > _START_TOL, axis=1))[0])
        raise TrajectoryFileError(
            f"{where}: the trajectory must start at the platform's initial pose (zeros); "
            f"row {bad} starts at {p[bad, 0].tolist()}"
        )
    return nk


def from_samples(t_s, poses, *, where: str = "from_samples") -> PiecewiseCubic:
    """Interpolating cubic spline (not-a-knot ends) through user samples.

    t_s: (K,) shared or (M, K) per-row times, s, starting at 0 and strictly increasing;
    poses: (M, K, 6) (or (K, 6) for one trajectory); ``poses[:, 0]`` must be zeros within 1e-6.
    Raises TrajectoryFileError naming the problem.
    """
    try:
        t = np.asarray(t_s, dtype=np.float64)
        p = np.asarray(poses, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise TrajectoryFileError(f"{where}: times and poses must be numeric arrays ({exc})") from None
    if p.ndim == 2:
        p = p[None]
    if p.ndim != 3 or p.shape[2] != 6:
        raise TrajectoryFileError(f"{where}: poses must be (M, K, 6), got {np.shape(poses)}")
    if t.ndim == 1:
        t = np.broadcast_to(t, (p.shape[0], t.shape[0]))
    if t.ndim != 2 or t.shape != p.shape[:2]:
        raise TrajectoryFileError(
            f"{where}: times must be (K,) or (M, K) matching poses {p.shape}, got {np.shape(t_s)}"
        )
    if np.isnan(t).any() or np.isnan(p).any():
        raise TrajectoryFileError(f"{where}: NaN in the samples")
    nk = _check_knots(t, p, where)
    m = p.shape[0]
    return PiecewiseCubic.from_knots(t, p, nk, np.full(m, _NOT_A_KNOT, np.int8), np.full(m, -1))


# --------------------------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------------------------
def save(path, traj: PiecewiseCubic, meta: dict | None = None) -> None:
    """Write ``traj`` to ``path`` (used verbatim, no suffix added) atomically (temp file + os.replace)."""
    path = os.fspath(path)
    kinds = set(np.unique(traj.end_condition).tolist())
    arrays: dict[str, np.ndarray] = {"format": np.array(FORMAT_NAME), "version": np.array(FORMAT_VERSION)}
    if kinds <= {_CLAMPED}:
        arrays.update(
            kind=np.array("waypoints"),
            knot_times_s=traj.knot_times_s,
            waypoints=traj.knot_poses,
            n_waypoints=traj.n_knots - 1,
        )
    elif kinds == {_NOT_A_KNOT}:
        t = traj.knot_times_s
        shared = bool(np.all(traj.n_knots == t.shape[1])) and bool(np.all(t == t[:1]))
        arrays.update(kind=np.array("samples"), t_s=t[0].copy() if shared else t, poses=traj.knot_poses)
    else:
        raise ValueError("save: cannot store a set mixing generated and user-made rows; save them separately")
    meta = {**traj.meta, **(meta or {})}
    if meta:
        arrays["meta_json"] = np.array(json.dumps(meta))
    with atomic_open(path) as f:
        np.savez(f, **arrays)  # a file object: savez appends no ".npz"


def read_npz(path: str, error: type[Exception]):
    """Read every array of an .npz file; return `get(key, optional=False)`, which raises `error` naming
    the file and a missing key (or returns None for a missing optional one). An unreadable or
    non-.npz file raises `error` too."""
    try:
        z = np.load(path, allow_pickle=False)
        if not isinstance(z, np.lib.npyio.NpzFile):  # a plain .npy array
            raise error(f"{path}: not an .npz archive (it holds a single .npy array)")
        with z:
            data = {k: z[k] for k in z.files}
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, KeyError) as exc:
        raise error(f"{path}: not a readable .npz archive (truncated or corrupt?): {exc}") from None

    def get(key: str, optional: bool = False) -> np.ndarray | None:
        if key not in data:
            if optional:
                return None
            raise error(f"{path}: missing key {key!r} (keys present: {sorted(data)})")
        return data[key]

    return get


def load(path) -> PiecewiseCubic:
    """Read and validate a trajectory file; any problem raises TrajectoryFileError naming file and problem."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise TrajectoryFileError(f"{path}: no such trajectory file")
    get = read_npz(path, TrajectoryFileError)

    def text(key: str) -> str:
        v = get(key)
        if v.shape != () or v.dtype.kind != "U":
            raise TrajectoryFileError(f"{path}: key {key!r} must be a string")
        return str(v)

    if text("format") != FORMAT_NAME:
        raise TrajectoryFileError(f"{path}: format is {text('format')!r}, expected {FORMAT_NAME!r}")
    version = get("version")
    if version.shape != () or version.dtype.kind not in "iu" or int(version) != FORMAT_VERSION:
        raise TrajectoryFileError(f"{path}: unsupported version {version!r}, expected {FORMAT_VERSION}")
    kind = text("kind")
    if kind == "waypoints":
        t, p, nw = get("knot_times_s"), get("waypoints"), get("n_waypoints")
        for key, arr in (("knot_times_s", t), ("waypoints", p)):
            if arr.dtype.kind != "f":
                raise TrajectoryFileError(f"{path}: {key!r} must be float, got {arr.dtype}")
        if nw.dtype.kind not in "iu" or nw.ndim != 1 or nw.shape[0] != t.shape[0]:
            raise TrajectoryFileError(
                f"{path}: 'n_waypoints' must be an int array of shape (M,) = ({t.shape[0]},), "
                f"got {nw.dtype} {nw.shape}"
            )
        nk = _check_knots(t.astype(np.float64), p.astype(np.float64), path)
        if np.any(nk != nw + 1):
            raise TrajectoryFileError(
                f"{path}: 'n_waypoints' disagrees with the number of knots (NaN padding) in some rows"
            )
        traj = PiecewiseCubic.from_knots(t, p, nk, np.full(len(nk), _CLAMPED, np.int8), nw)
    elif kind == "samples":
        t, p = get("t_s"), get("poses")
        if t.dtype.kind != "f" or p.dtype.kind != "f":
            raise TrajectoryFileError(f"{path}: 't_s' and 'poses' must be float arrays")
        if t.ndim == 1:
            if p.ndim != 3 or p.shape[1:] != (t.shape[0], 6):
                raise TrajectoryFileError(f"{path}: 'poses' must be (M, K={t.shape[0]}, 6), got {p.shape}")
            t = np.broadcast_to(t, p.shape[:2])
        nk = _check_knots(np.asarray(t, np.float64), p.astype(np.float64), path)
        traj = PiecewiseCubic.from_knots(
            t, p, nk, np.full(len(nk), _NOT_A_KNOT, np.int8), np.full(len(nk), -1)
        )
    else:
        raise TrajectoryFileError(f"{path}: unknown kind {kind!r}; valid: 'waypoints', 'samples'")
    if get("meta_json", optional=True) is not None:
        try:
            traj.meta = json.loads(text("meta_json"))
        except json.JSONDecodeError as exc:
            raise TrajectoryFileError(f"{path}: 'meta_json' is not valid JSON ({exc})") from None
    return traj


# --------------------------------------------------------------------------------------------
# Statistics
# --------------------------------------------------------------------------------------------
def _row_stats(traj: PiecewiseCubic, dt_s: float, chunk: int) -> dict[str, np.ndarray]:
    """Per-row path length (m), mean speed (m/s), max speed (m/s), mean curvature (1/m)."""
    m = len(traj)
    out = {k: np.full(m, np.nan) for k in ("length", "speed", "max_speed", "curv", "curv_median")}
    dur = traj.duration_s
    for lo in range(0, m, chunk):
        rows = np.arange(lo, min(lo + chunk, m))
        ns = int(np.floor(dur[rows].max() / dt_s + 1e-9)) + 1
        grid = np.arange(ns) * dt_s
        rr = np.repeat(rows, ns)
        pos, vel, acc = traj.evaluate(np.tile(grid, len(rows)), rr)
        p, v, a = (x[:, :3].reshape(len(rows), ns, 3) for x in (pos, vel, acc))
        inside = grid[None, :] <= dur[rows, None] + 1e-12
        step = np.linalg.norm(np.diff(p, axis=1), axis=2)  # polyline; zero once the row holds
        out["length"][rows] = step.sum(axis=1)
        speed = np.linalg.norm(v, axis=2)
        out["max_speed"][rows] = np.where(inside, speed, 0.0).max(axis=1)
        ok = inside & (speed > 0.05)
        kappa = np.where(ok, np.linalg.norm(np.cross(v, a), axis=2) / np.maximum(speed, 0.05) ** 3, np.nan)
        cnt = ok.sum(axis=1)
        with np.errstate(invalid="ignore"):
            out["curv"][rows] = np.where(cnt > 0, np.nansum(kappa, axis=1) / np.maximum(cnt, 1), np.nan)
        if cnt.any():
            med = np.full(len(rows), np.nan)
            med[cnt > 0] = np.nanmedian(kappa[cnt > 0], axis=1)
            out["curv_median"][rows] = med
    out["speed"] = out["length"] / np.where(dur > 0, dur, np.nan)
    return out


def statistics(traj: PiecewiseCubic, dt_s: float = 0.02, chunk: int = 500) -> dict:
    """Translational-path statistics of a set, overall and per N (keys: str(N); "-1" = user-made).

    Sampled every ``dt_s`` on [0, duration]. Per trajectory: path length = polyline length of
    (x, y, z); mean speed = path length / duration; max speed = max |v|; curvature
    |v x a| / |v|^3 averaged over the samples with |v| > 0.05 m/s (slower samples are skipped:
    there the curvature blows up where the path nearly stops and turns). Reported: the means
    over trajectories (curvature: over those with at least one such sample), the overall max
    speed, and the mean of per-trajectory median curvatures (robust to the remaining spikes).
    """
    s = _row_stats(traj, dt_s, chunk)

    def block(sel: np.ndarray) -> dict:
        def mean(x):
            x = x[sel]
            x = x[np.isfinite(x)]
            return float(x.mean()) if x.size else float("nan")

        return {
            "num": int(sel.sum()),
            "mean_path_length_m": mean(s["length"]),
            "mean_speed_mps": mean(s["speed"]),
            "max_speed_mps": float(s["max_speed"][sel].max()) if sel.any() else float("nan"),
            "mean_curvature_per_m": mean(s["curv"]),
            "median_curvature_per_m": mean(s["curv_median"]),
        }

    per_n = {str(n): block(traj.n_waypoints == n) for n in np.unique(traj.n_waypoints)}
    return {"num": len(traj), "dt_s": dt_s, "overall": block(np.ones(len(traj), bool)), "per_n": per_n}


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------
def _traj_from_args(args) -> PiecewiseCubic:
    if getattr(args, "file", None):
        return load(args.file)
    return sample(args.num, ranges_for_split(args.split), np.random.default_rng(args.seed))


def _print_table(stats: dict) -> None:
    cols = (
        "num",
        "mean_path_length_m",
        "mean_speed_mps",
        "max_speed_mps",
        "mean_curvature_per_m",
        "median_curvature_per_m",
    )
    heads = ("N", "count", "length m", "speed m/s", "max m/s", "curv 1/m", "med curv 1/m")
    print(" ".join(f"{h:>12}" for h in heads))
    rows = list(stats["per_n"].items()) + [("all", stats["overall"])]
    for name, b in rows:
        print(f"{name:>12} " + " ".join(f"{b[c]:>12d}" if c == "num" else f"{b[c]:>12.3f}" for c in cols))


def _plot(traj: PiecewiseCubic, stats: dict, out: str, dt_s: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(15, 9))
    ax3 = fig.add_subplot(2, 3, (1, 4), projection="3d")
    axz = fig.add_subplot(2, 3, 2)
    ns = np.unique(traj.n_waypoints)
    picks = [int(np.flatnonzero(traj.n_waypoints == n)[0]) for n in ns[:: max(1, len(ns) // 5)]]
    for r in picks:
        grid = np.arange(0.0, traj.duration_s[r] + 1e-9, dt_s)
        p = traj.evaluate(grid, np.full(len(grid), r))[0]
        ax3.plot(p[:, 0], p[:, 1], p[:, 2], label=f"N={traj.n_waypoints[r]}")
        wp = traj.knot_poses[r, : traj.n_knots[r]]
        ax3.scatter(wp[:, 0], wp[:, 1], wp[:, 2], s=8)
        axz.plot(grid, p[:, 2], label=f"N={traj.n_waypoints[r]}")
    ax3.set(xlabel="x (m)", ylabel="y (m)", zlabel="z (m)", title="example translational paths")
    ax3.legend(fontsize=7)
    axz.set(xlabel="t (s)", ylabel="z (m)", title="height over time")
    keys = list(stats["per_n"])
    for i, (col, lab) in enumerate(
        (
            ("mean_path_length_m", "path length (m)"),
            ("mean_speed_mps", "mean speed (m/s)"),
            ("mean_curvature_per_m", "mean curvature (1/m)"),
        )
    ):
        ax = fig.add_subplot(2, 3, (3, 5, 6)[i])
        ax.bar(keys, [stats["per_n"][k][col] for k in keys])
        ax.set(xlabel="N waypoints", ylabel=lab, title=f"{lab} per N")
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m lasmp.envs.trajectories", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)

    def common(p, num):
        p.add_argument("--split", choices=("train", "test"), default="test")
        p.add_argument("--num", type=int, default=num)
        p.add_argument("--seed", type=int, default=0)

    ps = sub.add_parser("stats", help="path length / speed / curvature, overall and per N")
    common(ps, 10000)
    ps.add_argument("--file", help="use a saved trajectory file instead of sampling")
    ps.add_argument("--dt", type=float, default=0.02, help="sampling step, s")
    ps.add_argument("--json", action="store_true", help="print one JSON object only")
    pp = sub.add_parser("plot", help="example paths and per-N statistics to a PNG")
    common(pp, 200)
    pp.add_argument("--file", help="use a saved trajectory file instead of sampling")
    pp.add_argument("--dt", type=float, default=0.02)
    pp.add_argument("--out", required=True)
    pg = sub.add_parser("generate", help="sample a set and write it to a file")
    common(pg, 10000)
    pg.add_argument("--out", required=True)
    args = ap.parse_args(argv)
    if getattr(args, "num", 1) < 1:
        ap.error("--num must be >= 1")
    if getattr(args, "dt", 1.0) <= 0:
        ap.error("--dt must be > 0")
    try:
        traj = _traj_from_args(args)
    except TrajectoryFileError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.cmd == "stats":
        st = statistics(traj, args.dt)
        if args.json:
            print(json.dumps(st))
        else:
            _print_table(st)
    elif args.cmd == "plot":
        _plot(traj, statistics(traj, args.dt), args.out, args.dt)
        print(f"wrote {args.out}", file=sys.stderr)
    else:
        save(args.out, traj, meta={"split": args.split, "seed": args.seed, "num": args.num})
        print(f"wrote {len(traj)} trajectories to {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
