"""User-made trajectories (:func:`from_samples`), and the checks on knots that files share.

A user-made trajectory is a cubic spline through sampled poses with *not-a-knot* ends
(``make_interp_spline``; 2 samples give a line, 3 a parabola). ``poses[:, 0]`` must be the
initial pose (zeros). :func:`check_knots` validates NaN-padded knots, here and when a file is
read (:mod:`lasmp.envs.trajectories.fileformat`); a problem raises :class:`TrajectoryFileError`.
"""

from __future__ import annotations

import numpy as np

from lasmp.envs.trajectories.splines import SAMPLES, PiecewisePoly

_START_TOL = 1e-6  # |pose| at t = 0 must be below this (the platform's initial pose)


class TrajectoryFileError(ValueError):
    """A trajectory file or a user-made trajectory is malformed; the message names the problem."""


def check_knots(t: np.ndarray, p: np.ndarray, where: str) -> np.ndarray:
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
    # the times first: zeroed or shuffled times would otherwise show as NaN poses (the padding)
    if np.any(t[:, 0] != 0.0):
        raise TrajectoryFileError(
            f"{where}: times must start at 0 s (got first time {t[:, 0][t[:, 0] != 0][0]!r})"
        )
    dt = np.diff(t, axis=1)
    if np.any(dt[valid[:, 1:]] <= 0.0):
        raise TrajectoryFileError(f"{where}: times must be strictly increasing")
    pv = p[valid]
    if np.isnan(pv).any():
        raise TrajectoryFileError(f"{where}: NaN in the poses")
    if not np.all(np.isfinite(pv)):
        raise TrajectoryFileError(f"{where}: poses must be finite")
    if not np.all(np.isnan(p[~valid])):
        raise TrajectoryFileError(f"{where}: poses present where the times are padding (NaN)")
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
    nk = check_knots(t, p, where)
    return PiecewisePoly.from_knots(t, p, nk, SAMPLES, 3, np.full(p.shape[0], -1))
