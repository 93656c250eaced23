"""Train: the floor of a passenger coach entering a canted curve, and riding on irregular track.

Frames and signs
    Car-body frame on the track centreline at rail level: x forward, y to the left, z up, the pose
    convention of :mod:`lasmp.eval.real_motion.motion` (``R = Rz(yaw) Ry(pitch) Rx(roll)``): a
    positive yaw turns left, a positive roll lifts the left side. The curve turns left, so its
    cant (outer = right rail raised) rolls the body to a *negative* roll.

Why a moving frame. A train cannot start from rest at speed, and the platform must start at rest.
The motion is therefore expressed in the inertial frame that moves at the constant train speed v
along the initial straight (Galilean invariance: a constant velocity is physically invisible to
the robot, which feels only accelerations and rotations). In that frame the straight is at rest,
the curve appears as the deviation ``(X(s) - v t, Y(s))`` of the track from the initial straight
line (s = v t), and the track vibration is faded in over ``RAMP_S`` = 2 s. So ``pose[0] == 0``, the
velocity at t = 0 is zero, and no speed ramp (a fictitious acceleration the train never makes) is
needed. The alternative, accelerating the platform from 0 to v at the start, would put a large
longitudinal acceleration into the scenario that is not part of a train ride.

1. Alignment (EN 13803, "Railway applications - Track - Track alignment design parameters - Track
   gauges 1435 mm and wider", 2017, formerly EN 13803-1:2010): a straight of ``straight_m``, a
   clothoid transition of length L whose curvature grows linearly with distance,
   ``kappa(u) = u / (L R)`` for 0 <= u <= L, then a circular arc of radius R. Heading
   ``psi(u) = u^2 / (2 L R)`` on the transition; its position is the Fresnel integrals
   ``X = A C(u / A), Y = A S(u / A)`` with ``A = sqrt(pi L R)`` (``scipy.special.fresnel``). The cant
   D ramps linearly along the transition with the curvature (straight-ramp cant transition) and
   is constant on the arc. Cant rolls the car body by ``theta = asin(D / e)``, with e = 1.5 m the
   distance between the rail-head centres of 1435 mm gauge track over which EN 13803 measures
   cant (asin because e is measured along the tilted sleeper; for D <= 180 mm it differs from
   atan(D / e) by < 0.1 %). The lateral acceleration felt on the floor (the specific force along
   the body y axis) is ``a_q = (v^2 / R) cos(theta) - g sin(theta)``, which is EN 13803's
   uncompensated lateral acceleration ``v^2 / R - g D / e`` to first order in theta (EN 13803:
   cant deficiency ``I = 11.8 V^2 / R - D`` in mm with V in km/h, 11.8 = e / (3.6^2 g)). Body
   roll on the suspension (the flexibility coefficient) is neglected: roll = -theta exactly.
   EN 13803 limits (ballasted track, 1435 mm gauge; recommended / maximum): cant 160 / 180 mm;
   cant deficiency about 100-150 mm depending on speed and traffic; rate of change of cant and
   of cant deficiency in transitions about 50-70 mm/s (the transition length follows from
   these: ``L >= v D / (dD/dt)_lim``). The defaults (160 km/h, R = 1500 m, D = 100 mm, L = 120 m)
   give I = 101 mm and dD/dt = dI/dt = 37 mm/s, inside the recommended values; ``params`` records
   them. Lateral acceleration is continuous (the point of a clothoid); its rate and the roll
   rate step at the ends of the transition, as the geometry of a straight-ramp clothoid does
   (the suspension rounds them in reality; not modelled).

2. Track irregularities: the FRA spectra of Hamid and Yang (1981), "Analytical descriptions of
   track geometry variations", Transportation Research Record 838 (FRA report
   DOT/FRA/ORD-83/03, Hamid, Rasmussen, Baluja and Yang 1983), in the form widely tabulated
   (e.g. Garg and Dukkipati (1984), "Dynamics of Railway Vehicle Systems", Academic Press;
   Zhai (2020), "Vehicle-Track Coupled Dynamics", Springer), one-sided, in cm^2 / (rad/m),
   Omega the spatial frequency (rad/m)::

       vertical profile  S_v(Omega) = k A_v Omega_c^2 / (Omega^2 (Omega^2 + Omega_c^2))
       alignment         S_a(Omega) = k A_a Omega_c^2 / (Omega^2 (Omega^2 + Omega_c^2))
       cross-level       S_c(Omega) = 4 k A_v Omega_c^2 / ((Omega^2 + Omega_c^2)(Omega^2 + Omega_s^2))

   with k = 0.25, Omega_c = 0.8245 rad/m, Omega_s = 0.4380 rad/m and, per FRA track class
   (A_v, A_a in cm^2 rad/m): class 4 (0.5376, 0.3027), class 5 (0.2095, 0.0762), class 6
   (0.0339, 0.0339). The fits apply to wavelengths of 1.5-300 m (:data:`WAVELENGTH_BAND_M`).
   At speed v a spatial frequency Omega is met at f = v Omega / (2 pi) Hz, so the temporal PSD
   per Hz is ``S(f) = S(Omega) 2 pi / v`` (x 1e-4 for m^2). The band is cut at
   ``f <= 0.2 / dt`` (20 Hz at 100 Hz samples: what the cubic spline through the samples keeps).
   Each channel is synthesised by the random-phase method
   (:func:`lasmp.eval.real_motion.noise.random_phase_noise`); cross-level (height difference of
   the rails) becomes a track roll angle ``c / e``. FRA's maximum passenger speeds (49 CFR 213.9):
   class 4 80 mph (35.8 m/s), class 5 90 mph (40.2 m/s), class 6 110 mph (49.2 m/s).

3. Car body: each channel passes through a base-excited second-order suspension (body on a
   spring and damper over the track input), ``H(s) = (2 zeta w_n s + w_n^2) / (s^2 + 2 zeta w_n s +
   w_n^2)``: long wavelengths are followed, the body mode (gain ~ 1 / (2 zeta) at resonance) is
   excited, short wavelengths are filtered. Body modes of passenger coaches lie near 1 Hz:
   vertical bounce ~1 Hz, lateral sway and roll ~0.5-1 Hz, damping ratios ~0.1-0.3 (Iwnicki
   (ed.) (2006), "Handbook of Railway Vehicle Dynamics", CRC Press; Garg and Dukkipati 1984);
   used here: vertical 1.0 Hz, lateral 0.8 Hz, roll 0.8 Hz, zeta = 0.2 each
   (:data:`SUSPENSION_MODES`). Neglected: the wheelbase / bogie-spacing filtering of the input,
   body bending modes, pitch.

4. Floor point: ``FLOOR_HEIGHT_M`` = 1.2 m above the rail plane (a typical single-deck coach
   floor; design choice), moved rigidly with the body by
   :func:`lasmp.eval.real_motion.motion.deck_pose`, so roll adds lateral sway at the floor.

Variants: "curve" (160 km/h on class 6 track: 200 m straight, 120 m transition, then the 1500 m
arc until the end; the heading turns ~0.4 rad in 20 s) and "straight" (vibration only, at
110 mph = 49.2 m/s, the class 6 limit).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import fresnel

from lasmp.eval.real_motion.motion import DEFAULT_DT_S, DEFAULT_DURATION_S, Motion, deck_pose, time_grid
from lasmp.eval.real_motion.noise import lti_filter, random_phase_noise, smooth_ramp

GRAVITY_M_S2 = 9.81
RAIL_CENTRES_M = 1.5  # EN 13803: cant is measured over the 1500 mm rail-head centres of 1435 mm gauge
FLOOR_HEIGHT_M = 1.2  # coach floor above the rail plane (design choice, typical single-deck coach)
RAMP_S = 2.0  # quintic fade-in of the track vibration, s
MAX_YAW_RAD = 2.6  # the platform world's yaw range

# FRA track spectra (Hamid and Yang 1981): class -> (A_v, A_a), cm^2 rad/m; common constants
FRA_ROUGHNESS_CM2_RAD_PER_M: dict[int, tuple[float, float]] = {
    4: (0.5376, 0.3027),
    5: (0.2095, 0.0762),
    6: (0.0339, 0.0339),
}
FRA_K = 0.25
FRA_OMEGA_C_RAD_PER_M = 0.8245
FRA_OMEGA_S_RAD_PER_M = 0.4380
WAVELENGTH_BAND_M = (1.5, 300.0)  # the FRA fits' wavelength range
MAX_FREQUENCY_TIMES_DT = 0.2  # the synthesis band ends at 0.2 / dt (20 Hz at 100 Hz samples)
TRACK_CHANNELS = ("vertical", "lateral", "roll")

# channel -> (natural frequency Hz, damping ratio) of the car body on its suspension (item 3)
SUSPENSION_MODES: dict[str, tuple[float, float]] = {
    "vertical": (1.0, 0.2),
    "lateral": (0.8, 0.2),
    "roll": (0.8, 0.2),
}

VARIANTS = ("curve", "straight")
# variant -> default speed: 160 km/h in the curve; 110 mph (FRA class 6 limit) on the straight
DEFAULT_SPEED_MPS = {"curve": 160.0 / 3.6, "straight": 110.0 * 0.44704}
DEFAULT_RADIUS_M = 1500.0
DEFAULT_CANT_MM = 100.0
DEFAULT_TRANSITION_M = 120.0
DEFAULT_STRAIGHT_M = 200.0
DEFAULT_TRACK_CLASS = 6


def track_psd_m2_per_rad_m(omega_rad_per_m: np.ndarray, channel: str, track_class: int) -> np.ndarray:
    """One-sided FRA spatial PSD, m^2 / (rad/m): channel "vertical", "lateral" or "roll" (cross-level)."""
    if track_class not in FRA_ROUGHNESS_CM2_RAD_PER_M:
        raise ValueError(
            f"unknown FRA track_class {track_class!r}; valid: {list(FRA_ROUGHNESS_CM2_RAD_PER_M)}"
        )
    a_v, a_a = FRA_ROUGHNESS_CM2_RAD_PER_M[track_class]
    w2 = np.asarray(omega_rad_per_m, dtype=np.float64) ** 2
    wc2, ws2 = FRA_OMEGA_C_RAD_PER_M**2, FRA_OMEGA_S_RAD_PER_M**2
    if channel == "vertical":
        s_cm2 = FRA_K * a_v * wc2 / (w2 * (w2 + wc2))
    elif channel == "lateral":
        s_cm2 = FRA_K * a_a * wc2 / (w2 * (w2 + wc2))
    elif channel == "roll":
        s_cm2 = 4.0 * FRA_K * a_v * wc2 / ((w2 + wc2) * (w2 + ws2))
    else:
        raise ValueError(f"unknown track channel {channel!r}; valid: {list(TRACK_CHANNELS)}")
    return 1e-4 * s_cm2


def track_psd_m2_per_hz(f_hz: np.ndarray, speed_mps: float, channel: str, track_class: int) -> np.ndarray:
    """The spatial PSD met at speed v, per Hz: S(f) = S(Omega = 2 pi f / v) 2 pi / v."""
    omega = 2.0 * np.pi * np.asarray(f_hz, dtype=np.float64) / speed_mps
    return track_psd_m2_per_rad_m(omega, channel, track_class) * 2.0 * np.pi / speed_mps


def suspension_tf(channel: str) -> tuple[np.ndarray, np.ndarray]:
    """(num, den) of the base-excited second-order car-body suspension of a channel."""
    f_n, zeta = SUSPENSION_MODES[channel]
    w_n = 2.0 * np.pi * f_n
    return np.array([2.0 * zeta * w_n, w_n**2]), np.array([1.0, 2.0 * zeta * w_n, w_n**2])


def synthesis_band_hz(speed_mps: float, dt_s: float) -> tuple[float, float]:
    """The temporal band of the track vibration: v / 300 m to min(v / 1.5 m, 0.2 / dt), Hz."""
    return speed_mps / WAVELENGTH_BAND_M[1], min(
        speed_mps / WAVELENGTH_BAND_M[0], MAX_FREQUENCY_TIMES_DT / dt_s
    )


def alignment(
    s_m: np.ndarray, straight_m: float, transition_m: float, radius_m: float
) -> dict[str, np.ndarray]:
    """Track centreline at distance s: x, y (m), heading psi (rad), curvature (1/m), cant fraction 0..1.

    Straight of ``straight_m``, clothoid of ``transition_m`` (curvature linear in distance), then
    the arc of ``radius_m`` turning left (module docstring, item 1).
    """
    s = np.asarray(s_m, dtype=np.float64)
    u = np.clip(s - straight_m, 0.0, transition_m)  # distance into the transition
    w = np.maximum(s - straight_m - transition_m, 0.0)  # distance into the arc
    a = math.sqrt(math.pi * transition_m * radius_m)
    fres_s, fres_c = fresnel(u / a)
    x_tr, y_tr = straight_m + a * fres_c, a * fres_s
    psi_tr = u**2 / (2.0 * transition_m * radius_m)
    # the arc continues from the transition's end point and heading
    psi_1 = transition_m / (2.0 * radius_m)
    s1, c1 = fresnel(transition_m / a)
    x_1, y_1 = straight_m + a * c1, a * s1
    x_c, y_c = x_1 - radius_m * math.sin(psi_1), y_1 + radius_m * math.cos(psi_1)
    psi = psi_tr + w / radius_m
    on_arc = w > 0
    x = np.where(on_arc, x_c + radius_m * np.sin(psi), np.where(s < straight_m, s, x_tr))
    y = np.where(on_arc, y_c - radius_m * np.cos(psi), y_tr)
    return {
        "x": x,
        "y": y,
        "psi": psi,
        "curvature": u / (transition_m * radius_m),  # u stops at L on the arc: 1 / R
        "cant_fraction": u / transition_m,
    }


def train(
    variant: str = "curve",
    *,
    speed_mps: float | None = None,
    radius_m: float = DEFAULT_RADIUS_M,
    cant_mm: float = DEFAULT_CANT_MM,
    transition_m: float = DEFAULT_TRANSITION_M,
    straight_m: float = DEFAULT_STRAIGHT_M,
    track_class: int = DEFAULT_TRACK_CLASS,
    vibration: bool = True,
    duration_s: float = DEFAULT_DURATION_S,
    dt_s: float = DEFAULT_DT_S,
    seed: int = 0,
) -> Motion:
    """The floor motion of a passenger coach (module docstring), in the frame moving with the train.

    ``variant``: "curve" (straight, clothoid transition, canted arc, with vibration) or "straight"
    (vibration only). ``speed_mps`` defaults per variant (:data:`DEFAULT_SPEED_MPS`); the curve
    geometry (``radius_m``, ``cant_mm``, ``transition_m``, ``straight_m``) is used by "curve" only.
    ``track_class``: FRA class 4, 5 or 6; ``vibration=False`` leaves the quasi-static curving alone.
    """
    if variant not in VARIANTS:
        raise ValueError(f"unknown train variant {variant!r}; valid: {list(VARIANTS)}")
    v = DEFAULT_SPEED_MPS[variant] if speed_mps is None else float(speed_mps)
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"speed_mps must be positive, got {speed_mps}")
    if track_class not in FRA_ROUGHNESS_CM2_RAD_PER_M:
        raise ValueError(
            f"unknown FRA track_class {track_class!r}; valid: {list(FRA_ROUGHNESS_CM2_RAD_PER_M)}"
        )
    t = time_grid(duration_s, dt_s)
    n = len(t)
    s = v * t
    params: dict = {
        "variant": variant,
        "speed_mps": v,
        "track_class": int(track_class),
        "vibration": bool(vibration),
    }

    if variant == "curve":
        if not radius_m > 0 or not transition_m > 0 or not straight_m >= 0:
            raise ValueError(
                "radius_m and transition_m must be positive and straight_m >= 0, "
                f"got {radius_m}, {transition_m}, {straight_m}"
            )
        if not 0 <= cant_mm < 1000.0 * RAIL_CENTRES_M:
            raise ValueError(f"cant_mm must be in [0, {1000.0 * RAIL_CENTRES_M:.0f}) mm, got {cant_mm}")
        if straight_m + transition_m >= s[-1]:
            raise ValueError(
                f"the arc starts at {straight_m + transition_m:.0f} m but the train runs only {s[-1]:.0f} m "
                f"in {t[-1]:.1f} s: shorten straight_m / transition_m or raise speed_mps / duration_s"
            )
        geo = alignment(s, straight_m, transition_m, radius_m)
        if np.max(np.abs(geo["psi"])) > MAX_YAW_RAD:
            raise ValueError(
                f"the heading turns {np.max(np.abs(geo['psi'])):.2f} rad > {MAX_YAW_RAD} rad (the "
                "platform's yaw range): raise radius_m or shorten duration_s"
            )
        theta_rad = math.asin(cant_mm / (1000.0 * RAIL_CENTRES_M))
        roll = -np.arcsin(geo["cant_fraction"] * cant_mm / (1000.0 * RAIL_CENTRES_M))
        lateral_acc = v**2 / radius_m * math.cos(theta_rad) - GRAVITY_M_S2 * math.sin(theta_rad)
        deficiency_mm = 1000.0 * RAIL_CENTRES_M * v**2 / (GRAVITY_M_S2 * radius_m) - cant_mm
        params.update(
            radius_m=float(radius_m),
            cant_mm=float(cant_mm),
            transition_m=float(transition_m),
            straight_m=float(straight_m),
            cant_angle_rad=theta_rad,
            transition_start_s=straight_m / v,
            arc_start_s=(straight_m + transition_m) / v,
            steady_lateral_acc_mps2=lateral_acc,
            en13803_uncompensated_acc_mps2=v**2 / radius_m
            - GRAVITY_M_S2 * cant_mm / (1000.0 * RAIL_CENTRES_M),
            cant_deficiency_mm=deficiency_mm,
            cant_rate_mm_s=v * cant_mm / transition_m,
            cant_deficiency_rate_mm_s=v * deficiency_mm / transition_m,
            final_heading_rad=float(geo["psi"][-1]),
        )
        x_track, y_track, psi = geo["x"] - s, geo["y"], geo["psi"]  # minus v t: the moving frame
    else:
        x_track, y_track, psi, roll = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)

    z_vib, lat_vib, roll_vib = np.zeros(n), np.zeros(n), np.zeros(n)
    if vibration:
        rng = np.random.default_rng(seed)
        f_lo, f_hi = synthesis_band_hz(v, dt_s)
        ramp = smooth_ramp(t, RAMP_S)
        body = {}
        for channel in TRACK_CHANNELS:
            track = random_phase_noise(
                lambda f, c=channel: track_psd_m2_per_hz(f, v, c, track_class),
                n,
                dt_s,
                f_min_hz=f_lo,
                f_max_hz=f_hi,
                seed=rng,
            )
            if channel == "roll":
                track = track / RAIL_CENTRES_M  # cross-level (rail height difference) -> track roll angle
            body[channel] = lti_filter(*suspension_tf(channel), ramp * track, dt_s)
        z_vib, lat_vib, roll_vib = body["vertical"], body["lateral"], body["roll"]
        params.update(synthesis_band_hz=[f_lo, f_hi], ramp_s=RAMP_S)

    # body lateral vibration along the track's left normal (-sin psi, cos psi)
    p_body = np.stack([x_track - np.sin(psi) * lat_vib, y_track + np.cos(psi) * lat_vib, z_vib], axis=1)
    euler = np.stack([roll + roll_vib, np.zeros(n), psi], axis=1)
    pose = deck_pose(p_body, euler, np.array([0.0, 0.0, FLOOR_HEIGHT_M]))
    params.update(floor_height_m=FLOOR_HEIGHT_M, duration_s=float(t[-1]), dt_s=float(dt_s), seed=int(seed))

    notes = (
        f"Train {variant} at {v:.1f} m/s on FRA class {track_class} track, in the frame moving at the "
        "train speed "
        "along the initial straight (constant velocity is invisible to the robot; the platform starts at rest"
        + (f", vibration faded in over {RAMP_S:.0f} s" if vibration else ", no vibration")
        + ")."
    )
    if variant == "curve":
        lim = "within" if params["cant_deficiency_mm"] <= 150.0 else "BEYOND"
        notes += (
            f" Curve R {radius_m:.0f} m, cant {cant_mm:.0f} mm (roll {params['cant_angle_rad']:.3f} rad), "
            f"transition {transition_m:.0f} m from t = {params['transition_start_s']:.1f} s, arc from "
            f"{params['arc_start_s']:.1f} s; steady lateral acceleration "
            f"{params['steady_lateral_acc_mps2']:.2f} m/s^2, cant deficiency "
            f"{params['cant_deficiency_mm']:.0f} mm ({lim} EN 13803's ~150 mm maximum); heading turns "
            f"{params['final_heading_rad']:.2f} rad; the curve's departure from the initial straight "
            f"({np.max(np.abs(y_track)):.0f} m sideways) is kept, not clipped (the world is unbounded)."
        )
    if vibration:
        notes += (
            f" Floor vibration RMS: vertical {np.std(z_vib):.4f} m, lateral {np.std(lat_vib):.4f} m, "
            f"roll {np.std(roll_vib):.4f} rad."
        )
    return Motion(name=f"train_{variant}", t_s=t, pose=pose, params=params, notes=notes)
