"""Rail: the floor of a passenger coach entering a canted curve, and riding on irregular track.

Why: a train floor accelerates sideways in curves and vibrates with the track. The alignment is
EN 13803's straight, clothoid transition and canted arc (cant rolls the body, the unbalanced part
of the centripetal acceleration is felt); the track irregularities are the FRA spectra of Hamid and
Yang (1981) for classes 4-6 (vertical profile, alignment, cross-level), synthesised by the
random-phase method and passed through a second-order car-body suspension per channel; the floor
point rides 1.2 m above the rail plane. Body frame: x forward, y left, z up; the curve turns left,
so its cant gives a negative roll. The motion is seen from the frame that moves at the train's
constant speed along the initial straight (a constant velocity is invisible to the robot), so it
starts at rest. Derivation, values and sources: docs/real_motion.md, "Rail".
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import fresnel

from lasmp.motions.motion import (
    DEFAULT_DT_S,
    DEFAULT_DURATION_S,
    GRAVITY_M_S2,
    MAX_YAW_RAD,
    Motion,
    choice,
    deck_pose,
    positive,
    time_grid,
)
from lasmp.motions.noise import lti_filter, random_phase_noise, second_order_tf, smooth_ramp

RAIL_CENTRES_M = 1.5  # EN 13803: cant is measured over the 1500 mm rail-head centres of 1435 mm gauge
FLOOR_HEIGHT_M = 1.2  # coach floor above the rail plane (design choice, typical single-deck coach)
RAMP_S = 2.0  # quintic fade-in of the track vibration, s

# FRA track spectra (Hamid and Yang 1981): class -> (A_v, A_a), cm^2 rad/m
FRA_ROUGHNESS_CM2_RAD_PER_M: dict[int, tuple[float, float]] = {
    4: (0.5376, 0.3027),
    5: (0.2095, 0.0762),
    6: (0.0339, 0.0339),
}
# class -> the cross-level roll-off wavenumber Omega_s, rad/m: it differs per class (Omega_c does not)
FRA_OMEGA_S_RAD_PER_M: dict[int, float] = {4: 1.1312, 5: 0.8209, 6: 0.4380}
FRA_K = 0.25
FRA_OMEGA_C_RAD_PER_M = 0.8245
WAVELENGTH_BAND_M = (1.5, 300.0)  # the FRA fits' wavelength range
MAX_FREQUENCY_TIMES_DT = 0.2  # the synthesis band ends at 0.2 / dt (20 Hz at 100 Hz samples)
TRACK_CHANNELS = ("vertical", "lateral", "roll")

# channel -> (natural frequency Hz, damping ratio) of the car body on its suspension
SUSPENSION_MODES: dict[str, tuple[float, float]] = {
    "vertical": (1.0, 0.2),
    "lateral": (0.8, 0.2),
    "roll": (0.8, 0.2),
}

VARIANTS = ("curve", "straight")
# variant -> default speed: 160 km/h in the curve; on the straight 110 mph, the passenger-train
# limit of FRA class 6 track (49 CFR 213.307; classes 4 and 5, 80 and 90 mph, are in 213.9)
DEFAULT_SPEED_MPS = {"curve": 160.0 / 3.6, "straight": 110.0 * 0.44704}
DEFAULT_RADIUS_M = 1500.0
DEFAULT_CANT_MM = 100.0
DEFAULT_TRANSITION_M = 120.0
DEFAULT_STRAIGHT_M = 200.0
DEFAULT_TRACK_CLASS = 6


def track_psd_m2_per_rad_m(omega_rad_per_m: np.ndarray, channel: str, track_class: int) -> np.ndarray:
    """One-sided FRA spatial PSD, m^2 / (rad/m): channel "vertical", "lateral" or "roll" (cross-level)."""
    choice("FRA", "track_class", track_class, FRA_ROUGHNESS_CM2_RAD_PER_M)
    a_v, a_a = FRA_ROUGHNESS_CM2_RAD_PER_M[track_class]
    w2 = np.asarray(omega_rad_per_m, dtype=np.float64) ** 2
    wc2, ws2 = FRA_OMEGA_C_RAD_PER_M**2, FRA_OMEGA_S_RAD_PER_M[track_class] ** 2
    if channel == "vertical":
        s_cm2 = FRA_K * a_v * wc2 / (w2 * (w2 + wc2))
    elif channel == "lateral":
        s_cm2 = FRA_K * a_a * wc2 / (w2 * (w2 + wc2))
    elif channel == "roll":
        s_cm2 = 4.0 * FRA_K * a_v * wc2 / ((w2 + wc2) * (w2 + ws2))
    else:
        choice("FRA", "track channel", channel, TRACK_CHANNELS)
    return 1e-4 * s_cm2


def track_psd_m2_per_hz(f_hz: np.ndarray, speed_mps: float, channel: str, track_class: int) -> np.ndarray:
    """The spatial PSD met at speed v, per Hz: S(f) = S(Omega = 2 pi f / v) 2 pi / v."""
    omega = 2.0 * np.pi * np.asarray(f_hz, dtype=np.float64) / speed_mps
    return track_psd_m2_per_rad_m(omega, channel, track_class) * 2.0 * np.pi / speed_mps


def suspension_tf(channel: str) -> tuple[list, list]:
    """(num, den) of the base-excited second-order car-body suspension of a channel."""
    f_n, zeta = SUSPENSION_MODES[channel]
    return second_order_tf(2.0 * np.pi * f_n, zeta, base_excited=True)


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
    the arc of ``radius_m`` turning left (docs/real_motion.md, "Rail").
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
    """The floor motion of a passenger coach (docs/real_motion.md), in the frame moving with the train.

    ``variant``: "curve" (straight, clothoid transition, canted arc, with vibration) or "straight"
    (vibration only). ``speed_mps`` defaults per variant (:data:`DEFAULT_SPEED_MPS`); the curve
    geometry (``radius_m``, ``cant_mm``, ``transition_m``, ``straight_m``) is used by "curve" only.
    ``track_class``: FRA class 4, 5 or 6; ``vibration=False`` leaves the quasi-static curving alone.
    """
    choice("train", "variant", variant, VARIANTS)
    v = positive("train", "speed_mps", DEFAULT_SPEED_MPS[variant] if speed_mps is None else speed_mps)
    choice("train", "track_class", track_class, FRA_ROUGHNESS_CM2_RAD_PER_M)
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
