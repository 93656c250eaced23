"""The spline constructions (``scipy.interpolate``) and the representation every set is evaluated from.

Generated sets (:func:`lasmp.envs.trajectories.generate.sample`) use one of two constructions,
chosen by :class:`SplineSpec`:

* ``"approximating"`` (default, docs/trajectories.md): the waypoints are the *control points* of a clamped
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
  0.69 m/s; degrees 5 / 7 / 9 / 11 give 10.41 / 8.53 / 7.34 / 6.53 m (docs/trajectories.md, "Why degree 10").
* ``"interpolating"`` (the harder, non-default reading): a cubic spline *through* the initial
  pose at t = 0 and the waypoints at ``t_k = k T / N`` (``scipy.interpolate.make_interp_spline``)
  with clamped ends (zero velocity at 0 and T). C2 inside; mean path length 23.7 m.

User-made sets (:func:`lasmp.envs.trajectories.user_made.from_samples`, kind ``"samples"``) are a
cubic spline through the sampled poses with *not-a-knot* ends (``make_interp_spline``; 2 samples
give a line, 3 a parabola).

Representation (:class:`PiecewisePoly`)
    Every set, whatever its construction, is evaluated from a per-row piecewise polynomial in
    power basis: breakpoints ``breaks_s`` and, per segment, coefficients in local time
    ``tau = t - break`` (ascending order, up to the highest degree in the set, zero padded), so
    thousands of rows with different knots evaluate in one vectorized Horner pass. Before 0
    the time clamps to 0; past the end the last pose holds with zero velocity and acceleration.
    Rows are built per group of identical knot times and construction, so a row's polynomial
    does not depend on which other rows are built with it: a set rebuilt from its knots (file
    load, subsets) evaluates bit-identically.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline

POSE_NAMES = ("x", "y", "z", "roll", "pitch", "yaw")  # the pose layout (package docstring)
# per-row construction codes (PiecewisePoly.kind)
APPROXIMATING, INTERPOLATING, SAMPLES = 0, 1, 2
KIND_NAMES = ("approximating", "interpolating", "samples")
GENERATED_KINDS = ("approximating", "interpolating")
END_REPEATS = 3  # copies of the first / last control point: zero velocity and acceleration at the ends
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
# the fields padded by design, with their padding: a row's slots after its last knot (axis 1) are
# NaN, after its last break +inf (a checkpoint's check tells this padding from a corrupt value)
PADDING = {"knot_times_s": np.nan, "knot_poses": np.nan, "breaks_s": np.inf}
_ROW_FIELDS = (
    "knot_times_s",
    "knot_poses",
    "n_knots",
    "kind",
    "degree",
    "n_waypoints",
    "breaks_s",
    "n_segments",
    "coeffs",
)


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
        return PiecewisePoly(
            t,
            p,
            self.n_knots.copy(),
            self.kind.copy(),
            self.degree.copy(),
            self.n_waypoints.copy(),
            b,
            self.n_segments.copy(),
            c,
            dict(self.meta),
        )

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
