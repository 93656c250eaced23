"""City bus: the floor of a 12 m low-floor bus in stop-and-go traffic, a turn, a speed hump, braking.

Frames and signs
    Bus body frame at the centre of gravity (CG): x forward, y to the left, z up; the pose
    convention of :mod:`lasmp.eval.real_motion.motion` (``R = Rz(yaw) Ry(pitch) Rx(roll)``), so a
    positive pitch puts the nose *down* and a positive roll lifts the left side (the body leans to
    the right). The bus starts at rest at the origin heading along world +x. Its translation is
    kept as it is (a bus travels ~80 m in 20 s; the platform world is unbounded and
    translation-invariant); the yaw is the heading, which stays within +-``turn_angle_rad``.

1. Longitudinal motion (:mod:`lasmp.eval.real_motion.profiles`): piecewise-constant jerk,
   integrated exactly. ``stop_and_go``: hold ``hold_s`` at rest; pull away 0 -> v_c
   (``velocity_change``, peak ``accel_mps2``, jerk ``jerk_mps3``); cruise at v_c over the speed
   hump; a turn at v_c; normal braking v_c -> 0 (peak ``brake_mps2``); dwell ``dwell_s``; repeated
   ``stops`` times (turns alternate left/right so the heading stays bounded); at rest to the end.
   ``emergency_brake``: hold; pull away; cruise ``cruise_s``; emergency braking v_c -> 0 at
   ``emergency_decel_mps2`` with jerk ``emergency_jerk_mps3`` (the brake-pressure build-up); at
   rest to the end. Path distance ``s(t)``, speed ``v(t)``, longitudinal acceleration ``a_x(t)``.

2. Turn: the lateral acceleration ``a_y(t)`` is itself a jerk-limited trapezoid (0 ->
   ``a_lat_mps2`` at ``jerk_mps3``, hold, back to 0), driven at constant speed v_c, and the heading
   rate follows from it, ``psi_dot = a_y / v`` (kinematic, no tyre slip). The heading change is
   the area of ``a_y`` over v, so the trapezoid is exactly the acceleration history of a
   ``velocity_change(0, turn_angle_rad * v_c, a_lat_mps2, jerk_mps3)``: ``psi(t) = u(t) / v_c``
   with u that profile's "velocity". A 45 deg turn at 30 km/h (radius v^2 / a_y = 46 m) has the
   same lateral-acceleration history as a 90 deg corner at 15 km/h. The CG's world position
   ``x = int v cos(psi) dt``, ``y = int v sin(psi) dt`` (cumulative Simpson on a 10x finer grid).

3. Road: elevation as a function of path distance, ``z_road(x) = bump(x) + roughness(x)``.

   * Speed hump (``bump_shape``): ``"circular"`` -- the round-top (Watts) hump, a circular arc of
     chord ``bump_length_m`` and rise ``bump_height_m``: radius ``R = (l^2 / 4 + h^2) / (2 h)``,
     ``z = sqrt(R^2 - (x - l/2)^2) - (R - h)`` for ``0 <= x <= l`` (G. R. Watts (1973), "Road humps
     for the control of vehicle speeds", TRRL Laboratory Report LR 597); or ``"half_sine"``:
     ``z = h sin(pi x / l)``. A negative height makes a pothole/dip of the same shape. Tyre
     enveloping (the contact patch smoothing the profile) is neglected.
   * Random roughness (``road_class``, None for a perfectly smooth road): ISO 8608:2016
     "Mechanical vibration -- Road surface profiles -- Reporting of measured data": displacement
     PSD ``G_d(n) = G_d(n0) (n / n0)^-2``, ``n0 = 0.1`` cycle/m, class geometric means
     ``G_d(n0)`` = 16e-6 (A), 64e-6 (B), 256e-6 (C), 1024e-6 (D) m^3, on the band
     0.011 <= n <= 2.83 cycle/m; a single track (both wheels of an axle see the same profile; no
     roll input) synthesised as ``sum_i sqrt(2 G_d(n_i) dn_i) cos(2 pi n_i x + phi_i)`` with
     ``N_ROAD_COMPONENTS`` log-spaced bins and phases ``phi_i ~ U[0, 2 pi)`` from
     ``np.random.default_rng(seed)``.

   The front axle (``cg_to_front_axle_m`` = a ahead of the CG) rides ``z_road(s + a)``, the rear
   axle (b = wheelbase - a behind) ``z_road(s - b)``: it meets everything the front met when the
   bus has moved one wheelbase L further, i.e. ``L / v`` later at constant speed.

4. Body heave and pitch from the road: each axle a quarter-car-like 1-DoF sprung mass on a
   spring-damper (tyre taken as rigid), ``z_b'' + 2 zeta w_n (z_b' - z_r') + w_n^2 (z_b - z_r) = 0``,
   i.e. ``H(s) = (2 zeta w_n s + w_n^2) / (s^2 + 2 zeta w_n s + w_n^2)`` (``body_freq_hz``,
   ``body_damping_ratio``; discretised exactly for a piecewise-linear input with scipy.signal
   ``cont2discrete(method="foh")`` and run with ``lfilter``). The axles are treated as decoupled
   (a pitch-plane dynamic index ``k_y^2 / (a b)`` of 1, the usual first approximation for buses
   and trucks), so
   ``z_cg = (b z_f + a z_r) / L`` and the road pitch ``theta = arcsin((z_r - z_f) / L)`` (nose up
   when the front rises). Each axle is at equilibrium on its own road height at t = 0.

5. Load-transfer roll and pitch: quasi-static gradients passed through the body mode,
   ``phi = H_lp[k_roll a_y]`` (leaning out of the turn) and ``theta += H_lp[-k_pitch a_x]``
   (nose down under braking, squat under acceleration), ``H_lp(s) = w_n^2 / (s^2 + 2 zeta w_n s +
   w_n^2)`` with the same ``w_n, zeta`` (an assumption: air-suspended buses have their bounce,
   pitch and roll modes close together near 1 Hz). The body rotates about its CG (roll and pitch
   centres not modelled).

6. Floor point: ``floor_offset_m`` (forward, left, up) from the CG, through
   :func:`~lasmp.eval.real_motion.motion.deck_pose` (lever arm of roll, pitch and yaw).

Parameter values (defaults) and sources
    * ``cruise_speed_mps`` = 30 km/h = 8.33 m/s: the lower end of urban speeds (30 km/h zones;
      50 km/h the usual urban limit in Europe; "Stockholm Declaration", Third Global Ministerial
      Conference on Road Safety, 2020, calls for 30 km/h where people walk and vehicles mix).
    * ``accel_mps2`` = ``brake_mps2`` = 1.5 m/s^2 and ``jerk_mps3`` = 2.0 m/s^3: normal service
      acceleration/braking ~1-1.5 m/s^2 and jerk below the comfort limit for standing passengers;
      L. L. Hoberock (1977), "A survey of longitudinal acceleration comfort studies in ground
      transportation vehicles", ASME J. Dynamic Systems, Measurement and Control 99(2), 76-84,
      ~0.11-0.15 g (1.1-1.5 m/s^2) and 0.3 g/s (2.9 m/s^3), the values commonly cited from that
      survey as acceptable for normal operation; the same jerk limits the turn's lateral ramps.
      Also B. de Graaf, W. van Weperen (1997), "The retention of balance: an exploratory study
      into the limits of acceleration the human body can withstand without losing equilibrium",
      Human Factors 39(1), 111-118.
    * ``emergency_decel_mps2`` = 5.0 m/s^2: UNECE Regulation No. 13 (heavy-vehicle braking),
      Annex 4, Type-0 test: service braking of category M3 vehicles (buses > 5 t) must reach a
      mean fully developed deceleration >= 5.0 m/s^2. ``emergency_jerk_mps3`` = 10 m/s^3: the
      deceleration builds in 0.5 s, inside the 0.6 s response time UNECE R13 (Annex 6) allows
      for compressed-air brakes to reach 75 % of the brake-cylinder pressure.
    * ``a_lat_mps2`` = 1.5 m/s^2, ``turn_angle_rad`` = pi/4 at v_c: lateral acceleration in urban
      turns 1-2 m/s^2: below the side-friction factors AASHTO (2018), "A Policy on Geometric
      Design of Highways and Streets" (7th ed.), allows on low-speed urban street curves (up to
      ~0.3, i.e. ~3 m/s^2, at 30 km/h), and at the ~0.15 g comfort value of Hoberock (1977)
      taken across to the lateral direction (assumed).
    * Geometry of a 12 m two-axle low-floor city bus: ``wheelbase_m`` = 5.845 m (Mercedes-Benz
      Citaro O 530 technical data); ``cg_to_front_axle_m`` = 3.6 m (CG at ~62 % of the wheelbase
      behind the front axle: rear-engined, rear axle carrying about 60-65 % of the weight, cf. the
      Citaro's permissible axle loads 7.1 t / 11.5 t; assumed); CG height ``CG_HEIGHT_M`` = 1.1 m
      and floor height ``FLOOR_HEIGHT_M`` = 0.34 m above the road (a Class I low-floor city bus
      in the sense of UNECE Regulation No. 107, ~320-340 mm floor at the doors in manufacturers'
      data; CG height assumed for a laden bus), so the floor is 0.76 m below the CG;
      ``floor_offset_m`` = (1.0, 0, -0.76): the standing area by the middle door, 1 m ahead of the
      CG (assumed).
    * ``body_freq_hz`` = 1.0 Hz, ``body_damping_ratio`` = 0.3: sprung-mass natural frequency ~1 Hz
      and damping ratio 0.2-0.4 of road vehicles (T. D. Gillespie (1992), "Fundamentals of Vehicle
      Dynamics", SAE R-114, ch. 5 "Ride"; J. Y. Wong (2008), "Theory of Ground Vehicles", 4th ed.,
      Wiley, ch. 7); air-suspended buses sit at its low end.
    * ``roll_gradient_rad_per_mps2`` = 0.7 deg per m/s^2 (~7 deg/g): mid of the 0.5-1 deg per
      m/s^2 typical of city buses (the roll gradient of Gillespie (1992), ch. 7; passenger cars
      3-7 deg/g, buses higher with their tall CG and narrow air-spring track); consistent with the
      estimate ``h_r / (K_phi / m - g h_r)`` for a 0.7 m roll-arm, 1.3 m spring track at 1 Hz and
      anti-roll bars doubling the spring roll stiffness (assumed).
    * ``pitch_gradient_rad_per_mps2`` = 0.2 deg per m/s^2: from the same suspension, the pitch
      under load transfer without anti-dive geometry is ``theta / a_x = h_cg / (w_n^2 a b)`` =
      1.1 / ((2 pi 1.0)^2 3.6 x 2.245) = 3.4e-3 rad = 0.20 deg per m/s^2 (Gillespie (1992), ch. 5/7
      load transfer; derived here).
    * ``bump_height_m`` = 0.075 m, ``bump_length_m`` = 3.66 m, circular: the 12 ft, 3-3.5 in round
      speed hump of the Institute of Transportation Engineers (2007), "Guidelines for the Design
      and Application of Speed Humps" (an ITE Recommended Practice), a lowered Watts (1973)
      profile (3.7 m, 100 mm); designed to be crossed at 25-30 km/h.
    * ``road_class`` = "A" (ISO 8608 "very good": new urban asphalt); "B"-"C" for worn streets.
    * ``hold_s`` = 0.5 s at rest first, ``dwell_s`` = 3 s at a stop between cycles, ``stops`` = 1:
      scenario choices. With the defaults the stop-and-go schedule ends at rest at 19.57 s, so it
      fits the suite's 20 s; slower accelerations or a larger turn need a longer ``duration_s``.

Not modelled: tyre slip and steer geometry (offtracking), roll/pitch centres and the body's
rotation about them, the brake release "jerk at stop" (the braking deceleration here ramps down
with the same jerk limit instead of ending abruptly), engine/driveline vibration and gear shifts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import cumulative_simpson

from lasmp.eval.real_motion.motion import (
    DEFAULT_DT_S,
    DEFAULT_DURATION_S,
    Motion,
    deck_pose,
    non_negative,
    positive,
    time_grid,
)
from lasmp.eval.real_motion.noise import lti_filter
from lasmp.eval.real_motion.profiles import JerkProfile, concatenate, hold, velocity_change

VARIANTS = ("stop_and_go", "emergency_brake")

KMH = 1.0 / 3.6  # m/s per km/h
CRUISE_SPEED_MPS = 30.0 * KMH
ACCEL_MPS2 = 1.5
BRAKE_MPS2 = 1.5
JERK_MPS3 = 2.0
EMERGENCY_DECEL_MPS2 = 5.0
EMERGENCY_JERK_MPS3 = 10.0
A_LAT_MPS2 = 1.5
TURN_ANGLE_RAD = math.pi / 4.0
MAX_TURN_ANGLE_RAD = 2.6  # the platform's yaw range: the heading must stay within it
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
        raise ValueError(f"bump_profile: unknown shape {shape!r}; valid: {list(BUMP_SHAPES)}")
    return z


def road_roughness(road_class: str, seed: int = 0, n_components: int = N_ROAD_COMPONENTS):
    """A function x (m) -> elevation (m) of an ISO 8608 random road of ``road_class`` (docstring 3)."""
    if road_class not in ROAD_CLASSES_GD_M3:
        raise ValueError(
            f"road_roughness: unknown road_class {road_class!r}; valid: {sorted(ROAD_CLASSES_GD_M3)}"
        )
    edges = np.geomspace(*ROAD_BAND_CYC_PER_M, n_components + 1)
    n = np.sqrt(edges[:-1] * edges[1:])
    psd = ROAD_CLASSES_GD_M3[road_class] * (n / ROAD_N0_CYC_PER_M) ** -2.0
    amp = np.sqrt(2.0 * psd * np.diff(edges))
    phase = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, n_components)

    def elevation(x_m) -> np.ndarray:
        x = np.asarray(x_m, dtype=np.float64)
        return np.cos(2.0 * np.pi * n * x[..., None] + phase) @ amp

    return elevation


def _second_order(u: np.ndarray, t_s: np.ndarray, freq_hz: float, zeta: float, with_rate: bool) -> np.ndarray:
    """Response from rest of ``(2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)`` (``with_rate``, a
    base-excited sprung mass) or ``w^2 / (s^2 + 2 zeta w s + w^2)`` (a low-pass body mode) to u(t)."""
    w = 2.0 * np.pi * freq_hz
    num = [2.0 * zeta * w, w * w] if with_rate else [w * w]
    # first-order hold: exact for an input linear between samples, as scipy.signal.lsim
    return lti_filter(num, [1.0, 2.0 * zeta * w, w * w], u, float(t_s[1] - t_s[0]), method="foh")


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
    """The floor point of a city bus (model, parameters and sources: module docstring).

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
    if variant not in VARIANTS:
        raise ValueError(f"{where}: unknown variant {variant!r}; valid: {list(VARIANTS)}")
    v_c = positive(where, "cruise_speed_mps", cruise_speed_mps)
    acc = positive(where, "accel_mps2", accel_mps2)
    brake = positive(where, "brake_mps2", brake_mps2)
    jerk = positive(where, "jerk_mps3", jerk_mps3)
    em_decel = positive(where, "emergency_decel_mps2", emergency_decel_mps2)
    em_jerk = positive(where, "emergency_jerk_mps3", emergency_jerk_mps3)
    a_lat = positive(where, "a_lat_mps2", a_lat_mps2)
    try:
        turn = float(turn_angle_rad)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: turn_angle_rad must be a number, got {turn_angle_rad!r}") from None
    if not (math.isfinite(turn) and abs(turn) <= MAX_TURN_ANGLE_RAD):
        raise ValueError(
            f"{where}: turn_angle_rad must be finite with |turn_angle_rad| <= {MAX_TURN_ANGLE_RAD} rad "
            f"(the platform's yaw range), got {turn_angle_rad!r}"
        )
    if isinstance(stops, bool) or not isinstance(stops, int | np.integer) or stops < 1:
        raise ValueError(f"{where}: stops must be an integer >= 1, got {stops!r}")
    try:
        bump_h = float(bump_height_m)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: bump_height_m must be a number, got {bump_height_m!r}") from None
    if not math.isfinite(bump_h):
        raise ValueError(f"{where}: bump_height_m must be finite, got {bump_height_m!r}")
    bump_l = positive(where, "bump_length_m", bump_length_m)
    if bump_shape not in BUMP_SHAPES:
        raise ValueError(f"{where}: unknown bump_shape {bump_shape!r}; valid: {list(BUMP_SHAPES)}")
    if abs(bump_h) > bump_l / 2.0:
        raise ValueError(f"{where}: |bump_height_m| {bump_h} must not exceed half bump_length_m {bump_l}")
    if road_class is not None and road_class not in ROAD_CLASSES_GD_M3:
        raise ValueError(
            f"{where}: unknown road_class {road_class!r}; valid: {sorted(ROAD_CLASSES_GD_M3)} or None"
        )
    wheelbase = positive(where, "wheelbase_m", wheelbase_m)
    a_front = positive(where, "cg_to_front_axle_m", cg_to_front_axle_m)
    if a_front >= wheelbase:
        raise ValueError(f"{where}: cg_to_front_axle_m {a_front} must be less than wheelbase_m {wheelbase}")
    b_rear = wheelbase - a_front
    f_body = positive(where, "body_freq_hz", body_freq_hz)
    zeta = positive(where, "body_damping_ratio", body_damping_ratio)
    k_roll = non_negative(where, "roll_gradient_rad_per_mps2", roll_gradient_rad_per_mps2)
    k_pitch = non_negative(where, "pitch_gradient_rad_per_mps2", pitch_gradient_rad_per_mps2)
    offset = np.asarray(floor_offset_m, dtype=np.float64)
    if offset.shape != (3,) or not np.all(np.isfinite(offset)):
        raise ValueError(
            f"{where}: floor_offset_m must be 3 finite numbers (forward, left, up) m, got {floor_offset_m!r}"
        )
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
