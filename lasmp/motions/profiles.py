"""Jerk-limited speed profiles: piecewise-constant jerk, integrated exactly phase by phase.

Shared by the city bus (:mod:`lasmp.motions.bus`) and the lift (:mod:`lasmp.motions.lift`). A
:class:`JerkProfile` is a list of phases of constant jerk from an initial state; within a phase
acceleration, velocity and position are exact polynomials, so a profile's peak jerk, acceleration
and speed are exactly the parameters that made it. Primitives, all from and to zero acceleration:
:func:`hold` (rest or cruise), :func:`velocity_change` (trapezoidal or triangular acceleration),
:func:`s_curve` (the 7-phase rest-to-rest trip of lift kinematics), :func:`concatenate`. Their
phase formulas and sources: docs/real_motion.md, "Jerk-limited profiles".
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from lasmp.motions.motion import finite, positive


class Kinematics(NamedTuple):
    """A sampled history: times (K,), s, and jerk, acceleration, velocity, position (K,) each."""

    t_s: np.ndarray
    jerk_mps3: np.ndarray
    acc_mps2: np.ndarray
    vel_mps: np.ndarray
    pos_m: np.ndarray


class Peaks(NamedTuple):
    """The largest |jerk|, |acceleration| and |velocity| of a profile (exact, from its phases)."""

    jerk_mps3: float
    acc_mps2: float
    vel_mps: float


@dataclass(frozen=True, eq=False)
class JerkProfile:
    """Piecewise-constant jerk: phase i lasts ``durations_s[i]`` with jerk ``jerks_mps3[i]``.

    Starts at t = 0 from position ``p0_m``, velocity ``v0_mps`` and acceleration ``a0_mps2``.
    """

    durations_s: np.ndarray
    jerks_mps3: np.ndarray
    p0_m: float = 0.0
    v0_mps: float = 0.0
    a0_mps2: float = 0.0

    def __post_init__(self):
        d = np.asarray(self.durations_s, dtype=np.float64).reshape(-1)
        j = np.asarray(self.jerks_mps3, dtype=np.float64).reshape(-1)
        if d.shape != j.shape:
            raise ValueError(f"JerkProfile: {len(d)} durations but {len(j)} jerks")
        if not (np.all(np.isfinite(d)) and np.all(np.isfinite(j))):
            raise ValueError("JerkProfile: durations and jerks must be finite")
        if np.any(d < 0):
            raise ValueError(f"JerkProfile: phase durations must be >= 0, got {d.tolist()}")
        for name in ("p0_m", "v0_mps", "a0_mps2"):
            object.__setattr__(self, name, finite("JerkProfile", name, getattr(self, name)))
        object.__setattr__(self, "durations_s", d)
        object.__setattr__(self, "jerks_mps3", j)

    @property
    def duration_s(self) -> float:
        return float(np.sum(self.durations_s))

    def knots(self) -> Kinematics:
        """The exact state at the phase boundaries (n + 1 knots); ``jerk_mps3[i]`` is phase i's jerk
        (the last entry, after the end, is 0)."""
        n = len(self.durations_s)
        t = np.zeros(n + 1)
        a = np.empty(n + 1)
        v = np.empty(n + 1)
        p = np.empty(n + 1)
        a[0], v[0], p[0] = self.a0_mps2, self.v0_mps, self.p0_m
        for i, (dt, j) in enumerate(zip(self.durations_s, self.jerks_mps3, strict=True)):
            t[i + 1] = t[i] + dt
            a[i + 1] = a[i] + j * dt
            v[i + 1] = v[i] + a[i] * dt + j * dt**2 / 2.0
            p[i + 1] = p[i] + v[i] * dt + a[i] * dt**2 / 2.0 + j * dt**3 / 6.0
        return Kinematics(t, np.append(self.jerks_mps3, 0.0), a, v, p)

    @property
    def end_state(self) -> tuple[float, float, float]:
        """(position m, velocity m/s, acceleration m/s^2) at the end of the last phase."""
        k = self.knots()
        return float(k.pos_m[-1]), float(k.vel_mps[-1]), float(k.acc_mps2[-1])

    def sample(self, t_s) -> Kinematics:
        """Jerk, acceleration, velocity, position at times ``t_s`` (exact piecewise polynomials).

        Outside ``[0, duration_s]`` the motion continues with zero jerk from the nearest end.
        """
        t = np.asarray(t_s, dtype=np.float64).reshape(-1)
        k = self.knots()
        # phase index per time: knots t_0 = 0 <= ... <= t_n; zero-length phases are never selected
        idx = np.searchsorted(k.t_s, t, side="right") - 1
        before = idx < 0
        idx = np.clip(idx, 0, len(k.t_s) - 1)
        tau = t - k.t_s[idx]
        j = k.jerk_mps3[idx].copy()
        j[before] = 0.0  # zero jerk before the start, extrapolating the initial state backwards
        a0, v0, p0 = k.acc_mps2[idx], k.vel_mps[idx], k.pos_m[idx]
        acc = a0 + j * tau
        vel = v0 + a0 * tau + j * tau**2 / 2.0
        pos = p0 + v0 * tau + a0 * tau**2 / 2.0 + j * tau**3 / 6.0
        return Kinematics(t, j, acc, vel, pos)

    def peaks(self) -> Peaks:
        """Exact peak |jerk|, |acceleration| and |velocity| over the profile's phases.

        |a| is piecewise linear, so its peak is at a knot; |v| peaks at a knot or inside a phase
        where the acceleration crosses zero (``tau* = -a_i / j_i``).
        """
        k = self.knots()
        active = self.durations_s > 0
        jerk = float(np.max(np.abs(self.jerks_mps3[active]), initial=0.0))
        acc = float(np.max(np.abs(k.acc_mps2)))
        vel = float(np.max(np.abs(k.vel_mps)))
        for i in np.flatnonzero(active & (self.jerks_mps3 != 0)):
            tau = -k.acc_mps2[i] / self.jerks_mps3[i]
            if 0.0 < tau < self.durations_s[i]:
                v_ext = k.vel_mps[i] + k.acc_mps2[i] * tau + self.jerks_mps3[i] * tau**2 / 2.0
                vel = max(vel, abs(float(v_ext)))
        return Peaks(jerk, acc, vel)


def hold(duration_s: float, v_mps: float = 0.0) -> JerkProfile:
    """Zero jerk and acceleration for ``duration_s``: a hold at rest (v = 0) or a cruise at ``v_mps``."""
    where = "hold"
    d = finite(where, "duration_s", duration_s)
    if d < 0:
        raise ValueError(f"{where}: duration_s must be >= 0, got {duration_s!r}")
    return JerkProfile(np.array([d]), np.array([0.0]), v0_mps=finite(where, "v_mps", v_mps))


def velocity_change_phases(dv_mps: float, a_max_mps2: float, j_max_mps3: float) -> tuple[float, float, float]:
    """(T_j, T_a, peak acceleration) of a jerk-limited change of speed by ``|dv_mps|``."""
    dv = abs(float(dv_mps))
    if dv * j_max_mps3 >= a_max_mps2**2:  # long enough to reach a_max: trapezoidal acceleration
        t_j = a_max_mps2 / j_max_mps3
        return t_j, dv / a_max_mps2 - t_j, a_max_mps2
    t_j = math.sqrt(dv / j_max_mps3)  # triangular: the jerk ramps end before a_max is reached
    return t_j, 0.0, j_max_mps3 * t_j


def velocity_change(v0_mps: float, v1_mps: float, a_max_mps2: float, j_max_mps3: float) -> JerkProfile:
    """Jerk-limited change of velocity v0 -> v1 from and to zero acceleration (docs/real_motion.md).

    Trapezoidal acceleration peaking at ``a_max_mps2``, or triangular (peak ``sqrt(|dv| j_max)``) when
    the change is too small to reach it. ``v0 == v1`` gives an empty (zero-length) profile.
    """
    where = "velocity_change"
    v0 = finite(where, "v0_mps", v0_mps)
    v1 = finite(where, "v1_mps", v1_mps)
    a_max = positive(where, "a_max_mps2", a_max_mps2)
    j_max = positive(where, "j_max_mps3", j_max_mps3)
    if v1 == v0:
        return JerkProfile(np.zeros(0), np.zeros(0), v0_mps=v0)
    t_j, t_a, _ = velocity_change_phases(v1 - v0, a_max, j_max)
    s = math.copysign(1.0, v1 - v0)
    return JerkProfile(np.array([t_j, t_a, t_j]), s * j_max * np.array([1.0, 0.0, -1.0]), v0_mps=v0)


def _accel_time_s(v_mps: float, a_max_mps2: float, j_max_mps3: float) -> float:
    """Duration of a jerk-limited 0 -> v (or v -> 0) change."""
    t_j, t_a, _ = velocity_change_phases(v_mps, a_max_mps2, j_max_mps3)
    return 2.0 * t_j + t_a


def s_curve_peak_speed(distance_m: float, v_max_mps: float, a_max_mps2: float, j_max_mps3: float) -> float:
    """The peak speed of the rest-to-rest S-curve over ``|distance_m|``: ``v_max``, or less on a short trip."""
    d = abs(float(distance_m))
    if v_max_mps * _accel_time_s(v_max_mps, a_max_mps2, j_max_mps3) <= d:
        return v_max_mps
    v_tri = (d**2 * j_max_mps3 / 4.0) ** (1.0 / 3.0)  # D(v) = 2 v^1.5 / sqrt(j) = d
    if v_tri * j_max_mps3 <= a_max_mps2**2:
        return v_tri
    r = a_max_mps2**2 / j_max_mps3  # D(v) = v^2 / a + v a / j = d, a quadratic in v
    return (-r + math.sqrt(r * r + 4.0 * d * a_max_mps2)) / 2.0


def s_curve(distance_m: float, v_max_mps: float, a_max_mps2: float, j_max_mps3: float) -> JerkProfile:
    """Rest-to-rest jerk-limited point-to-point profile covering ``distance_m`` (either sign).

    Up to 7 phases (+j, 0, -j, cruise, -j, 0, +j); v_max and/or a_max are not reached when the
    distance is too short (docs/real_motion.md). Its end position equals ``distance_m`` exactly up to
    rounding.
    """
    where = "s_curve"
    d = finite(where, "distance_m", distance_m)
    v_max = positive(where, "v_max_mps", v_max_mps)
    a_max = positive(where, "a_max_mps2", a_max_mps2)
    j_max = positive(where, "j_max_mps3", j_max_mps3)
    if d == 0.0:
        return JerkProfile(np.zeros(0), np.zeros(0))
    v_peak = s_curve_peak_speed(d, v_max, a_max, j_max)
    # whatever the distance the accelerating and braking halves cover v_peak * t_acc between them
    t_cruise = max(0.0, (abs(d) - v_peak * _accel_time_s(v_peak, a_max, j_max)) / v_peak)
    s = math.copysign(1.0, d)
    return concatenate(
        [
            velocity_change(0.0, s * v_peak, a_max, j_max),
            hold(t_cruise, s * v_peak),
            velocity_change(s * v_peak, 0.0, a_max, j_max),
        ]
    )


def concatenate(profiles: list[JerkProfile], p0_m: float | None = None, tol: float = 1e-9) -> JerkProfile:
    """The profiles played one after the other, as one profile (hold, accelerate, cruise, brake, ...).

    Each profile after the first must start at the velocity and acceleration the previous one ends
    with (within ``tol``, absolute); their own start positions are ignored (position is continuous).
    ``p0_m`` overrides the first profile's start position.
    """
    if not profiles:
        raise ValueError("concatenate: no profiles")
    first = profiles[0]
    _, v_end, a_end = first.end_state
    for i, prof in enumerate(profiles[1:], start=1):
        if abs(prof.v0_mps - v_end) > tol or abs(prof.a0_mps2 - a_end) > tol:
            raise ValueError(
                f"concatenate: profile {i} starts at v = {prof.v0_mps} m/s, a = {prof.a0_mps2} m/s^2 but "
                f"profile {i - 1} ends at v = {v_end} m/s, a = {a_end} m/s^2"
            )
        _, v_end, a_end = JerkProfile(prof.durations_s, prof.jerks_mps3, 0.0, v_end, a_end).end_state
    return JerkProfile(
        np.concatenate([p.durations_s for p in profiles]),
        np.concatenate([p.jerks_mps3 for p in profiles]),
        first.p0_m if p0_m is None else p0_m,
        first.v0_mps,
        first.a0_mps2,
    )
