"""Aircraft in turbulence: the cabin floor of a mid-size transport flying through Dryden turbulence.

Frames and signs
    Aircraft body frame at the centre of gravity (CG): x forward, y to the left wing, z up, the pose
    convention of :mod:`lasmp.eval.real_motion.motion` (``R = Rz(yaw) Ry(pitch) Rx(roll)``), so a
    positive roll lifts the left wing and a positive yaw turns left. The motion is expressed in a
    frame moving with the aircraft's initial velocity (airspeed V along the initial heading, level):
    a constant velocity is physically invisible to the robot (Galilean invariance), so only the
    deviations from straight and level flight move the platform and the motion starts at rest.

1. Turbulence (Dryden form of MIL-F-8785C, "Flying Qualities of Piloted Airplanes", 1980,
   section 3.7.2, also MIL-HDBK-1797, 1997, appendix A): a frozen field flown through at V, so a
   spatial frequency Omega (rad/m) is met at w = V Omega (rad/s). The vertical gust ``w_g`` has
   the one-sided PSD (per rad/s)::

       Phi_w(w) = sigma_w^2 L_w / (pi V) (1 + 3 (L_w w / V)^2) / (1 + (L_w w / V)^2)^2

   whose integral over w >= 0 is sigma_w^2. It is the output of the forming filter
   ``H_w(s) = sigma_w sqrt(L_w / (pi V)) (1 + sqrt(3) L_w s / V) / (1 + L_w s / V)^2`` driven by
   white noise of unit one-sided PSD (:func:`lasmp.eval.real_motion.noise.filtered_white_noise`).
   The roll gust ``p_g`` (the spanwise gradient of the vertical gust, which rolls the wing) has
   ``Phi_p(w) = sigma_w^2 / (V L_w) 0.8 (pi L_w / (4 b))^(1/3) / (1 + (4 b w / (pi V))^2)``, from
   ``H_p(s) = sigma_w sqrt(0.8 / V) (pi / (4 b))^(1/6) / (L_w^(1/3) (1 + 4 b s / (pi V)))``
   (b the wing span). Medium/high altitude (above 2000 ft): scale length L_w = 1750 ft = 533.4 m
   (MIL-F-8785C; MIL-HDBK-1797 uses L_w = 875 ft), and the intensity sigma_w = sigma_u = sigma_v
   from MIL-F-8785C figure 7 as a function of altitude and probability of exceedance:
   "light" 1e-2, "moderate" 1e-3, "severe" 1e-5 (the convention of MIL-HDBK-1797 and of the
   MathWorks Aerospace Blockset Dryden blocks). :data:`INTENSITY_TABLE_FTPS` holds the figure's
   values (ft/s at 500 ... 45000 ft, as tabulated in those blocks and in JSBSim's FGWinds),
   interpolated linearly in altitude. At the default 3000 m (9843 ft): light 6.0 ft/s = 1.84 m/s,
   moderate 9.4 ft/s = 2.88 m/s, severe 23.1 ft/s = 7.05 m/s. The gusts are generated for
   10 L_w / V before t = 0 and dropped, so the field is stationary from the first sample.

2. Vertical response (plunge, pitch attitude held). A vertical gust changes the angle of attack
   by (w_g - w_a) / V, with w_a the aircraft's own vertical speed, so the lift increment gives::

       a_z = dw_a/dt = K (w_g,eff - w_a),     K = rho V C_La / (2 (m / S))   [1/s]

   The sharp-edged-gust load factor ``dn = K w_g / g`` is the instantaneous part (Pratt and
   Walker (1954), "A revised gust-load formula and a re-evaluation of V-G data taken on civil
   transport airplanes from 1933 to 1950", NACA Report 1206; 14 CFR 25.341(a)); the feedback of
   w_a is the plunge lag (time constant 1 / K = 2.0 s here) that the Pratt-Walker alleviation
   factor K_g accounts for: a long updraft lifts the aircraft with the air instead of
   accelerating it forever. ``w_g,eff`` is ``w_g`` through a first-order lag ``1 / (tau_u s + 1)``
   for the build-up of unsteady lift on entering a gust (Kuessner function, approximated by
   ``psi(s') = 1 - 0.5 e^(-0.13 s') - 0.5 e^(-s')`` in semichords travelled s', Sears and Sparks
   (1941), "On the reaction of an elastic wing to vertical gusts", J. Aeronaut. Sci. 9(2), as
   used in Bisplinghoff, Ashley and Halfman (1955), "Aeroelasticity"; psi reaches 1 - 1/e at
   s' = 3, so ``tau_u = 3 (c / 2) / V`` = 0.048 s). Together::

       a_z / w_g = K s / ((s + K)(tau_u s + 1)),   z = double integral of a_z from rest.

   The short-period pitch response (which weathercocks the nose into the gust and relieves part
   of the load) is neglected, so the loads are on the high side; pitch stays 0. ``z`` is the
   physical double integral: there is no mean climb (the flight path is level), the aircraft's
   altitude wanders only with the turbulence (tens of metres over 20 s in moderate turbulence,
   as a real aircraft with its altitude hold off does); the world is unbounded, and what the
   robot feels is the acceleration.

3. Roll response: the roll mode (first order, time constant tau_r) drives the roll rate p
   toward the roll gust, and a wings-leveller (pilot or autopilot) returns the bank to level::

       dp/dt = (p_g - p) / tau_r - w_a^2 phi,   dphi/dt = p,
       phi / p_g = (1 / tau_r) / (s^2 + s / tau_r + w_a^2)

   a second-order system (damping ratio 1 / (2 tau_r w_a)) that keeps the bank bounded.
   tau_r = 1.0 s is within MIL-F-8785C's Level 1 limit for Class III (transport) aircraft
   (table IX: at most 1.4 s in flight-phase categories A and C, 3.0 s in B). The wings-leveller
   bandwidth w_a = 0.5 rad/s is a design choice (not from a standard): with tau_r = 1 s the loop
   is critically damped and the bank settles in ~10 s.

4. Lateral path: the banked lift turns the aircraft (coordinated, sideslip held at zero by the
   yaw damper): ``dpsi/dt = -g tan(phi) / V`` (positive roll lifts the left wing, so the aircraft
   turns right), and in the co-moving frame ``dx/dt = V (cos psi - 1)``, ``dy/dt = V sin psi``.
   The lateral specific force on the cabin floor is then nearly zero, as in a real airliner: a
   bank tilts the floor *and* the lift, so the robot feels no sideways pull. What remains is
   second order: the gust lift increment is applied vertically rather than along the banked
   body z axis, leaving ``a_z sin(phi)`` (~0.03 m/s^2 RMS in moderate turbulence). The load
   increment of a bank (1 / cos phi - 1, < 0.1 % at 2 deg) and lateral gusts are neglected.

5. Cabin floor point: ``cabin_point_m`` in the body frame (default 8 m aft of the CG on the
   aisle, floor 1 m below the CG: a design choice for a mid-size narrow-body) moved rigidly with
   the CG by :func:`lasmp.eval.real_motion.motion.deck_pose` (roll adds lever-arm sway).

6. Ramp-in: the gust inputs (not the responses) are multiplied by a quintic smooth step over
   ``RAMP_S`` = 2 s (:func:`lasmp.eval.real_motion.noise.smooth_ramp`) and every response
   starts from rest, so ``pose[0] == 0`` and the motion starts at rest.

Aircraft (:data:`MID_SIZE_TRANSPORT`, an A320 / 737-800 class narrow-body in climb/descent):

=====================  ==========  ==============================================================
airspeed V (TAS)       130 m/s     typical climb/descent speed near 10 000 ft (250 kt)
altitude               3000 m      above 2000 ft: the medium/high-altitude Dryden model applies
air density rho        0.909       ISA at 3000 m (ISO 2533:1975; U.S. Standard Atmosphere 1976),
                       kg/m^3      rho0 (1 - 2.25577e-5 h)^4.25588, rho0 = 1.225 kg/m^3
wing loading m / S     600 kg/m^2  A320-200: MTOW 78 t / 122.6 m^2 = 636 kg/m^2; 737-800: 79 t /
                                   124.6 m^2 = 634 kg/m^2 (manufacturers' airport-planning
                                   documents); 600 for a part-loaded aircraft
lift slope C_La        5.0 /rad    USAF DATCOM / Raymer (2018), "Aircraft Design: A Conceptual
                                   Approach", eq. 12.6 (Helmbold-Diederich): aspect ratio 9.5,
                                   half-chord sweep 22 deg, Mach 0.4 give 5.1 /rad
span b, mean chord c   34.1, 4.2 m A320-200 (Airbus, "A320 Aircraft Characteristics - Airport and
                                   Maintenance Planning"): span 34.10 m, MAC 4.19 m
roll mode tau_r        1.0 s       MIL-F-8785C table IX (Class III, Level 1: <= 1.4 s)
wings-leveller w_a     0.5 rad/s   design choice (critically damped with tau_r; item 3)
gust rate K            0.49 1/s    rho V C_La / (2 m / S) (item 2)
unsteady-lift tau_u    0.048 s     3 semichords / V (item 2)
=====================  ==========  ==============================================================

Fitting to the platform world: nothing is scaled or clipped; the altitude and lateral drift are
kept (the platform world is unbounded and translation invariant), and ``notes`` states the extremes.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.integrate import cumulative_trapezoid

from lasmp.eval.real_motion.motion import DEFAULT_DT_S, DEFAULT_DURATION_S, Motion, deck_pose, time_grid
from lasmp.eval.real_motion.noise import filtered_white_noise, lti_filter, smooth_ramp

GRAVITY_M_S2 = 9.81
FT_M = 0.3048
SCALE_LENGTH_M = 1750.0 * FT_M  # MIL-F-8785C medium/high-altitude Dryden scale length L_w
RAMP_S = 2.0  # quintic ramp-in of the gusts, s
WARMUP_SCALE_TIMES = 10.0  # gusts generated for this many L_w / V before t = 0 (stationary start)
KUSSNER_SEMICHORDS = 3.0  # Kuessner psi(s') reaches 1 - 1/e at s' = 3 semichords (item 2)
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
    """Mass, wing and roll-control data of the aircraft (module docstring table)."""

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
    if intensity not in INTENSITY_TABLE_FTPS:
        raise ValueError(f"unknown turbulence intensity {intensity!r}; valid: {list(INTENSITIES)}")
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
    """The cabin-floor motion of a mid-size transport in Dryden turbulence (module docstring).

    ``intensity``: "light", "moderate" or "severe" (MIL-F-8785C exceedance probability 1e-2, 1e-3,
    1e-5); ``airspeed_mps``: true airspeed; ``altitude_m``: 610 m (2000 ft) to 11 km.
    """
    if intensity not in INTENSITY_TABLE_FTPS:
        raise ValueError(f"unknown turbulence intensity {intensity!r}; valid: {list(INTENSITIES)}")
    if not (math.isfinite(airspeed_mps) and airspeed_mps > 0):
        raise ValueError(f"airspeed_mps must be positive, got {airspeed_mps}")
    cabin = np.asarray(cabin_point_m, dtype=np.float64)
    if cabin.shape != (3,) or not np.all(np.isfinite(cabin)):
        raise ValueError(f"cabin_point_m must be 3 finite numbers (body frame, m), got {cabin_point_m}")
    sigma_w = turbulence_sigma_mps(intensity, altitude_m)
    t = time_grid(duration_s, dt_s)
    n = len(t)
    model = MID_SIZE_TRANSPORT
    v = float(airspeed_mps)
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
