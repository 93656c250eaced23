"""Aircraft in turbulence: the cabin floor of a mid-size transport flying through Dryden turbulence.

Why: a cabin floor in turbulence is the moving floor with the most random vertical acceleration.
Vertical and roll gusts come from the Dryden forming filters of MIL-F-8785C (medium/high
altitude, L_w = 1,750 ft, intensities "light", "moderate", "severe" from its figure 7); the
vertical gust drives the plunge of an A320-class transport through its gust load factor, with an
unsteady-lift lag, and the roll gust a 1-s roll mode held level by a wings-leveller; the bank turns
the aircraft (coordinated). Pitch is held at 0. Body frame at the CG: x forward, y to the left
wing, z up; the motion is seen from the frame moving with the initial velocity (invisible to the
robot), so it starts at rest; nothing is scaled or clipped. Derivation, the aircraft's data and
every source: docs/real_motion.md, "Aircraft".
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.integrate import cumulative_trapezoid

from lasmp.motions.motion import (
    DEFAULT_DT_S,
    DEFAULT_DURATION_S,
    GRAVITY_M_S2,
    Motion,
    choice,
    deck_pose,
    point,
    positive,
    time_grid,
)
from lasmp.motions.noise import filtered_white_noise, lti_filter, smooth_ramp

FT_M = 0.3048
SCALE_LENGTH_M = 1750.0 * FT_M  # MIL-F-8785C medium/high-altitude Dryden scale length L_w
RAMP_S = 2.0  # quintic ramp-in of the gusts, s
WARMUP_SCALE_TIMES = 10.0  # gusts generated for this many L_w / V before t = 0 (stationary start)
KUSSNER_SEMICHORDS = 3.0  # Kuessner psi(s') reaches 1 - 1/e at s' = 3 semichords
CABIN_POINT_M = (-8.0, 0.0, -1.0)  # body frame: 8 m aft of the CG, on the aisle, floor 1 m below the CG
DEFAULT_AIRSPEED_MPS = 130.0
DEFAULT_ALTITUDE_M = 3000.0

# MIL-F-8785C fig. 7: sigma (ft/s) against altitude (ft) for probabilities of exceedance 1e-2 / 1e-3 / 1e-5
INTENSITY_ALTITUDES_FT = np.array([500.0, 1750.0, 3750.0, 7500.0, 15000.0, 25000.0, 35000.0, 45000.0])
INTENSITY_TABLE_FTPS: dict[str, np.ndarray] = {
    "light": np.array([6.6, 6.9, 7.4, 6.7, 4.6, 2.7, 0.4, 0.0]),
    "moderate": np.array([8.6, 9.6, 10.6, 10.1, 8.0, 6.6, 5.0, 4.2]),
    "severe": np.array([15.6, 17.6, 23.0, 23.6, 22.1, 20.0, 16.0, 15.1]),
}
INTENSITIES = tuple(INTENSITY_TABLE_FTPS)
MIN_ALTITUDE_M = 2000.0 * FT_M  # the medium/high-altitude model applies above 2000 ft
MAX_ALTITUDE_M = 11000.0  # the ISA troposphere formula (and a non-zero "light" sigma) holds up to here


@dataclass(frozen=True)
class TransportAircraft:
    """Mass, wing and roll-control data of the aircraft (values and sources: docs/real_motion.md)."""

    wing_loading_kg_m2: float = 600.0
    lift_slope_per_rad: float = 5.0
    span_m: float = 34.1
    mean_chord_m: float = 4.2
    roll_time_constant_s: float = 1.0
    wings_level_omega_rad_s: float = 0.5


MID_SIZE_TRANSPORT = TransportAircraft()


def isa_density_kg_m3(altitude_m: float) -> float:
    """Air density of the ISA troposphere (ISO 2533:1975), valid below 11 km."""
    return 1.225 * (1.0 - 2.25577e-5 * altitude_m) ** 4.25588


def turbulence_sigma_mps(intensity: str, altitude_m: float) -> float:
    """MIL-F-8785C medium/high-altitude RMS gust velocity sigma_w (m/s) for an intensity name."""
    choice("turbulence_sigma_mps", "intensity", intensity, INTENSITIES)
    if not MIN_ALTITUDE_M <= altitude_m <= MAX_ALTITUDE_M:
        raise ValueError(
            f"altitude_m must be in [{MIN_ALTITUDE_M:.0f}, {MAX_ALTITUDE_M:.0f}] m (medium/high-altitude "
            f"Dryden model, ISA troposphere), got {altitude_m}"
        )
    sigma_ftps = np.interp(altitude_m / FT_M, INTENSITY_ALTITUDES_FT, INTENSITY_TABLE_FTPS[intensity])
    return float(sigma_ftps) * FT_M


def dryden_vertical_tf(
    sigma_w_mps: float, scale_m: float, airspeed_mps: float
) -> tuple[np.ndarray, np.ndarray]:
    """(num, den) of the Dryden vertical-gust forming filter H_w(s), descending powers of s."""
    tau_s = scale_m / airspeed_mps
    gain = sigma_w_mps * math.sqrt(scale_m / (math.pi * airspeed_mps))
    return gain * np.array([math.sqrt(3.0) * tau_s, 1.0]), np.array([tau_s**2, 2.0 * tau_s, 1.0])


def dryden_roll_tf(
    sigma_w_mps: float, scale_m: float, airspeed_mps: float, span_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """(num, den) of the Dryden roll-gust forming filter H_p(s) (rad/s per unit white noise)."""
    gain = (
        sigma_w_mps
        * math.sqrt(0.8 / airspeed_mps)
        * (math.pi / (4.0 * span_m)) ** (1.0 / 6.0)
        / scale_m ** (1.0 / 3.0)
    )
    return np.array([gain]), np.array([4.0 * span_m / (math.pi * airspeed_mps), 1.0])


def gust_rate_per_s(
    airspeed_mps: float, density_kg_m3: float, model: TransportAircraft = MID_SIZE_TRANSPORT
) -> float:
    """K = rho V C_La / (2 m / S): vertical acceleration per unit vertical gust speed, 1/s."""
    return density_kg_m3 * airspeed_mps * model.lift_slope_per_rad / (2.0 * model.wing_loading_kg_m2)


def aircraft(
    intensity: str = "light",
    *,
    airspeed_mps: float = DEFAULT_AIRSPEED_MPS,
    altitude_m: float = DEFAULT_ALTITUDE_M,
    cabin_point_m: tuple[float, float, float] = CABIN_POINT_M,
    duration_s: float = DEFAULT_DURATION_S,
    dt_s: float = DEFAULT_DT_S,
    seed: int = 0,
) -> Motion:
    """The cabin-floor motion of a mid-size transport in Dryden turbulence (docs/real_motion.md).

    ``intensity``: "light", "moderate" or "severe" (MIL-F-8785C exceedance probability 1e-2, 1e-3,
    1e-5); ``airspeed_mps``: true airspeed; ``altitude_m``: 610 m (2000 ft) to 11 km.
    """
    where = "aircraft"
    choice(where, "intensity", intensity, INTENSITIES)
    v = positive(where, "airspeed_mps", airspeed_mps)
    cabin = point(where, "cabin_point_m", cabin_point_m, "forward, left, up")
    sigma_w = turbulence_sigma_mps(intensity, altitude_m)
    t = time_grid(duration_s, dt_s)
    n = len(t)
    model = MID_SIZE_TRANSPORT
    rho = isa_density_kg_m3(altitude_m)
    k_gust = gust_rate_per_s(v, rho, model)
    tau_u = KUSSNER_SEMICHORDS * 0.5 * model.mean_chord_m / v
    tau_r = model.roll_time_constant_s
    omega_a = model.wings_level_omega_rad_s

    rng = np.random.default_rng(seed)
    warmup_s = WARMUP_SCALE_TIMES * SCALE_LENGTH_M / v
    w_gust = filtered_white_noise(
        *dryden_vertical_tf(sigma_w, SCALE_LENGTH_M, v), n, dt_s, seed=rng, warmup_s=warmup_s
    )
    p_gust = filtered_white_noise(
        *dryden_roll_tf(sigma_w, SCALE_LENGTH_M, v, model.span_m), n, dt_s, seed=rng, warmup_s=warmup_s
    )
    ramp = smooth_ramp(t, RAMP_S)

    # plunge: w_a / w_g = K / ((s + K)(tau_u s + 1)); a_z = dw_a/dt
    w_air = lti_filter([k_gust], np.polymul([tau_u, 1.0], [1.0, k_gust]), ramp * w_gust, dt_s)
    z = cumulative_trapezoid(w_air, t, initial=0.0)
    # roll mode + wings-leveller: phi / p_g = (1 / tau_r) / (s^2 + s / tau_r + omega_a^2)
    roll = lti_filter([1.0 / tau_r], [1.0, 1.0 / tau_r, omega_a**2], ramp * p_gust, dt_s)
    # coordinated turn from the bank, in the frame moving with the initial velocity
    yaw = cumulative_trapezoid(-GRAVITY_M_S2 * np.tan(roll) / v, t, initial=0.0)
    x = cumulative_trapezoid(v * (np.cos(yaw) - 1.0), t, initial=0.0)
    y = cumulative_trapezoid(v * np.sin(yaw), t, initial=0.0)

    euler = np.stack([roll, np.zeros(n), yaw], axis=1)
    pose = deck_pose(np.stack([x, y, z], axis=1), euler, cabin)

    a_z = np.gradient(w_air, t)
    params = {
        "intensity": intensity,
        "sigma_w_mps": sigma_w,
        "scale_length_m": SCALE_LENGTH_M,
        "airspeed_mps": v,
        "altitude_m": float(altitude_m),
        "air_density_kg_m3": rho,
        "gust_rate_per_s": k_gust,
        "unsteady_lift_lag_s": tau_u,
        "ramp_s": RAMP_S,
        "cabin_point_m": cabin.tolist(),
        "aircraft": asdict(model),
        "duration_s": float(t[-1]),
        "dt_s": float(dt_s),
        "seed": int(seed) if isinstance(seed, (int, np.integer)) else None,
    }
    notes = (
        f"Dryden {intensity} turbulence (sigma_w {sigma_w:.2f} m/s, L_w {SCALE_LENGTH_M:.0f} m) at "
        f"{v:.0f} m/s, {altitude_m:.0f} m. Frame moving with the initial velocity (constant velocity is "
        f"invisible to the robot); gusts ramped in over {RAMP_S:.0f} s so the motion starts at rest. "
        "Not scaled or clipped: CG vertical "
        f"acceleration RMS {np.sqrt(np.mean(a_z**2)):.2f} m/s^2 (peak {np.max(np.abs(a_z)):.2f}), max |roll| "
        f"{np.max(np.abs(roll)):.3f} rad, altitude wander {np.ptp(z):.1f} m and lateral drift "
        f"{np.max(np.abs(y)):.1f} m kept (the world is unbounded); pitch held at 0 (short period neglected)."
    )
    return Motion(name=f"aircraft_{intensity}", t_s=t, pose=pose, params=params, notes=notes)
