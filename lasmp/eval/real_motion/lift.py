"""Lift (elevator): the car floor on a jerk-limited S-curve trip up or down, or a safety-gear stop.

Model
    The car floor moves vertically only (world z up): ``pose = [0, 0, z(t), 0, 0, 0]``. After a
    hold of ``hold_s`` at rest the car travels ``travel_m`` on the classic rest-to-rest 7-phase
    S-curve of :func:`lasmp.eval.real_motion.profiles.s_curve` (piecewise-constant jerk
    ``+-j_max``, acceleration up to ``a_max``, speed up to ``v_max``; fewer phases when the trip is
    too short to reach them), then stays at rest until ``duration_s``:

    * ``"up"``: ``z`` rises by ``travel_m``; ``"down"``: it falls by ``travel_m``.
    * ``"emergency_stop"``: the car sets off up on the same trip; ``trip_after_s`` after reaching
      rated speed ``v_max`` the safety gear (in the up direction: the ascending car overspeed
      protection means) trips and stops the car at the constant retardation
      ``emergency_decel_mps2``. The retardation of a gripping safety gear is not set by a
      controller but by the mechanics: it rises while the wedges or rollers bite and the gear's
      springs deflect. We model that rise as a jerk-limited ramp of ``emergency_onset_s`` (the
      jerk is ``emergency_decel_mps2 / emergency_onset_s``, 118 m/s^3 by default) and let the
      retardation fall again over the same time as the car comes to rest, i.e.
      ``velocity_change(v_max, 0, emergency_decel, emergency_decel / emergency_onset_s)``, so the
      car ends at rest with zero acceleration. Real stops end more abruptly (and ring with rope
      and car-frame elasticity); both are neglected.

    Horizontal car sway from the guide rails (ISO 18738-1 measures it, typically well below the
    vertical ride accelerations) is left zero: the motion is pure vertical translation.

Parameter values (defaults) and sources
    * ``v_max_mps`` = 1.6 m/s: a rated speed of the preferred series 0.63, 1.0, 1.6, 2.5 m/s for
      passenger lifts in ISO 4190-1:2010, "Lift (Elevator) installation -- Part 1: Class I, II, III
      and VI lifts"; typical passenger lifts run at 1.0-2.5 m/s.
    * ``a_max_mps2`` = 1.0 m/s^2, ``j_max_mps3`` = 1.5 m/s^3: typical ride-quality settings of
      passenger lifts, 0.8-1.2 m/s^2 and 1.0-2.0 m/s^3 (G. C. Barney, L. Al-Sharif (2016),
      "Elevator Traffic Handbook: Theory and Practice", 2nd ed., Routledge; CIBSE Guide D:2015,
      "Transportation systems in buildings"); the quantities (peak jerk, peak acceleration,
      maximum speed of a trip) are those defined for measuring ride quality in ISO 18738-1:2012,
      "Measurement of ride quality -- Part 1: Lifts (elevators)". The S-curve formulas: R. D.
      Peters (1995), "Ideal lift kinematics", Elevator Technology 6, IAEE.
    * ``emergency_decel_mps2`` = 0.6 g_n = 5.88 m/s^2: EN 81-20:2020, "Safety rules for the
      construction and installation of lifts -- Part 20: Passenger and goods passenger lifts",
      requires the average retardation of a progressive safety gear (free fall, rated load) to lie
      between 0.2 g_n and 1.0 g_n (as did EN 81-1:1998+A3:2009, 9.8.4), and the ascending car
      overspeed protection not to retard the empty car by more than 1 g_n; 0.6 g_n is the middle
      of that band. g_n = 9.80665 m/s^2 (standard gravity).
    * ``emergency_onset_s`` = 0.05 s: our choice (no standard prescribes it): a stiff gear builds
      its braking force within tens of milliseconds of the wedges touching the rail; 50 ms keeps
      the peak deceleration resolved on the 100 Hz grid (5 samples).
    * ``trip_after_s`` = 1.0 s at rated speed before the gear trips (scenario choice; real gears
      trip at >= 115 % of rated speed on overspeed, here the trip is taken at rated speed).
    * ``travel_m`` = 12 m: four storeys of 3 m (scenario choice), ``hold_s`` = 1 s at rest first.
"""

from __future__ import annotations

import numpy as np

from lasmp.eval.real_motion.motion import (
    DEFAULT_DT_S,
    DEFAULT_DURATION_S,
    Motion,
    non_negative,
    positive,
    time_grid,
)
from lasmp.eval.real_motion.profiles import JerkProfile, concatenate, hold, s_curve, velocity_change

VARIANTS = ("up", "down", "emergency_stop")

G_N_MPS2 = 9.80665  # standard gravity
TRAVEL_M = 12.0
V_MAX_MPS = 1.6
A_MAX_MPS2 = 1.0
J_MAX_MPS3 = 1.5
EMERGENCY_DECEL_MPS2 = 0.6 * G_N_MPS2
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
    """The car's vertical trip (no leading hold), z positive up (module docstring)."""
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
    """The floor of a lift car (model, parameters and sources: module docstring).

    ``variant``: "up", "down" (a ``travel_m`` trip on the jerk-limited S-curve) or
    "emergency_stop" (travelling up, the safety gear stops the car from rated speed at
    ``emergency_decel_mps2``). The trip starts after ``hold_s`` at rest and must end, at rest,
    within ``duration_s``. The motion has no random content: ``seed`` is accepted for the suite's
    common signature and recorded. Raises ValueError naming the bad parameter or the misfit.
    """
    where = "lift"
    if variant not in VARIANTS:
        raise ValueError(f"{where}: unknown variant {variant!r}; valid: {list(VARIANTS)}")
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
