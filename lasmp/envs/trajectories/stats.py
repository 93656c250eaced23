"""Statistics of a trajectory set: path length, speed, acceleration, angular rate, curvature.

:func:`statistics` samples every trajectory on a time grid and reports them overall and per N
(the number of waypoints); :func:`print_table` prints them with the headings of
:data:`STAT_COLUMNS`.
"""

from __future__ import annotations

import numpy as np

from lasmp.envs.trajectories.splines import PiecewisePoly

_CHUNK_SAMPLES = 500_000  # samples of one evaluation pass: ~70 MB of positions, velocities, accelerations
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
    # rows per pass: at most `chunk`, and few enough that one pass evaluates at most _CHUNK_SAMPLES
    # samples (a set of long user-made recordings would otherwise take gigabytes per pass)
    longest = int(np.floor(float(dur.max(initial=0.0)) / dt_s + 1e-9)) + 1
    chunk = max(1, min(chunk, _CHUNK_SAMPLES // longest))
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


def print_table(stats: dict) -> None:
    """Print `statistics` as a table: a row per N, then "all"; the columns of STAT_COLUMNS."""
    print(" ".join(f"{h:>12}" for h in ("N", *STAT_COLUMNS.values())))
    rows = list(stats["per_n"].items()) + [("all", stats["overall"])]
    for name, b in rows:
        print(
            f"{name:>12} "
            + " ".join(f"{b[c]:>12d}" if c == "num" else f"{b[c]:>12.3f}" for c in STAT_COLUMNS)
        )
