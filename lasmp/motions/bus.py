"""City bus: the floor of a 12 m low-floor bus in stop-and-go traffic, a turn, a speed hump, braking.

Why: a bus floor is the everyday moving floor with the largest horizontal accelerations. A
jerk-limited speed profile (:mod:`lasmp.motions.profiles`) pulls away, cruises over a round-top
speed hump, turns 45 degrees with a jerk-limited lateral acceleration and brakes to a stop
(``stop_and_go``), or brakes hard from cruise (``emergency_brake``, 5 m/s^2: the UNECE R13 minimum
for M3 buses, so a lower bound on what a real emergency stop reaches). Each axle rides the hump
and an ISO 8608 road through a second-order suspension; load transfer adds roll in the turn and
pitch under braking. Bus frame at the CG: x forward, y left, z up; the bus starts at rest heading
along +x and its translation is kept. Derivation, parameter values and sources:
docs/real_motion.md, "Bus".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import cumulative_simpson

from lasmp.motions.motion import (
    DEFAULT_DT_S,
    DEFAULT_DURATION_S,
    MAX_YAW_RAD,
    Motion,
    choice,
    deck_pose,
    finite,
    non_negative,
    point,
    positive,
    time_grid,
)
from lasmp.motions.noise import lti_filter, second_order_tf, sum_of_cosines
from lasmp.motions.profiles import JerkProfile, concatenate, hold, velocity_change

VARIANTS = ("stop_and_go", "emergency_brake")

KMH = 1.0 / 3.6  # m/s per km/h
CRUISE_SPEED_MPS = 30.0 * KMH
ACCEL_MPS2 = 1.5
BRAKE_MPS2 = 1.5
JERK_MPS3 = 2.0
EMERGENCY_DECEL_MPS2 = 5.0  # UNECE R13's legal minimum for M3 service braking: a lower bound
EMERGENCY_JERK_MPS3 = 10.0
A_LAT_MPS2 = 1.5
TURN_ANGLE_RAD = math.pi / 4.0
MAX_TURN_ANGLE_RAD = MAX_YAW_RAD  # the heading must stay within the training trajectories' yaw range
WHEELBASE_M = 5.845
CG_TO_FRONT_AXLE_M = 3.6
CG_HEIGHT_M = 1.1
FLOOR_HEIGHT_M = 0.34
FLOOR_OFFSET_M = (1.0, 0.0, FLOOR_HEIGHT_M - CG_HEIGHT_M)
BODY_FREQ_HZ = 1.0
BODY_DAMPING_RATIO = 0.3
ROLL_GRADIENT_RAD_PER_MPS2 = math.radians(0.7)
PITCH_GRADIENT_RAD_PER_MPS2 = math.radians(0.2)
BUMP_HEIGHT_M = 0.075
BUMP_LENGTH_M = 3.66
BUMP_SHAPES = ("circular", "half_sine")
ROAD_CLASS = "A"
# ISO 8608 class geometric means G_d(n0), m^3, at n0 = 0.1 cycle/m, waviness w = 2
ROAD_CLASSES_GD_M3 = {"A": 16e-6, "B": 64e-6, "C": 256e-6, "D": 1024e-6}
ROAD_N0_CYC_PER_M = 0.1
ROAD_BAND_CYC_PER_M = (0.011, 2.83)
N_ROAD_COMPONENTS = 200
HOLD_S = 0.5  # at rest before pulling away, so the motion starts from rest
EMERGENCY_CRUISE_S = 2.0  # at speed before the emergency stop
BUMP_LEAD_S = 0.1  # cruise before the front axle meets the hump (and after the rear leaves it)
DWELL_S = 3.0  # at a stop between two stop-and-go cycles
SUBSTEPS = 10  # fine grid dt / SUBSTEPS for the position integral and the suspension filters


@dataclass
class _Turn:
    t0_s: float  # start time of the lateral-acceleration ramp
    lateral: JerkProfile  # its acceleration is a_y (left-positive magnitude), its velocity psi * v
    speed_mps: float
    sign: float  # +1 left, -1 right


def bump_profile(x_m, height_m: float, length_m: float, shape: str = "circular") -> np.ndarray:
    """Road elevation (m) of one hump (or a dip, height < 0) starting at x = 0, at distances x_m."""
    x = np.asarray(x_m, dtype=np.float64)
    h, ell = float(height_m), float(length_m)
    inside = (x >= 0.0) & (x <= ell)
    z = np.zeros_like(x)
    if h == 0.0:
        return z
    if shape == "half_sine":
        z[inside] = h * np.sin(np.pi * x[inside] / ell)
    elif shape == "circular":
        r = (ell**2 / 4.0 + h**2) / (2.0 * abs(h))  # radius of the arc through both ends and the crest
        z[inside] = math.copysign(1.0, h) * (np.sqrt(r**2 - (x[inside] - ell / 2.0) ** 2) - (r - abs(h)))
    else:
        choice("bump_profile", "shape", shape, BUMP_SHAPES)
    return z


def road_roughness(road_class: str, seed: int = 0, n_components: int = N_ROAD_COMPONENTS):
    """A function x (m) -> elevation (m) of an ISO 8608 random road of ``road_class``: random-phase
    cosines on ``n_components`` log-spaced bins of the ISO band (docs/real_motion.md, "Bus")."""
    choice("road_roughness", "road_class", road_class, ROAD_CLASSES_GD_M3)
    edges = np.geomspace(*ROAD_BAND_CYC_PER_M, n_components + 1)
    n = np.sqrt(edges[:-1] * edges[1:])
    psd = ROAD_CLASSES_GD_M3[road_class] * (n / ROAD_N0_CYC_PER_M) ** -2.0
    phase = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, n_components)
    amp = np.sqrt(2.0 * psd * np.diff(edges)) * np.exp(1j * phase)

    def elevation(x_m) -> np.ndarray:
        x = np.asarray(x_m, dtype=np.float64)
        return sum_of_cosines(x, 2.0 * np.pi * n, amp).reshape(x.shape)

    return elevation


def _second_order(u: np.ndarray, t_s: np.ndarray, freq_hz: float, zeta: float, with_rate: bool) -> np.ndarray:
    """Response from rest of ``(2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)`` (``with_rate``, a
    base-excited sprung mass) or ``w^2 / (s^2 + 2 zeta w s + w^2)`` (a low-pass body mode) to u(t)."""
    tf = second_order_tf(2.0 * np.pi * freq_hz, zeta, base_excited=with_rate)
    # first-order hold: exact for an input linear between samples, as scipy.signal.lsim
    return lti_filter(*tf, u, float(t_s[1] - t_s[0]), method="foh")


def city_bus(
    variant: str = "stop_and_go",
    *,
    cruise_speed_mps: float = CRUISE_SPEED_MPS,
    accel_mps2: float = ACCEL_MPS2,
    brake_mps2: float = BRAKE_MPS2,
    jerk_mps3: float = JERK_MPS3,
    emergency_decel_mps2: float = EMERGENCY_DECEL_MPS2,
    emergency_jerk_mps3: float = EMERGENCY_JERK_MPS3,
    a_lat_mps2: float = A_LAT_MPS2,
    turn_angle_rad: float = TURN_ANGLE_RAD,
    stops: int = 1,
    bump_height_m: float = BUMP_HEIGHT_M,
    bump_length_m: float = BUMP_LENGTH_M,
    bump_shape: str = "circular",
    road_class: str | None = ROAD_CLASS,
    wheelbase_m: float = WHEELBASE_M,
    cg_to_front_axle_m: float = CG_TO_FRONT_AXLE_M,
    body_freq_hz: float = BODY_FREQ_HZ,
    body_damping_ratio: float = BODY_DAMPING_RATIO,
    roll_gradient_rad_per_mps2: float = ROLL_GRADIENT_RAD_PER_MPS2,
    pitch_gradient_rad_per_mps2: float = PITCH_GRADIENT_RAD_PER_MPS2,
    floor_offset_m=FLOOR_OFFSET_M,
    hold_s: float = HOLD_S,
    cruise_s: float | None = None,
    dwell_s: float = DWELL_S,
    duration_s: float = DEFAULT_DURATION_S,
    dt_s: float = DEFAULT_DT_S,
    seed: int = 0,
) -> Motion:
    """The floor point of a city bus (model, parameters and sources: docs/real_motion.md).

    ``variant``: "stop_and_go" (pull away, cruise over a speed hump, a turn of ``turn_angle_rad``
    (positive left; alternating in direction over ``stops`` cycles), normal braking to a stop) or
    "emergency_brake" (pull away, cruise ``cruise_s``, emergency stop). ``cruise_s`` (None: just
    long enough for both axles to cross the hump, or 2 s before the emergency stop) is the
    straight cruise before the turn / the emergency braking. ``bump_height_m`` < 0 is a pothole,
    0 no hump; ``road_class`` None a smooth road. ``floor_offset_m``: the platform's point in the
    bus frame (forward, left, up) from the CG, m. ``seed`` draws the road roughness. The schedule
    must end at rest within ``duration_s``. Raises ValueError naming the bad parameter.
    """
    where = "city_bus"
    choice(where, "variant", variant, VARIANTS)
    v_c = positive(where, "cruise_speed_mps", cruise_speed_mps)
    acc = positive(where, "accel_mps2", accel_mps2)
    brake = positive(where, "brake_mps2", brake_mps2)
    jerk = positive(where, "jerk_mps3", jerk_mps3)
    em_decel = positive(where, "emergency_decel_mps2", emergency_decel_mps2)
    em_jerk = positive(where, "emergency_jerk_mps3", emergency_jerk_mps3)
    a_lat = positive(where, "a_lat_mps2", a_lat_mps2)
    turn = finite(where, "turn_angle_rad", turn_angle_rad)
    if abs(turn) > MAX_TURN_ANGLE_RAD:
        raise ValueError(
            f"{where}: |turn_angle_rad| must be <= {MAX_TURN_ANGLE_RAD} rad (the training "
            f"trajectories' yaw range), got {turn_angle_rad!r}"
        )
    if isinstance(stops, bool) or not isinstance(stops, int | np.integer) or stops < 1:
        raise ValueError(f"{where}: stops must be an integer >= 1, got {stops!r}")
    bump_h = finite(where, "bump_height_m", bump_height_m)
    bump_l = positive(where, "bump_length_m", bump_length_m)
    choice(where, "bump_shape", bump_shape, BUMP_SHAPES)
    if abs(bump_h) > bump_l / 2.0:
        raise ValueError(f"{where}: |bump_height_m| {bump_h} must not exceed half bump_length_m {bump_l}")
    if road_class is not None:
        choice(where, "road_class (or None)", road_class, ROAD_CLASSES_GD_M3)
    wheelbase = positive(where, "wheelbase_m", wheelbase_m)
    a_front = positive(where, "cg_to_front_axle_m", cg_to_front_axle_m)
    if a_front >= wheelbase:
        raise ValueError(f"{where}: cg_to_front_axle_m {a_front} must be less than wheelbase_m {wheelbase}")
    b_rear = wheelbase - a_front
    f_body = positive(where, "body_freq_hz", body_freq_hz)
    zeta = positive(where, "body_damping_ratio", body_damping_ratio)
    k_roll = non_negative(where, "roll_gradient_rad_per_mps2", roll_gradient_rad_per_mps2)
    k_pitch = non_negative(where, "pitch_gradient_rad_per_mps2", pitch_gradient_rad_per_mps2)
    offset = point(where, "floor_offset_m", floor_offset_m, "forward, left, up")
    t_hold = non_negative(where, "hold_s", hold_s)
    dwell = non_negative(where, "dwell_s", dwell_s)
    duration = positive(where, "duration_s", duration_s)
    dt = positive(where, "dt_s", dt_s)
    if variant == "stop_and_go":
        # long enough for the front axle to reach the hump and the rear axle to leave it at v_c
        default_cruise = (
            2.0 * BUMP_LEAD_S + (wheelbase + bump_l) / v_c if bump_h != 0.0 else 2.0 * BUMP_LEAD_S
        )
    else:
        default_cruise = EMERGENCY_CRUISE_S
    t_cruise = default_cruise if cruise_s is None else non_negative(where, "cruise_s", cruise_s)

    # 1.-2. the schedule: longitudinal phases, turns, and the times the front axle meets a hump
    segments: list[JerkProfile] = [hold(t_hold)]
    turns: list[_Turn] = []
    bump_times: list[float] = []
    events: dict[str, list[float]] = {"pull_away_s": [], "cruise_s": [], "brake_s": [], "stop_s": []}
    t = t_hold
    n_cycles = stops if variant == "stop_and_go" else 1
    for k in range(n_cycles):
        pull = velocity_change(0.0, v_c, acc, jerk)
        events["pull_away_s"].append(t)
        segments.append(pull)
        t += pull.duration_s
        events["cruise_s"].append(t)
        if variant == "stop_and_go" and bump_h != 0.0:
            bump_times.append(t + BUMP_LEAD_S)
        segments.append(hold(t_cruise, v_c))
        t += t_cruise
        if variant == "stop_and_go":
            if turn != 0.0:
                lateral = velocity_change(0.0, abs(turn) * v_c, a_lat, jerk)
                turns.append(_Turn(t, lateral, v_c, math.copysign(1.0, turn) * (-1.0) ** k))
                segments.append(hold(lateral.duration_s, v_c))
                t += lateral.duration_s
            stop = velocity_change(v_c, 0.0, brake, jerk)
        else:
            stop = velocity_change(v_c, 0.0, em_decel, em_jerk)
        events["brake_s"].append(t)
        segments.append(stop)
        t += stop.duration_s
        events["stop_s"].append(t)
        if k < n_cycles - 1:
            segments.append(hold(dwell))
            t += dwell
    if t > duration + 1e-9:
        raise ValueError(
            f"{where}: the {variant} schedule ({n_cycles} cycle(s): hold {t_hold:g} s, pull away, "
            f"cruise {t_cruise:.2f} s, turn, brake) takes {t:.2f} s and does not fit in "
            f"duration_s = {duration:g} s: lengthen duration_s or shorten the schedule "
            "(speeds, accelerations, turn, stops)"
        )
    segments.append(hold(duration - t))
    longitudinal = concatenate(segments)

    t_out = time_grid(duration, dt)
    t_f = time_grid(duration, dt / SUBSTEPS)
    lon = longitudinal.sample(t_f)
    s_m, v_mps, a_x = lon.pos_m, lon.vel_mps, lon.acc_mps2
    psi = np.zeros_like(t_f)
    a_y = np.zeros_like(t_f)
    for tr in turns:
        lat = tr.lateral.sample(np.maximum(t_f - tr.t0_s, 0.0))
        psi += tr.sign * lat.vel_mps / tr.speed_mps
        a_y += tr.sign * np.where(t_f >= tr.t0_s, lat.acc_mps2, 0.0)
    x_m = cumulative_simpson(v_mps * np.cos(psi), x=t_f, initial=0.0)
    y_m = cumulative_simpson(v_mps * np.sin(psi), x=t_f, initial=0.0)

    # 3. road under each axle, relative to where it stands at t = 0 (equilibrium there)
    stations = longitudinal.sample(np.asarray(bump_times)).pos_m + a_front if bump_times else np.zeros(0)
    rough = road_roughness(road_class, seed) if road_class is not None else None

    def road(x: np.ndarray) -> np.ndarray:
        z = np.zeros_like(x)
        for x0 in stations:
            z += bump_profile(x - x0, bump_h, bump_l, bump_shape)
        if rough is not None:
            # tabulate on a 1 cm grid and interpolate: the shortest wavelength (0.35 m) keeps 35 points
            grid = np.arange(x.min() - 0.02, x.max() + 0.02, 0.01)
            z += np.interp(x, grid, rough(grid))
        return z

    z_front_road = road(s_m + a_front)
    z_rear_road = road(s_m - b_rear)
    z_front_road -= z_front_road[0]
    z_rear_road -= z_rear_road[0]

    # 4.-5. body heave, pitch and roll
    z_front = _second_order(z_front_road, t_f, f_body, zeta, with_rate=True)
    z_rear = _second_order(z_rear_road, t_f, f_body, zeta, with_rate=True)
    heave = (b_rear * z_front + a_front * z_rear) / wheelbase
    pitch = np.arcsin(np.clip((z_rear - z_front) / wheelbase, -1.0, 1.0))
    pitch += _second_order(-k_pitch * a_x, t_f, f_body, zeta, with_rate=False)
    roll = _second_order(k_roll * a_y, t_f, f_body, zeta, with_rate=False)

    sub = slice(None, None, SUBSTEPS)
    p_cg = np.stack([x_m[sub], y_m[sub], heave[sub]], axis=1)
    euler = np.stack([roll[sub], pitch[sub], psi[sub]], axis=1)
    euler[0] = 0.0  # exactly level at rest (the filters start from rest; guards against -0.0 noise)
    pose = deck_pose(p_cg, euler, offset)

    # the rear axle meets a hump when the bus has moved one wheelbase further (None: not in the motion)
    s_front_hits = longitudinal.sample(np.asarray(bump_times)).pos_m if bump_times else np.zeros(0)
    moving = np.flatnonzero(np.diff(s_m) > 0)  # s is strictly increasing over these steps
    bump_rear_times = [
        float(np.interp(s0 + wheelbase, s_m[moving + 1], t_f[moving + 1]))
        if s0 + wheelbase <= s_m[-1]
        else None
        for s0 in s_front_hits
    ]
    params = {
        "variant": variant,
        "cruise_speed_mps": v_c,
        "accel_mps2": acc,
        "brake_mps2": brake,
        "jerk_mps3": jerk,
        "emergency_decel_mps2": em_decel,
        "emergency_jerk_mps3": em_jerk,
        "a_lat_mps2": a_lat,
        "turn_angle_rad": turn,
        "stops": int(stops),
        "bump_height_m": bump_h,
        "bump_length_m": bump_l,
        "bump_shape": bump_shape,
        "road_class": road_class,
        "wheelbase_m": wheelbase,
        "cg_to_front_axle_m": a_front,
        "body_freq_hz": f_body,
        "body_damping_ratio": zeta,
        "roll_gradient_rad_per_mps2": k_roll,
        "pitch_gradient_rad_per_mps2": k_pitch,
        "floor_offset_m": offset.tolist(),
        "hold_s": t_hold,
        "cruise_s": t_cruise,
        "dwell_s": dwell,
        "duration_s": duration,
        "dt_s": dt,
        "seed": int(seed),
        "events": {
            **events,
            "turn_start_s": [tr.t0_s for tr in turns],
            "turn_end_s": [tr.t0_s + tr.lateral.duration_s for tr in turns],
            "bump_front_s": bump_times,
            "bump_rear_s": bump_rear_times,
        },
        "model": "jerk-limited speed profile; turn from a jerk-limited lateral acceleration "
        "(psi_dot = a_y / v); circular/half-sine hump + ISO 8608 roughness through per-axle 2nd-order "
        "suspension (heave, pitch); load-transfer roll/pitch gradients through the body mode",
    }
    travel = float(s_m[-1])
    notes = (
        f"Floor point {offset.tolist()} m (fwd, left, up) from the CG of a 12 m city bus, {variant}: "
        f"{v_c * 3.6:.0f} km/h, {travel:.0f} m travelled, "
        f"|heading| up to {float(np.max(np.abs(psi))):.2f} rad; "
        "real scale: translation kept as is (the platform world is unbounded), rotations not scaled."
    )
    return Motion(name=f"bus_{variant}", t_s=t_out, pose=pose, params=params, notes=notes)
