"""Lift (elevator): the car floor on a jerk-limited S-curve trip up or down, or a safety-gear stop.

Why: a lift is the vertical moving floor, with the largest sustained vertical accelerations a
robot meets indoors. The car moves vertically only: after a hold at rest it travels 12 m on the
7-phase rest-to-rest S-curve of :func:`lasmp.motions.profiles.s_curve` (1.6 m/s, 1.0 m/s^2,
1.5 m/s^3), up or down. ``emergency_stop`` is an *ascending* car stopped from rated speed by its
ascending-car overspeed protection at 0.6 g_n, inside EN 81-20's limit of at most 1 g_n for that
stop; the retardation builds up over 50 ms. Car sway is not modelled. Parameter values and
sources: docs/real_motion.md, "Lift".
"""

from __future__ import annotations

import numpy as np

from lasmp.motions.motion import (
    DEFAULT_DT_S,
    DEFAULT_DURATION_S,
    Motion,
    choice,
    non_negative,
    positive,
    time_grid,
)
from lasmp.motions.profiles import JerkProfile, concatenate, hold, s_curve, velocity_change

VARIANTS = ("up", "down", "emergency_stop")

G_N_MPS2 = 9.80665  # standard gravity
TRAVEL_M = 12.0
V_MAX_MPS = 1.6
A_MAX_MPS2 = 1.0
J_MAX_MPS3 = 1.5
EMERGENCY_DECEL_MPS2 = 0.6 * G_N_MPS2  # an ascending car's stop: EN 81-20 allows at most 1 g_n
EMERGENCY_ONSET_S = 0.05
TRIP_AFTER_S = 1.0
HOLD_S = 1.0


def lift_profile(
    variant: str,
    travel_m: float,
    v_max_mps: float,
    a_max_mps2: float,
    j_max_mps3: float,
    emergency_decel_mps2: float,
    emergency_onset_s: float,
    trip_after_s: float,
) -> JerkProfile:
    """The car's vertical trip (no leading hold), z positive up (docs/real_motion.md, "Lift")."""
    where = "lift"
    trip = s_curve(travel_m, v_max_mps, a_max_mps2, j_max_mps3)
    if variant == "up":
        return trip
    if variant == "down":
        return s_curve(-travel_m, v_max_mps, a_max_mps2, j_max_mps3)
    # emergency_stop: the normal trip's acceleration, then trip_after_s at rated speed, then the gear
    accel = velocity_change(0.0, v_max_mps, a_max_mps2, j_max_mps3)
    v_peak = trip.peaks().vel_mps
    # the symmetric trip accelerates and decelerates for accel.duration_s each and cruises in between
    cruise_available_s = (
        trip.duration_s - 2.0 * accel.duration_s if v_peak >= v_max_mps * (1 - 1e-12) else 0.0
    )
    if cruise_available_s < trip_after_s:
        raise ValueError(
            f"{where}: emergency_stop needs the car at rated speed {v_max_mps} m/s for trip_after_s = "
            f"{trip_after_s} s, but a {travel_m} m trip cruises only {max(cruise_available_s, 0.0):.2f} s at "
            f"{v_peak:.2f} m/s: lengthen travel_m or shorten trip_after_s"
        )
    stop = velocity_change(v_max_mps, 0.0, emergency_decel_mps2, emergency_decel_mps2 / emergency_onset_s)
    return concatenate([accel, hold(trip_after_s, v_max_mps), stop])


def lift(
    variant: str = "up",
    *,
    travel_m: float = TRAVEL_M,
    v_max_mps: float = V_MAX_MPS,
    a_max_mps2: float = A_MAX_MPS2,
    j_max_mps3: float = J_MAX_MPS3,
    emergency_decel_mps2: float = EMERGENCY_DECEL_MPS2,
    emergency_onset_s: float = EMERGENCY_ONSET_S,
    trip_after_s: float = TRIP_AFTER_S,
    hold_s: float = HOLD_S,
    duration_s: float = DEFAULT_DURATION_S,
    dt_s: float = DEFAULT_DT_S,
    seed: int = 0,
) -> Motion:
    """The floor of a lift car (model, parameters and sources: docs/real_motion.md).

    ``variant``: "up", "down" (a ``travel_m`` trip on the jerk-limited S-curve) or
    "emergency_stop" (travelling up, the ascending car overspeed protection stops the car from
    rated speed at ``emergency_decel_mps2``). The trip starts after ``hold_s`` at rest and must end, at rest,
    within ``duration_s``. The motion has no random content: ``seed`` is accepted for the suite's
    common signature and recorded. Raises ValueError naming the bad parameter or the misfit.
    """
    where = "lift"
    choice(where, "variant", variant, VARIANTS)
    travel = positive(where, "travel_m", travel_m)
    v_max = positive(where, "v_max_mps", v_max_mps)
    a_max = positive(where, "a_max_mps2", a_max_mps2)
    j_max = positive(where, "j_max_mps3", j_max_mps3)
    em_decel = positive(where, "emergency_decel_mps2", emergency_decel_mps2)
    em_onset = positive(where, "emergency_onset_s", emergency_onset_s)
    trip_after = non_negative(where, "trip_after_s", trip_after_s)
    t_hold = non_negative(where, "hold_s", hold_s)
    duration = positive(where, "duration_s", duration_s)
    dt = positive(where, "dt_s", dt_s)

    trip = lift_profile(variant, travel, v_max, a_max, j_max, em_decel, em_onset, trip_after)
    end_s = t_hold + trip.duration_s
    if end_s > duration + 1e-9:
        raise ValueError(
            f"{where}: the {variant} trip of travel_m = {travel:g} m at v_max {v_max:g} m/s, "
            f"a_max {a_max:g} m/s^2, j_max {j_max:g} m/s^3 takes {trip.duration_s:.2f} s "
            f"(+ hold_s {t_hold:g} s = {end_s:.2f} s) and does not fit in duration_s = {duration:g} s: "
            "shorten travel_m or lengthen duration_s"
        )
    profile = concatenate([hold(t_hold), trip, hold(duration - end_s)])
    t = time_grid(duration, dt)
    z = profile.sample(t).pos_m
    pose = np.zeros((len(t), 6))
    pose[:, 2] = z - z[0]
    peaks = trip.peaks()
    params = {
        "variant": variant,
        "travel_m": travel,
        "v_max_mps": v_max,
        "a_max_mps2": a_max,
        "j_max_mps3": j_max,
        "emergency_decel_mps2": em_decel,
        "emergency_onset_s": em_onset,
        "emergency_jerk_mps3": em_decel / em_onset,
        "trip_after_s": trip_after,
        "hold_s": t_hold,
        "duration_s": duration,
        "dt_s": dt,
        "seed": int(seed),
        "trip_start_s": t_hold,
        "trip_end_s": end_s,
        "peak_speed_mps": peaks.vel_mps,
        "peak_acc_mps2": peaks.acc_mps2,
        "peak_jerk_mps3": peaks.jerk_mps3,
        "model": "jerk-limited 7-phase S-curve (exact piecewise-cubic position); emergency stop: "
        "jerk-limited velocity change at the safety-gear retardation; no car sway",
    }
    what = {
        "up": f"up {travel:g} m",
        "down": f"down {travel:g} m",
        "emergency_stop": f"up at {v_max:g} m/s, safety-gear stop at {em_decel:.2f} m/s^2, "
        f"at rest {float(z[-1]):.2f} m up",
    }[variant]
    notes = (
        f"Lift car floor, {what}: trip {t_hold:g}-{end_s:.2f} s, peak speed {peaks.vel_mps:.3f} m/s, "
        f"acceleration {peaks.acc_mps2:.3f} m/s^2, jerk {peaks.jerk_mps3:.3g} m/s^3; real scale "
        "(vertical translation kept as is), no horizontal sway or rotation."
    )
    return Motion(name=f"lift_{variant}", t_s=t, pose=pose, params=params, notes=notes)
