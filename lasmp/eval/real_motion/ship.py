"""Ship deck at sea: a deck point of a mid-size ship in a long-crested JONSWAP sea.

Frames and signs
    Ship body frame at the centre of gravity (CG): x forward (bow), y to port, z up, the pose
    convention of :mod:`lasmp.eval.real_motion.motion` (``R = Rz(yaw) Ry(pitch) Rx(roll)``), so a
    positive pitch puts the bow *down* and a positive roll lifts the port side. The wave heading
    ``mu`` (``heading_deg``) is the angle from the bow to the direction the waves *travel*:
    180 deg head seas, 0 deg following seas, 90 deg beam seas travelling from starboard to port.
    The ship has no forward speed (hove to / station keeping), so the encounter frequency is the
    wave frequency.

1. Wave spectrum: JONSWAP in the form of DNV-RP-C205 "Environmental conditions and environmental
   loads" (Det Norske Veritas, 2010), section 3.5.5, after Hasselmann et al. (1973), "Measurements
   of wind-wave growth and swell decay during the Joint North Sea Wave Project (JONSWAP)", Dtsch.
   Hydrogr. Z., Erg.-H. A 8(12)::

       S(w)    = A_g * S_PM(w) * g ** exp(-(w - wp)^2 / (2 s^2 wp^2))
       S_PM(w) = 5/16 * Hs^2 * wp^4 * w^-5 * exp(-5/4 * (w / wp)^-4)     (Pierson-Moskowitz)
       A_g     = 1 - 0.287 ln(g)                                          (normalising factor)
       s       = 0.07 for w <= wp, 0.09 for w > wp;   wp = 2 pi / Tp

   in m^2 s/rad, one-sided. ``A_g`` makes 4 sqrt(m0) = Hs (m0 the spectrum's area) to within about
   1 % for 1 <= gamma <= 7 (checked in the tests). ``gamma`` = 3.3 is the JONSWAP mean value;
   DNV-RP-C205 3.5.5 recommends gamma = 1 (Pierson-Moskowitz) for these presets, where
   Tp / sqrt(Hs) > 5 (fully developed seas): pass ``gamma=1.0`` for that reading.

2. Sea elevation at the CG (random-phase method): ``eta(t) = sum_i a_i cos(w_i t + phi_i)`` with
   ``a_i = sqrt(2 S(w_i) dw)``, ``N_COMPONENTS`` = 1000 components on the band
   [0.4, 5.0] wp (it holds all but ~0.2 % of m0), the band cut into N equal bins of width dw and
   ``w_i`` drawn uniformly *inside* bin i. An equally spaced grid would make the record repeat
   after 2 pi / dw (about 25-35 min here); the jittered frequencies have no common period.
   ``phi_i`` ~ U[0, 2 pi). Both from ``np.random.default_rng(seed)``. (Deterministic amplitudes
   with random phases: Tucker, Challenor and Carter (1984), "Numerical simulation of a random sea:
   a common error and its effect upon wave group statistics", Applied Ocean Research 6(2), show
   that this slightly understates wave-group variability; it is exact in the variance.)

3. Wave excitation (Froude-Krylov hydrostatics of a wall-sided box waterplane L x B): for a
   component of wave number ``k = w^2 / g`` (deep water) the quasi-static equilibrium of the
   hull is the least-squares plane through the wave surface over the waterplane, which gives
   the static (w -> 0 dynamics) response per metre of wave amplitude, with
   ``u = k cos(mu) L / 2``, ``v = k sin(mu) B / 2``, ``sinc(u) = sin(u) / u`` and
   ``f(u) = 3 (sin u - u cos u) / u^3 = 3 j1(u) / u`` (j1 the spherical Bessel function)::

       heave_static = sinc(u) sinc(v)                    (mean elevation over the waterplane)
       pitch_static = +i k cos(mu) sinc(v) f(u)          (minus the fitted slope along x)
       roll_static  = -i k sin(mu) sinc(u) f(v)          (the fitted slope along y)

   For long waves (k L -> 0) these are the elevation and the wave slopes at the CG (head seas
   pitch, beam seas roll); waves shorter than the ship average out (sinc, f -> 0). Neglected:
   diffraction, the pressure decay with draft (Smith effect), heave-pitch coupling, nonlinear
   roll damping. Journee and Massie (2001), "Offshore Hydromechanics", TU Delft, and Fossen
   (2011), "Handbook of Marine Craft Hydrodynamics and Motion Control", Wiley, treat these
   Froude-Krylov loads and the linear seakeeping model of step 4.

4. Ship dynamics: heave, roll and pitch each a linear second-order system driven through its
   static response, ``x'' + 2 zeta wn x' + wn^2 x = wn^2 x_static(t)``, i.e. per component the
   transfer function ``H(w) = wn^2 / (wn^2 - w^2 + 2 i zeta wn w)`` (:func:`second_order_gain`):
   exact steady state, no ODE integration. Surge, sway and yaw of the CG are left at zero
   (not modelled): the deck point's horizontal motion is the lever arm of roll and pitch only.

   :data:`MID_SIZE_SHIP`, a ~100 m vessel (offshore supply ship / frigate size), length L = 100 m,
   beam B = 16 m (draft d = 6 m, block coefficient C_B = 0.6, waterplane coefficient C_WP = 0.75
   for the estimates below):

   * heave period 6.5 s: ``2 pi sqrt((m + a33) / (rho g A_WP))`` with added mass a33 ~ m gives
     ``2 pi sqrt(2 C_B d / (C_WP g))`` = 6.2 s;
   * pitch period 6.0 s: the same form with radius of gyration 0.25 L, added inertia ~ the
     inertia and a waterplane inertia 0.65 B L^3 / 12 gives 5.8 s;
   * roll period 12.0 s: IMO Intact Stability Code 2008 (resolution MSC.267(85)), Part A 2.3.4,
     ``T = 2 C B / sqrt(GM)``, ``C = 0.373 + 0.023 B/d - 0.043 L/100``, with GM = 1.1 m: 11.9 s;
   * damping ratios: heave and pitch 0.30 (strongly damped by wave radiation), roll 0.08 (lightly
     damped, little radiation damping: resonance gain 1 / (2 zeta) = 6.25); see Journee and
     Massie (2001) and Fossen (2011) on the damping of the ship motions.

5. Deck point: ``deck_offset_m`` (ship frame, default 20 m forward, 5 m to port, 3 m up) is
   moved rigidly with the CG by :func:`lasmp.eval.real_motion.motion.deck_pose`, so roll and
   pitch add lever-arm heave (20 m x 0.05 rad = 1 m) and horizontal motion (3 m x roll).

6. Ramp-in: the CG motion is multiplied by a half-cosine ramp ``r(t) = (1 - cos(pi t / T_r)) / 2``
   over ``ramp_s`` (2 s) so the motion starts at the zero pose with zero velocity (r(0) = r'(0)
   = 0); the sea itself is not ramped, only the response.

Sea states (:data:`SEA_STATES`): the World Meteorological Organization sea state code (WMO
Manual on Codes, WMO-No. 306, code table 3700: 3 "slight" Hs 0.5-1.25 m, 4 "moderate"
1.25-2.5 m, 5 "rough" 2.5-4 m, 6 "very rough" 4-6 m) with the mean Hs and the most probable modal (peak) period of each
code in the open North Atlantic, from Bales, Lee and Voelker (1981), "Standardized wave and wind
environments for NATO operational areas", DTNSRDC/SPD-0919-01.

Fitting to the platform world: nothing is scaled or clipped. The training workspace is
+-1 m horizontally, a 5 m vertical range and |roll|, |pitch| <= 0.7 rad; ``notes`` states the
motion's extremes and every limit it exceeds. Smaller motion comes only from the documented
parameters (``hs_m``, ``heading_deg``, ``deck_offset_m``).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.signal import freqs
from scipy.special import spherical_jn

from lasmp.eval.real_motion.motion import (
    DEFAULT_DT_S,
    DEFAULT_DURATION_S,
    Motion,
    deck_pose,
    positive,
    time_grid,
)

GRAVITY_M_S2 = 9.81
JONSWAP_GAMMA = 3.3  # mean peak enhancement of the JONSWAP measurements (Hasselmann et al. 1973)
N_COMPONENTS = 1000  # cosines in the sea; with jittered frequencies the record has no period
BAND_OVER_PEAK = (0.4, 5.0)  # synthesis band in units of the peak frequency: < 0.2 % of m0 outside
RAMP_S = 2.0  # half-cosine ramp-in of the response, s
DECK_OFFSET_M = (20.0, 5.0, 3.0)  # robot's deck patch from the CG: forward, to port, up (ship frame), m
HEADING_DEG = 150.0  # bow-quartering seas: both pitch (cos) and roll (sin) are excited

# name: (significant wave height Hs m, peak period Tp s): WMO code 3700 mean Hs of the band and the
# most probable modal period in the open North Atlantic (Bales, Lee and Voelker 1981)
SEA_STATES: dict[str, tuple[float, float]] = {
    "sea_state_3": (0.88, 7.5),  # slight, Hs 0.5-1.25 m
    "sea_state_4": (1.88, 8.8),  # moderate, Hs 1.25-2.5 m
    "sea_state_5": (3.25, 9.7),  # rough, Hs 2.5-4 m
    "sea_state_6": (5.0, 12.4),  # very rough, Hs 4-6 m
}

# the platform world's training workspace (see notes): horizontal half-range, vertical range, tilt
WORKSPACE_HORIZONTAL_M = 1.0
WORKSPACE_VERTICAL_RANGE_M = 5.0
WORKSPACE_TILT_RAD = 0.7


@dataclass(frozen=True)
class ShipModel:
    """Waterplane size and per-DoF second-order dynamics of the ship (see the module docstring)."""

    length_m: float = 100.0
    beam_m: float = 16.0
    heave_period_s: float = 6.5
    pitch_period_s: float = 6.0
    roll_period_s: float = 12.0
    heave_damping_ratio: float = 0.30
    pitch_damping_ratio: float = 0.30
    roll_damping_ratio: float = 0.08

    def __post_init__(self):
        for name, value in asdict(self).items():
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"ShipModel: {name} must be a positive finite number, got {value!r}")


MID_SIZE_SHIP = ShipModel()


@dataclass(frozen=True)
class WaveComponents:
    """A long-crested sea as a sum of cosines: eta(t) = sum amplitude_m cos(omega_rad_s t + phase_rad)."""

    omega_rad_s: np.ndarray
    amplitude_m: np.ndarray
    phase_rad: np.ndarray
    d_omega_rad_s: float  # width of the frequency bins, rad/s

    def elevation(self, t_s) -> np.ndarray:
        """eta(t), m, at times t_s (K,)."""
        t = np.asarray(t_s, dtype=np.float64).reshape(-1)
        a = (self.amplitude_m * np.exp(1j * self.phase_rad))[:, None]
        return _sum_of_cosines(t, self.omega_rad_s, a)[:, 0]


def _check_gamma(where: str, gamma: float) -> float:
    g = positive(where, "gamma", gamma)
    if g < 1.0:  # gamma < 1 would flatten the peak below Pierson-Moskowitz: not a JONSWAP sea
        raise ValueError(f"{where}: gamma (peak enhancement) must be >= 1, got {gamma!r}")
    return g


def jonswap_spectrum(omega_rad_s, hs_m: float, tp_s: float, gamma: float = JONSWAP_GAMMA) -> np.ndarray:
    """JONSWAP wave spectrum S(omega), m^2 s/rad, one-sided (DNV-RP-C205 (2010) 3.5.5; see module doc)."""
    hs = positive("jonswap_spectrum", "hs_m", hs_m)
    tp = positive("jonswap_spectrum", "tp_s", tp_s)
    g = _check_gamma("jonswap_spectrum", gamma)
    w = np.asarray(omega_rad_s, dtype=np.float64)
    wp = 2.0 * np.pi / tp
    out = np.zeros_like(w)
    pos = w > 0  # S(0) = 0: the exponential kills the w^-5 pole
    wn = w[pos] / wp
    s_pm = 5.0 / 16.0 * hs**2 / wp * wn**-5 * np.exp(-1.25 * wn**-4)
    sigma = np.where(wn <= 1.0, 0.07, 0.09)
    peak = g ** np.exp(-0.5 * ((wn - 1.0) / sigma) ** 2)
    out[pos] = (1.0 - 0.287 * np.log(g)) * s_pm * peak
    return out


def wave_components(
    hs_m: float,
    tp_s: float,
    gamma: float = JONSWAP_GAMMA,
    seed: int = 0,
    n_components: int = N_COMPONENTS,
) -> WaveComponents:
    """The random-phase cosines of a JONSWAP sea (jittered frequency grid; see module docstring)."""
    hs = positive("wave_components", "hs_m", hs_m)
    tp = positive("wave_components", "tp_s", tp_s)
    if int(n_components) != n_components or n_components < 1:
        raise ValueError(f"wave_components: n_components must be a positive integer, got {n_components!r}")
    n = int(n_components)
    rng = np.random.default_rng(seed)
    wp = 2.0 * np.pi / tp
    w_lo, w_hi = BAND_OVER_PEAK[0] * wp, BAND_OVER_PEAK[1] * wp
    dw = (w_hi - w_lo) / n
    omega = w_lo + (np.arange(n) + rng.uniform(size=n)) * dw
    phase = rng.uniform(0.0, 2.0 * np.pi, size=n)
    amp = np.sqrt(2.0 * jonswap_spectrum(omega, hs, tp, gamma) * dw)
    return WaveComponents(omega_rad_s=omega, amplitude_m=amp, phase_rad=phase, d_omega_rad_s=float(dw))


def _sum_of_cosines(t_s: np.ndarray, omega_rad_s: np.ndarray, complex_amp: np.ndarray) -> np.ndarray:
    """Re(sum_i A_i exp(i w_i t)) for complex amplitudes A (N, D): (K, D), in time chunks (memory)."""
    out = np.empty((len(t_s), complex_amp.shape[1]))
    chunk = max(1, 2_000_000 // max(1, len(omega_rad_s)))  # ~32 MB of complex exponentials at a time
    for i in range(0, len(t_s), chunk):
        phasor = np.exp(1j * np.outer(t_s[i : i + chunk], omega_rad_s))
        out[i : i + chunk] = (phasor @ complex_amp).real
    return out


def wave_elevation(
    t_s,
    hs_m: float,
    tp_s: float,
    gamma: float = JONSWAP_GAMMA,
    seed: int = 0,
    n_components: int = N_COMPONENTS,
) -> np.ndarray:
    """Sea surface elevation at the ship's CG, m, at times t_s (K,): the sea :func:`ship_deck` uses."""
    return wave_components(hs_m, tp_s, gamma, seed, n_components).elevation(t_s)


def second_order_gain(omega_rad_s, natural_omega_rad_s: float, damping_ratio: float) -> np.ndarray:
    """H(w) = wn^2 / (wn^2 - w^2 + 2 i zeta wn w): unit static gain, 1 / (2 zeta) at resonance (complex)."""
    wn = positive("second_order_gain", "natural_omega_rad_s", natural_omega_rad_s)
    zeta = positive("second_order_gain", "damping_ratio", damping_ratio)
    w = np.asarray(omega_rad_s, dtype=np.float64)
    _, h = freqs([wn**2], [1.0, 2.0 * zeta * wn, wn**2], worN=w.reshape(-1))
    return h.reshape(w.shape)


def _spherical_fit(x: np.ndarray) -> np.ndarray:
    """f(x) = 3 j1(x) / x: the least-squares slope of cos(kx) over a length, relative to the point slope."""
    ax = np.abs(x)
    small = ax < 1e-6
    safe = np.where(small, 1.0, ax)
    return np.where(small, 1.0 - ax**2 / 10.0, 3.0 * spherical_jn(1, safe) / safe)


def ship_response(
    t_s, components: WaveComponents, heading_deg: float, ship: ShipModel = MID_SIZE_SHIP
) -> np.ndarray:
    """Steady-state [heave_m, roll_rad, pitch_rad] (K, 3) of the CG in the sea ``components``.

    Per component: static response of the box waterplane to the wave (step 3 of the module
    docstring) times the DoF's second-order transfer function (step 4). No ramp-in.
    """
    mu = math.radians(float(heading_deg))
    w = np.asarray(components.omega_rad_s, dtype=np.float64)
    k = w**2 / GRAVITY_M_S2  # deep-water dispersion
    kx, ky = k * math.cos(mu), k * math.sin(mu)
    u, v = kx * ship.length_m / 2.0, ky * ship.beam_m / 2.0
    sinc_u, sinc_v = np.sinc(u / np.pi), np.sinc(v / np.pi)  # numpy's sinc is sin(pi x) / (pi x)
    heave_static = sinc_u * sinc_v + 0j
    pitch_static = 1j * kx * sinc_v * _spherical_fit(u)  # bow down = minus the slope along x
    roll_static = -1j * ky * sinc_u * _spherical_fit(v)  # port up = the slope along y

    def gain(period_s: float, zeta: float) -> np.ndarray:
        return second_order_gain(w, 2.0 * np.pi / period_s, zeta)

    wave = components.amplitude_m * np.exp(1j * components.phase_rad)
    amp = np.stack(
        [
            wave * heave_static * gain(ship.heave_period_s, ship.heave_damping_ratio),
            wave * roll_static * gain(ship.roll_period_s, ship.roll_damping_ratio),
            wave * pitch_static * gain(ship.pitch_period_s, ship.pitch_damping_ratio),
        ],
        axis=1,
    )
    return _sum_of_cosines(np.asarray(t_s, dtype=np.float64).reshape(-1), w, amp)


def half_cosine_ramp(t_s, ramp_s: float) -> np.ndarray:
    """0 at t = 0 rising smoothly to 1 at t = ramp_s (zero slope at both ends), 1 after."""
    t = np.clip(np.asarray(t_s, dtype=np.float64) / ramp_s, 0.0, 1.0)
    return 0.5 * (1.0 - np.cos(np.pi * t))


def _workspace_notes(pose: np.ndarray) -> str:
    """The motion's extremes against the platform's training workspace, and what exceeds it."""
    horiz = float(np.max(np.abs(pose[:, :2])))
    z_range = float(np.ptp(pose[:, 2]))
    tilt = float(np.max(np.abs(pose[:, 3:5])))
    over = []
    if horiz > WORKSPACE_HORIZONTAL_M:
        over.append(f"horizontal |x|,|y| up to {horiz:.2f} m > {WORKSPACE_HORIZONTAL_M} m")
    if z_range > WORKSPACE_VERTICAL_RANGE_M:
        over.append(f"vertical range {z_range:.2f} m > {WORKSPACE_VERTICAL_RANGE_M} m")
    if tilt > WORKSPACE_TILT_RAD:
        over.append(f"|roll|,|pitch| up to {tilt:.3f} rad > {WORKSPACE_TILT_RAD} rad")
    extremes = f"max |x|,|y| {horiz:.2f} m, z range {z_range:.2f} m, max |roll|,|pitch| {tilt:.3f} rad"
    verdict = (
        "EXCEEDS the training workspace: " + "; ".join(over) if over else "within the training workspace"
    )
    limits = f"+-{WORKSPACE_HORIZONTAL_M} m, {WORKSPACE_VERTICAL_RANGE_M} m, {WORKSPACE_TILT_RAD} rad"
    return f"{extremes}: {verdict} ({limits})"


def ship_deck(
    sea_state: str = "sea_state_4",
    *,
    hs_m: float | None = None,
    tp_s: float | None = None,
    gamma: float = JONSWAP_GAMMA,
    heading_deg: float = HEADING_DEG,
    deck_offset_m=DECK_OFFSET_M,
    ship: ShipModel = MID_SIZE_SHIP,
    duration_s: float = DEFAULT_DURATION_S,
    dt_s: float = DEFAULT_DT_S,
    ramp_s: float = RAMP_S,
    n_components: int = N_COMPONENTS,
    seed: int = 0,
) -> Motion:
    """A deck point of a ship in a random JONSWAP sea (model, parameters and sources: module docstring).

    ``sea_state`` picks (Hs, Tp) from :data:`SEA_STATES`; ``hs_m`` / ``tp_s`` override either.
    ``heading_deg``: wave travel direction from the bow (180 head, 90 beam seas). ``deck_offset_m``:
    the platform's point in the ship frame (forward, port, up), m. ``seed`` draws the sea. Raises
    ValueError naming the bad parameter.
    """
    where = "ship_deck"
    if sea_state not in SEA_STATES:
        raise ValueError(
            f"{where}: unknown sea_state {sea_state!r}; valid: {sorted(SEA_STATES)} "
            "(hs_m and tp_s override a preset's values)"
        )
    preset_hs, preset_tp = SEA_STATES[sea_state]
    hs = positive(where, "hs_m", preset_hs if hs_m is None else hs_m)
    tp = positive(where, "tp_s", preset_tp if tp_s is None else tp_s)
    g = _check_gamma(where, gamma)
    duration = positive(where, "duration_s", duration_s)
    dt = positive(where, "dt_s", dt_s)
    ramp = positive(where, "ramp_s", ramp_s)
    if not math.isfinite(float(heading_deg)):
        raise ValueError(f"{where}: heading_deg must be finite, got {heading_deg!r}")
    offset = np.asarray(deck_offset_m, dtype=np.float64)
    if offset.shape != (3,) or not np.all(np.isfinite(offset)):
        raise ValueError(
            f"{where}: deck_offset_m must be 3 finite numbers (forward, port, up) m, got {deck_offset_m!r}"
        )
    omega_max = BAND_OVER_PEAK[1] * 2.0 * np.pi / tp
    if dt >= np.pi / omega_max:  # the samples must resolve the sea's highest component
        raise ValueError(
            f"{where}: dt_s = {dt} s does not resolve the sea (Tp {tp} s, components up to "
            f"{omega_max:.2f} rad/s): use dt_s < {np.pi / omega_max:.3f}"
        )

    t = time_grid(duration, dt)
    comp = wave_components(hs, tp, g, seed, n_components)
    cg = ship_response(t, comp, heading_deg, ship) * half_cosine_ramp(t, ramp)[:, None]
    p_cg = np.zeros((len(t), 3))
    p_cg[:, 2] = cg[:, 0]
    euler = np.zeros((len(t), 3))
    euler[:, 0], euler[:, 1] = cg[:, 1], cg[:, 2]
    pose = deck_pose(p_cg, euler, offset)

    params = {
        "sea_state": sea_state,
        "hs_m": hs,
        "tp_s": tp,
        "gamma": g,
        "heading_deg": float(heading_deg),
        "deck_offset_m": offset.tolist(),
        "ship": asdict(ship),
        "duration_s": duration,
        "dt_s": dt,
        "ramp_s": ramp,
        "n_components": int(n_components),
        "band_over_peak": list(BAND_OVER_PEAK),
        "seed": int(seed),
        "model": "JONSWAP (DNV-RP-C205) long-crested sea; box-waterplane Froude-Krylov excitation; "
        "2nd-order heave/roll/pitch; surge/sway/yaw zero",
    }
    notes = (
        f"Deck point {offset.tolist()} m (fwd, port, up) of a {ship.length_m:g} m ship hove to in "
        f"Hs {hs:g} m, Tp {tp:g} s, gamma {g:g}, waves travelling at {float(heading_deg):g} deg "
        "from the bow; "
        f"real scale, not scaled or clipped, {ramp:g} s half-cosine ramp-in; "
        "horizontal motion is the lever arm of roll/pitch only (surge, sway, yaw not modelled). "
        + _workspace_notes(pose)
    )
    return Motion(name=f"ship_{sea_state}", t_s=t, pose=pose, params=params, notes=notes)
