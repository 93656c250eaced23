"""6-DoF platform reference trajectories (SPEC §4): generation, evaluation, files, statistics.

Pose
    Everywhere a pose is ``[x, y, z, roll, pitch, yaw]`` (m, m, m, rad, rad, rad): the platform's
    joint displacement from its initial pose, so the initial pose is all zeros. The rotational
    joints compose as ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``; nothing here rotates anything.

Generated trajectories (:func:`sample`): N waypoints drawn uniformly in the ranges, over T.
    Two constructions (:class:`SplineSpec`), both built with ``scipy.interpolate``:

    * ``"approximating"`` (default, SPEC §4): the waypoints are the *control points* of a clamped
      uniform B-spline (``scipy.interpolate.BSpline``) of degree ``degree`` (default 10), lowered
      to (control points - 1) when there are fewer. The control polygon is
      ``[0, 0, 0, w_1, ..., w_N, w_N, w_N]``: the initial pose and the last waypoint are each
      repeated three times, so the path starts at the initial pose and ends at w_N with zero
      velocity *and* acceleration (a clamped B-spline's j-th end derivative depends only on the
      first/last j + 1 control points). With the rest before t = 0 and after T it is C2
      everywhere (C^(degree-1) inside). The path lies in the convex hull of its control points.
      Its knots are uniform in time over [0, T] (clamped: the end knots have multiplicity
      degree + 1); the waypoints' nominal times ``k T / N`` are stored, but only T is used.
      Why degree 10 and tripled ends: on the testing split (10,000 draws, seed 0) they give a
      mean path length of 6.90 m and mean speed of 0.690 m/s, the closest to the paper's 7.12 m and
      0.69 m/s; degrees 5 / 7 / 9 / 11 give 10.41 / 8.53 / 7.34 / 6.53 m (README, "Trajectories").
    * ``"interpolating"`` (the harder, non-default reading): a cubic spline *through* the initial
      pose at t = 0 and the waypoints at ``t_k = k T / N`` (``scipy.interpolate.make_interp_spline``)
      with clamped ends (zero velocity at 0 and T). C2 inside; mean path length 23.7 m.

User-made trajectories (:func:`from_samples`)
    A cubic spline through sampled poses with *not-a-knot* ends (``make_interp_spline``; 2
    samples give a line, 3 a parabola). ``poses[:, 0]`` must be the initial pose (zeros).

Representation (:class:`PiecewisePoly`)
    Every set, whatever its construction, is evaluated from a per-row piecewise polynomial in
    power basis: breakpoints ``breaks_s`` and, per segment, coefficients in local time
    ``tau = t - break`` (ascending order, up to the highest degree in the set, zero padded), so
    thousands of rows with different knots evaluate in one vectorized Horner pass. Before 0
    the time clamps to 0; past the end the last pose holds with zero velocity and acceleration.
    Rows are built per group of identical knot times and construction, so a row's polynomial
    does not depend on which other rows are built with it: a set rebuilt from its knots (file
    load, subsets) evaluates bit-identically.

File format (``.npz``, written by :func:`save`, read by :func:`load`)
    ``format`` = "lasmp-trajectories", ``version`` = 2, ``kind`` = one of

    * "waypoints" (generated sets, compact): ``knot_times_s`` (M, Kmax) float64 and
      ``waypoints`` (M, Kmax, 6) float64 -- the knots *including* knot 0 (t = 0, zero pose) --
      padded at the end of each row with NaN; ``n_waypoints`` (M,) int (row m has
      ``n_waypoints[m] + 1`` knots); ``spline`` ("approximating" or "interpolating") and
      ``spline_degree`` (int): the construction, so the file rebuilds the same motion whatever
      today's defaults are.
    * "samples" (user-made): ``t_s`` (K,) shared times, or (M, K) per-row times padded at the
      end with NaN, and ``poses`` (M, K, 6) (NaN where the times are NaN). Rebuilt with
      not-a-knot ends.

    Optional ``meta_json``: a JSON string (e.g. split and seed), available as ``traj.meta``.
    Version 1 files (the old interpolating-only generator, which recorded no construction) are
    refused with an error that says how to regenerate them.

CLI: ``python -m lasmp.envs.trajectories {stats,plot,generate} --help``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import zipfile
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline

from lasmp.atomic import atomic_open

FORMAT_NAME = "lasmp-trajectories"
FORMAT_VERSION = 2
POSE_NAMES = ("x", "y", "z", "roll", "pitch", "yaw")
# per-row construction codes (PiecewisePoly.kind)
APPROXIMATING, INTERPOLATING, SAMPLES = 0, 1, 2
KIND_NAMES = ("approximating", "interpolating", "samples")
GENERATED_KINDS = ("approximating", "interpolating")
END_REPEATS = 3  # copies of the first / last control point: zero velocity and acceleration at the ends
_START_TOL = 1e-6  # |pose| at t = 0 must be below this (the platform's initial pose)


class TrajectoryFileError(ValueError):
    """A trajectory file or a user-made trajectory is malformed; the message names the problem."""


# --------------------------------------------------------------------------------------------
# Ranges and construction
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


DEFAULT_DEGREE = 10  # calibrated to the paper's testing-set statistics (module docstring)
MAX_DEGREE = 15


@dataclass(frozen=True)
class SplineSpec:
    """How generated waypoints become a trajectory: ``kind`` and the approximating B-spline's degree."""

    kind: str = "approximating"
    degree: int = DEFAULT_DEGREE  # approximating only (the interpolating spline is cubic)

    def __post_init__(self):
        if self.kind not in GENERATED_KINDS:
            raise ValueError(f"unknown trajectory kind {self.kind!r}; valid: {list(GENERATED_KINDS)}")
        if not 3 <= self.degree <= MAX_DEGREE:  # degree >= 3 keeps the path C2
            raise ValueError(f"spline degree must be in 3..{MAX_DEGREE} (C2 needs >= 3), got {self.degree}")

    @property
    def code(self) -> int:
        return KIND_NAMES.index(self.kind)


# --------------------------------------------------------------------------------------------
# Construction with scipy, per group of rows sharing knot times (vectorized over the group)
# --------------------------------------------------------------------------------------------
def _power_basis(spl: BSpline, breaks: np.ndarray) -> np.ndarray:
    """Coefficients (G, S, k+1, 6) in local time of `spl` (c: (n, G, 6)) on the S segments of `breaks`.

    Coefficient j of a segment is the j-th derivative at its left break over j!; BSpline evaluates
    a knot with the interval to its right, i.e. the segment's own polynomial.
    """
    x = breaks[:-1]
    c = np.stack([spl(x, nu=j) / math.factorial(j) for j in range(spl.k + 1)], axis=1)  # (S, k+1, G, 6)
    return np.ascontiguousarray(c.transpose(2, 0, 1, 3))


def _approximating(duration_s: float, poses: np.ndarray, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Clamped uniform B-spline over the control polygon [0 x3, w_1..w_N, w_N x2] (poses: (G, N+1, 6))."""
    first, last = poses[:, :1], poses[:, -1:]
    ctrl = np.concatenate(
        [np.repeat(first, END_REPEATS - 1, axis=1), poses, np.repeat(last, END_REPEATS - 1, axis=1)], axis=1
    )
    n_ctrl = ctrl.shape[1]
    k = min(degree, n_ctrl - 1)
    breaks = np.linspace(0.0, duration_s, n_ctrl - k + 1)
    knots = np.concatenate([np.zeros(k), breaks, np.full(k, duration_s)])
    spl = BSpline(knots, ctrl.transpose(1, 0, 2), k)
    return breaks, _power_basis(spl, breaks)


def _interpolating(times: np.ndarray, poses: np.ndarray, clamped: bool) -> tuple[np.ndarray, np.ndarray]:
    """Cubic spline through (times (K,), poses (G, K, 6)): clamped (zero end velocity) or not-a-knot."""
    n = len(times)
    if clamped:
        rest = [(1, np.zeros(poses.shape[::2]))]  # zero velocity, per row and channel
        spl = make_interp_spline(times, poses.transpose(1, 0, 2), k=3, bc_type=(rest, rest))
    else:  # not-a-knot; with 2 or 3 samples the line or the parabola through them
        spl = make_interp_spline(times, poses.transpose(1, 0, 2), k=min(3, n - 1))
    return times, _power_basis(spl, times)


def _build_group(kind: int, degree: int, times: np.ndarray, poses: np.ndarray):
    """(breaks (S+1,), coeffs (G, S, d+1, 6)) of rows sharing knot times `times` (K,)."""
    if len(times) == 1:  # a single knot: hold it (one zero-length segment)
        return np.zeros(2), poses[:, None, :1, :].copy()
    if kind == APPROXIMATING:
        return _approximating(float(times[-1]), poses, degree)
    return _interpolating(times, poses, clamped=kind == INTERPOLATING)


# --------------------------------------------------------------------------------------------
# The representation
# --------------------------------------------------------------------------------------------
_ROW_FIELDS = ("knot_times_s", "knot_poses", "n_knots", "kind", "degree", "n_waypoints",
               "breaks_s", "n_segments", "coeffs")  # fmt: skip


@dataclass
class PiecewisePoly:
    """M 6-DoF trajectories as piecewise polynomials, evaluable for thousands of rows at once.

    Source data: ``knot_times_s`` (M, K) and ``knot_poses`` (M, K, 6), NaN-padded (knot 0 is the
    initial pose at t = 0); ``n_knots`` (M,); ``kind`` (M,) (APPROXIMATING, INTERPOLATING or
    SAMPLES); ``degree`` (M,) the construction's degree parameter; ``n_waypoints`` (M,) (-1 for
    user-made rows). Derived: ``breaks_s`` (M, S+1) (+inf padded), ``n_segments`` (M,), ``coeffs``
    (M, S, D+1, 6) (zero padded). Build with :meth:`from_knots`, :func:`sample`, :func:`from_samples`.
    """

    knot_times_s: np.ndarray
    knot_poses: np.ndarray
    n_knots: np.ndarray
    kind: np.ndarray
    degree: np.ndarray
    n_waypoints: np.ndarray
    breaks_s: np.ndarray
    n_segments: np.ndarray
    coeffs: np.ndarray
    meta: dict = field(default_factory=dict)

    @classmethod
    def from_knots(cls, knot_times_s, knot_poses, n_knots, kind, degree, n_waypoints) -> PiecewisePoly:
        """Build the polynomials from (validated) NaN-padded knots, per group of identical construction."""
        t = np.asarray(knot_times_s, dtype=np.float64)
        p = np.asarray(knot_poses, dtype=np.float64)
        m = t.shape[0]
        nk = np.asarray(n_knots, dtype=np.int64)
        kinds = np.broadcast_to(np.asarray(kind, dtype=np.int8), (m,)).copy()
        degrees = np.broadcast_to(np.asarray(degree, dtype=np.int64), (m,)).copy()
        key = np.column_stack([kinds, degrees, np.nan_to_num(t, nan=-1.0)])
        groups, inverse = np.unique(key, axis=0, return_inverse=True)
        built = []
        for g in range(len(groups)):
            rows = np.flatnonzero(inverse.reshape(-1) == g)
            n = int(nk[rows[0]])
            breaks, coeffs = _build_group(
                int(kinds[rows[0]]), int(degrees[rows[0]]), t[rows[0], :n], p[rows, :n]
            )
            built.append((rows, breaks, coeffs))
        s_max = max((len(b) - 1 for _, b, _ in built), default=1)
        d_max = max((c.shape[2] for _, _, c in built), default=1)
        breaks_s = np.full((m, s_max + 1), np.inf)
        n_seg = np.zeros(m, dtype=np.int64)
        coeffs = np.zeros((m, s_max, d_max, 6))
        for rows, breaks, c in built:
            breaks_s[rows, : len(breaks)] = breaks
            n_seg[rows] = len(breaks) - 1
            coeffs[rows, : c.shape[1], : c.shape[2]] = c
        nw = np.asarray(n_waypoints, dtype=np.int64).copy()
        return cls(t, p, nk, kinds, degrees, nw, breaks_s, n_seg, coeffs)

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
        idx = np.arange(len(rows))
        ns = self.n_segments[rows]
        b = self.breaks_s[rows]  # (n, S+1)
        t_end = b[idx, ns]
        past = t >= t_end
        tc = np.clip(t, 0.0, t_end)
        seg = np.minimum(np.sum(b[:, 1:] <= tc[:, None], axis=1), ns - 1)
        tau = (tc - b[idx, seg])[:, None]
        c = self.coeffs[rows, seg]  # (n, D+1, 6)
        # Horner with derivatives: pos = sum c_j tau^j, vel = its derivative, half_acc = half the second
        pos, vel, half_acc = c[:, -1].copy(), np.zeros_like(c[:, 0]), np.zeros_like(c[:, 0])
        for j in range(c.shape[1] - 2, -1, -1):
            half_acc = half_acc * tau + vel
            vel = vel * tau + pos
            pos = pos * tau + c[:, j]
        acc = 2.0 * half_acc
        vel[past] = 0.0
        acc[past] = 0.0
        return pos, vel, acc

    def subset(self, rows) -> PiecewisePoly:
        """A new set holding the given rows (copies)."""
        rows = np.asarray(rows, dtype=np.int64).reshape(-1)
        return PiecewisePoly(*(getattr(self, f)[rows] for f in _ROW_FIELDS), meta=dict(self.meta))

    def _padded(self, k: int, s: int, d: int) -> PiecewisePoly:
        """A copy (or self) whose knot, segment and coefficient axes have at least k, s, d entries."""
        m = len(self)
        kk, ss, dd = self.knot_times_s.shape[1], self.coeffs.shape[1], self.coeffs.shape[2]
        if kk >= k and ss >= s and dd >= d:
            return self
        k, s, d = max(k, kk), max(s, ss), max(d, dd)
        t = np.full((m, k), np.nan)
        p = np.full((m, k, 6), np.nan)
        b = np.full((m, s + 1), np.inf)
        c = np.zeros((m, s, d, 6))
        t[:, :kk], p[:, :kk], b[:, : ss + 1], c[:, :ss, :dd] = (
            self.knot_times_s,
            self.knot_poses,
            self.breaks_s,
            self.coeffs,
        )
        return PiecewisePoly(t, p, self.n_knots.copy(), self.kind.copy(), self.degree.copy(),
                             self.n_waypoints.copy(), b, self.n_segments.copy(), c, dict(self.meta))  # fmt: skip

    def replace_rows(self, rows, other: PiecewisePoly) -> None:
        """In place: rows of self get other's rows (len(other) == len(rows)); pads axes as needed."""
        rows = np.asarray(rows, dtype=np.int64).reshape(-1)
        if len(other) != len(rows):
            raise ValueError(f"replace_rows: {len(rows)} rows but other has {len(other)}")
        dims = (
            max(self.knot_times_s.shape[1], other.knot_times_s.shape[1]),
            max(self.coeffs.shape[1], other.coeffs.shape[1]),
            max(self.coeffs.shape[2], other.coeffs.shape[2]),
        )
        grown = self._padded(*dims)
        if grown is not self:
            for f in _ROW_FIELDS:
                setattr(self, f, getattr(grown, f))
        other = other._padded(*dims)
        for f in _ROW_FIELDS:
            getattr(self, f)[rows] = getattr(other, f)


# --------------------------------------------------------------------------------------------
# Generation and user-made trajectories
# --------------------------------------------------------------------------------------------
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


def from_samples(t_s, poses, *, where: str = "from_samples") -> PiecewisePoly:
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
    return PiecewisePoly.from_knots(t, p, nk, SAMPLES, 3, np.full(p.shape[0], -1))


# --------------------------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------------------------
def waypoint_arrays(traj: PiecewisePoly) -> dict[str, np.ndarray]:
    """The "waypoints" layout of a generated set (one construction): knots, N, spline kind and degree."""
    kinds, degrees = np.unique(traj.kind), np.unique(traj.degree)
    if len(kinds) != 1 or int(kinds[0]) == SAMPLES or len(degrees) != 1:
        raise ValueError(
            "a waypoints file holds generated rows of one construction (kind and degree); "
            f"got kinds {[KIND_NAMES[k] for k in kinds]} and degrees {degrees.tolist()}"
        )
    return {
        "knot_times_s": np.ascontiguousarray(traj.knot_times_s, dtype=np.float64),
        "waypoints": np.ascontiguousarray(traj.knot_poses, dtype=np.float64),
        "n_waypoints": np.ascontiguousarray(traj.n_knots - 1, dtype=np.int64),
        "spline": np.array(KIND_NAMES[int(kinds[0])]),
        "spline_degree": np.array(int(degrees[0]), dtype=np.int64),
    }


def save(path, traj: PiecewisePoly, meta: dict | None = None) -> None:
    """Write ``traj`` to ``path`` (used verbatim, no suffix added) atomically (temp file + os.replace)."""
    path = os.fspath(path)
    arrays: dict[str, np.ndarray] = {"format": np.array(FORMAT_NAME), "version": np.array(FORMAT_VERSION)}
    if np.all(traj.kind == SAMPLES):
        t = traj.knot_times_s
        shared = bool(np.all(traj.n_knots == t.shape[1])) and bool(np.all(t == t[:1]))
        arrays.update(kind=np.array("samples"), t_s=t[0].copy() if shared else t, poses=traj.knot_poses)
    elif np.any(traj.kind == SAMPLES):
        raise ValueError("save: cannot store a set mixing generated and user-made rows; save them separately")
    else:
        arrays.update(kind=np.array("waypoints"), **waypoint_arrays(traj))
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


def _text(get, path: str, key: str, error: type[Exception]) -> str:
    v = get(key)
    if v.shape != () or v.dtype.kind != "U":
        raise error(f"{path}: key {key!r} must be a string")
    return str(v)


def check_version(get, path: str, expected: int, error: type[Exception], regenerate: str) -> None:
    """Refuse a file of another format version, saying how to make a current one."""
    version = get("version")
    if version.shape != () or version.dtype.kind not in "iu":
        raise error(f"{path}: 'version' must be an integer scalar, got {version.dtype} {version.shape}")
    if int(version) != expected:
        hint = (
            " Version 1 files hold the old interpolating-cubic waypoints with no record of the spline "
            "construction; they cannot be read as today's approximating B-splines."
            if int(version) < expected
            else ""
        )
        raise error(f"{path}: unsupported version {int(version)}, expected {expected}.{hint} {regenerate}")


def waypoints_from_arrays(get, path: str, error: type[Exception]) -> PiecewisePoly:
    """Validate and build the "waypoints" layout (waypoint_arrays) read through `get`."""
    t, p, nw = get("knot_times_s"), get("waypoints"), get("n_waypoints")
    for key, arr in (("knot_times_s", t), ("waypoints", p)):
        if arr.dtype.kind != "f":
            raise error(f"{path}: {key!r} must be float, got {arr.dtype}")
    if t.ndim != 2 or t.shape[0] < 1 or p.shape != t.shape + (6,):
        raise error(
            f"{path}: wrong shape: 'knot_times_s' must be (M, K) and 'waypoints' (M, K, 6), "
            f"got {t.shape} and {p.shape}"
        )
    if nw.dtype.kind not in "iu" or nw.shape != (t.shape[0],):
        raise error(
            f"{path}: wrong shape: 'n_waypoints' must be int ({t.shape[0]},), got {nw.dtype} {nw.shape}"
        )
    kind = _text(get, path, "spline", error)
    degree = get("spline_degree")
    if degree.shape != () or degree.dtype.kind not in "iu":
        raise error(f"{path}: 'spline_degree' must be an integer scalar, got {degree.dtype} {degree.shape}")
    try:
        spec = SplineSpec(kind, int(degree))
        nk = _check_knots(t.astype(np.float64), p.astype(np.float64), path)
    except ValueError as exc:  # TrajectoryFileError included
        raise error(f"{path}: {exc}") from None
    if np.any(nk != nw + 1):
        raise error(f"{path}: 'n_waypoints' disagrees with the number of knots (NaN padding) in some rows")
    return PiecewisePoly.from_knots(t, p, nk, spec.code, spec.degree, nw)


def load(path) -> PiecewisePoly:
    """Read and validate a trajectory file; any problem raises TrajectoryFileError naming file and problem."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise TrajectoryFileError(f"{path}: no such trajectory file")
    get = read_npz(path, TrajectoryFileError)
    err = TrajectoryFileError
    if _text(get, path, "format", err) != FORMAT_NAME:
        raise err(f"{path}: format is {_text(get, path, 'format', err)!r}, expected {FORMAT_NAME!r}")
    check_version(get, path, FORMAT_VERSION, err,
                  "Regenerate it with `python -m lasmp.envs.trajectories generate`.")  # fmt: skip
    kind = _text(get, path, "kind", err)
    if kind == "waypoints":
        traj = waypoints_from_arrays(get, path, err)
    elif kind == "samples":
        t, p = get("t_s"), get("poses")
        if t.dtype.kind != "f" or p.dtype.kind != "f":
            raise err(f"{path}: 't_s' and 'poses' must be float arrays")
        if t.ndim == 1:
            if p.ndim != 3 or p.shape[1:] != (t.shape[0], 6):
                raise err(f"{path}: 'poses' must be (M, K={t.shape[0]}, 6), got {p.shape}")
            t = np.broadcast_to(t, p.shape[:2])
        nk = _check_knots(np.asarray(t, np.float64), p.astype(np.float64), path)
        traj = PiecewisePoly.from_knots(t, p, nk, SAMPLES, 3, np.full(len(nk), -1))
    else:
        raise err(f"{path}: unknown kind {kind!r}; valid: 'waypoints', 'samples'")
    if get("meta_json", optional=True) is not None:
        try:
            traj.meta = json.loads(_text(get, path, "meta_json", err))
        except json.JSONDecodeError as exc:
            raise err(f"{path}: 'meta_json' is not valid JSON ({exc})") from None
    return traj


# --------------------------------------------------------------------------------------------
# Statistics
# --------------------------------------------------------------------------------------------
_SLOW_MPS = 0.05  # curvature is not sampled below this speed (it diverges where the path stops)


def angular_rate(pose: np.ndarray, vel: np.ndarray) -> np.ndarray:
    """|omega| (rad/s) of the platform from ZYX Euler angles and their rates (..., 6 pose layout)."""
    pitch, yaw = pose[..., 4], pose[..., 5]
    droll, dpitch, dyaw = vel[..., 3], vel[..., 4], vel[..., 5]
    # omega_w = dyaw e_z + dpitch Rz e_y + droll Rz Ry e_x
    wx = -np.sin(yaw) * dpitch + np.cos(yaw) * np.cos(pitch) * droll
    wy = np.cos(yaw) * dpitch + np.sin(yaw) * np.cos(pitch) * droll
    wz = dyaw - np.sin(pitch) * droll
    return np.sqrt(wx * wx + wy * wy + wz * wz)


def _samples(traj: PiecewisePoly, dt_s: float, chunk: int):
    """Per-row length, mean and max speed; pooled per-sample |a|, |omega|, curvature with their rows."""
    m = len(traj)
    rows_out = {k: np.full(m, np.nan) for k in ("length", "max_speed")}
    pooled = {k: [] for k in ("acc", "omega", "curv", "row_acc", "row_curv")}
    dur = traj.duration_s
    for lo in range(0, m, chunk):
        rows = np.arange(lo, min(lo + chunk, m))
        ns = int(np.floor(dur[rows].max() / dt_s + 1e-9)) + 1
        grid = np.arange(ns) * dt_s
        pos, vel, acc = traj.evaluate(np.tile(grid, len(rows)), np.repeat(rows, ns))
        pos, vel, acc = (x.reshape(len(rows), ns, 6) for x in (pos, vel, acc))
        p, v, a = pos[..., :3], vel[..., :3], acc[..., :3]
        inside = grid[None, :] <= dur[rows, None] + 1e-12
        rows_out["length"][rows] = np.linalg.norm(np.diff(p, axis=1), axis=2).sum(axis=1)  # 0 once it holds
        speed = np.linalg.norm(v, axis=2)
        rows_out["max_speed"][rows] = np.where(inside, speed, 0.0).max(axis=1)
        rr = np.broadcast_to(rows[:, None], inside.shape)
        pooled["acc"].append(np.linalg.norm(a, axis=2)[inside].astype(np.float32))
        pooled["omega"].append(angular_rate(pos, vel)[inside].astype(np.float32))
        pooled["row_acc"].append(rr[inside])
        moving = inside & (speed > _SLOW_MPS)
        kappa = np.linalg.norm(np.cross(v, a), axis=2)[moving] / speed[moving] ** 3
        pooled["curv"].append(kappa.astype(np.float32))
        pooled["row_curv"].append(rr[moving])
    rows_out["speed"] = rows_out["length"] / np.where(dur > 0, dur, np.nan)
    return rows_out, {k: np.concatenate(v) for k, v in pooled.items()}


def statistics(traj: PiecewisePoly, dt_s: float = 0.02, chunk: int = 500) -> dict:
    """Translational-path and rotation statistics of a set, overall and per N (keys: str(N); "-1" = user-made).

    Sampled every ``dt_s`` on [0, duration] of each trajectory.
    - mean path length (m): mean over trajectories of the polyline length of (x, y, z);
    - mean speed (m/s): mean over trajectories of path length / duration;
    - max speed (m/s): the largest |v| of any sample;
    - p99 acceleration (m/s^2) and p99 angular rate (rad/s): 99th percentiles of |a| (translation)
      and of |omega| (the platform's angular velocity from the Euler rates) over all samples;
    - curvature (1/m), estimator: kappa = |v x a| / |v|^3 of the analytic spline derivatives at
      every sample with |v| > 0.05 m/s (slower samples are skipped: kappa diverges where the path
      stops and turns); reported as the mean and the median of all such samples (pooled).
    """
    s, pool = _samples(traj, dt_s, chunk)

    def block(sel: np.ndarray) -> dict:
        def mean(x):
            x = x[sel]
            x = x[np.isfinite(x)]
            return float(x.mean()) if x.size else float("nan")

        def pooled(key, row_key, fn):
            vals = pool[key][sel[pool[row_key]]]
            return float(fn(vals)) if vals.size else float("nan")

        return {
            "num": int(sel.sum()),
            "mean_path_length_m": mean(s["length"]),
            "mean_speed_mps": mean(s["speed"]),
            "max_speed_mps": float(s["max_speed"][sel].max()) if sel.any() else float("nan"),
            "p99_acceleration_mps2": pooled("acc", "row_acc", lambda x: np.percentile(x, 99)),
            "p99_angular_rate_rad_s": pooled("omega", "row_acc", lambda x: np.percentile(x, 99)),
            "mean_curvature_per_m": pooled("curv", "row_curv", np.mean),
            "median_curvature_per_m": pooled("curv", "row_curv", np.median),
        }

    per_n = {str(n): block(traj.n_waypoints == n) for n in np.unique(traj.n_waypoints)}
    return {"num": len(traj), "dt_s": dt_s, "overall": block(np.ones(len(traj), bool)), "per_n": per_n}


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------
def _traj_from_args(args) -> PiecewisePoly:
    if getattr(args, "file", None):
        return load(args.file)
    spline = SplineSpec(args.kind, args.degree)
    return sample(args.num, ranges_for_split(args.split), np.random.default_rng(args.seed), spline=spline)


STAT_COLUMNS = {  # key -> table heading
    "num": "count",
    "mean_path_length_m": "length m",
    "mean_speed_mps": "speed m/s",
    "max_speed_mps": "max m/s",
    "p99_acceleration_mps2": "p99 acc m/s2",
    "p99_angular_rate_rad_s": "p99 w rad/s",
    "mean_curvature_per_m": "curv 1/m",
    "median_curvature_per_m": "med curv 1/m",
}


def _print_table(stats: dict) -> None:
    print(" ".join(f"{h:>12}" for h in ("N", *STAT_COLUMNS.values())))
    rows = list(stats["per_n"].items()) + [("all", stats["overall"])]
    for name, b in rows:
        print(
            f"{name:>12} "
            + " ".join(f"{b[c]:>12d}" if c == "num" else f"{b[c]:>12.3f}" for c in STAT_COLUMNS)
        )


def _plot(traj: PiecewisePoly, stats: dict, out: str, dt_s: float) -> None:
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
        p.add_argument("--kind", choices=GENERATED_KINDS, default="approximating", help="spline construction")
        p.add_argument("--degree", type=int, default=DEFAULT_DEGREE, help="approximating B-spline degree")

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
    except ValueError as exc:  # a bad file (TrajectoryFileError) or construction
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
