"""Ship deck at sea: a deck point of a ~100 m ship, hove to in a long-crested JONSWAP sea.

Why: the deck of a ship is the moving floor a legged robot is most often asked to stand on. The
sea is a JONSWAP spectrum (DNV-RP-C205 form, peak enhancement by DNV's rule: :func:`dnv_gamma`)
synthesised from 1,000 random-phase cosines on jittered frequencies; each cosine drives heave,
roll and pitch through the Froude-Krylov static response of a box waterplane and a second-order
mode per degree of freedom; :func:`~lasmp.motions.motion.deck_pose` carries the CG's motion to a
deck point 20 m forward, 5 m to port, 3 m up. Ship frame: x to the bow, y to port, z up; a
positive pitch puts the bow down. The sea states are WMO codes 3-6. Nothing is scaled or clipped;
``notes`` says where the motion leaves the training ranges. The derivation, the ship's periods
and damping and every source: docs/real_motion.md, "Ship".
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.signal import freqs
from scipy.special import spherical_jn

from lasmp.motions.motion import (
    DEFAULT_DT_S,
    DEFAULT_DURATION_S,
    GRAVITY_M_S2,
    TRAINING_RANGES,
    Motion,
    choice,
    deck_pose,
    finite,
    point,
    positive,
    time_grid,
)
from lasmp.motions.noise import second_order_tf, sum_of_cosines

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

# the training trajectories' workspace (notes): horizontal half-range, vertical range, tilt
WORKSPACE_HORIZONTAL_M = TRAINING_RANGES.high[0]
WORKSPACE_VERTICAL_RANGE_M = TRAINING_RANGES.high[2] - TRAINING_RANGES.low[2]
WORKSPACE_TILT_RAD = TRAINING_RANGES.high[3]


def dnv_gamma(hs_m: float, tp_s: float) -> float:
    """The JONSWAP peak enhancement DNV-RP-C205 (2010) 3.5.5.5 recommends where none is measured.

    With ``r = Tp / sqrt(Hs)`` (s / sqrt(m)): 5 for ``r <= 3.6`` (a steep, young sea),
    ``exp(5.75 - 1.15 r)`` between, and 1 (Pierson-Moskowitz, a fully developed sea) for ``r >= 5``.
    """
    r = positive("dnv_gamma", "tp_s", tp_s) / math.sqrt(positive("dnv_gamma", "hs_m", hs_m))
    if r <= 3.6:
        return 5.0
    if r >= 5.0:
        return 1.0
    return math.exp(5.75 - 1.15 * r)


@dataclass(frozen=True)
class ShipModel:
    """Waterplane size and per-DoF second-order dynamics of the ship (values: docs/real_motion.md)."""

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
            positive("ShipModel", name, value)


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
        return sum_of_cosines(t_s, self.omega_rad_s, self.amplitude_m * np.exp(1j * self.phase_rad))


def _check_gamma(where: str, gamma: float | None, hs_m: float, tp_s: float) -> float:
    """`gamma`, or DNV's rule for (Hs, Tp) when it is None; ValueError unless >= 1."""
    if gamma is None:
        return dnv_gamma(hs_m, tp_s)
    g = positive(where, "gamma", gamma)
    if g < 1.0:  # gamma < 1 would flatten the peak below Pierson-Moskowitz: not a JONSWAP sea
        raise ValueError(f"{where}: gamma (peak enhancement) must be >= 1, got {gamma!r}")
    return g


def jonswap_spectrum(omega_rad_s, hs_m: float, tp_s: float, gamma: float | None = None) -> np.ndarray:
    """JONSWAP wave spectrum S(omega), m^2 s/rad, one-sided (DNV-RP-C205 (2010) 3.5.5).

    ``gamma`` None: :func:`dnv_gamma` of (Hs, Tp). The normalisation ``1 - 0.287 ln(gamma)`` keeps
    ``4 sqrt(m0)`` within about 1 % of Hs for 1 <= gamma <= 7.
    """
    hs = positive("jonswap_spectrum", "hs_m", hs_m)
    tp = positive("jonswap_spectrum", "tp_s", tp_s)
    g = _check_gamma("jonswap_spectrum", gamma, hs, tp)
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
    gamma: float | None = None,
    seed: int = 0,
    n_components: int = N_COMPONENTS,
) -> WaveComponents:
    """The random-phase cosines of a JONSWAP sea: ``n_components`` frequencies, one drawn uniformly
    inside each equal bin of the band (so the record never repeats), phases uniform."""
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


def wave_elevation(
    t_s,
    hs_m: float,
    tp_s: float,
    gamma: float | None = None,
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
    _, h = freqs(*second_order_tf(wn, zeta, base_excited=False), worN=w.reshape(-1))
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

    Per component: the static response of the box waterplane to the wave times the DoF's
    second-order transfer function (docs/real_motion.md, "Ship"). No ramp-in.
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
    return sum_of_cosines(t_s, w, amp)


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
    gamma: float | None = None,
    heading_deg: float = HEADING_DEG,
    deck_offset_m=DECK_OFFSET_M,
    ship: ShipModel = MID_SIZE_SHIP,
    duration_s: float = DEFAULT_DURATION_S,
    dt_s: float = DEFAULT_DT_S,
    ramp_s: float = RAMP_S,
    n_components: int = N_COMPONENTS,
    seed: int = 0,
) -> Motion:
    """A deck point of a ship in a random JONSWAP sea (model, parameters and sources: docs/real_motion.md).

    ``sea_state`` picks (Hs, Tp) from :data:`SEA_STATES`; ``hs_m`` / ``tp_s`` override either;
    ``gamma`` None takes DNV's peak enhancement for them (:func:`dnv_gamma`).
    ``heading_deg``: wave travel direction from the bow (180 head, 90 beam seas). ``deck_offset_m``:
    the platform's point in the ship frame (forward, port, up), m. ``seed`` draws the sea. Raises
    ValueError naming the bad parameter.
    """
    where = "ship_deck"
    preset_hs, preset_tp = SEA_STATES[choice(where, "sea_state", sea_state, SEA_STATES)]
    hs = positive(where, "hs_m", preset_hs if hs_m is None else hs_m)
    tp = positive(where, "tp_s", preset_tp if tp_s is None else tp_s)
    g = _check_gamma(where, gamma, hs, tp)
    duration = positive(where, "duration_s", duration_s)
    dt = positive(where, "dt_s", dt_s)
    ramp = positive(where, "ramp_s", ramp_s)
    heading = finite(where, "heading_deg", heading_deg)
    offset = point(where, "deck_offset_m", deck_offset_m, "forward, port, up")
    omega_max = BAND_OVER_PEAK[1] * 2.0 * np.pi / tp
    if dt >= np.pi / omega_max:  # the samples must resolve the sea's highest component
        raise ValueError(
            f"{where}: dt_s = {dt} s does not resolve the sea (Tp {tp} s, components up to "
            f"{omega_max:.2f} rad/s): use dt_s < {np.pi / omega_max:.3f}"
        )

    t = time_grid(duration, dt)
    comp = wave_components(hs, tp, g, seed, n_components)
    cg = ship_response(t, comp, heading, ship) * half_cosine_ramp(t, ramp)[:, None]
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
        "heading_deg": heading,
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
        f"Hs {hs:g} m, Tp {tp:g} s, gamma {g:g}, waves travelling at {heading:g} deg "
        "from the bow; "
        f"real scale, not scaled or clipped, {ramp:g} s half-cosine ramp-in; "
        "horizontal motion is the lever arm of roll/pitch only (surge, sway, yaw not modelled). "
        + _workspace_notes(pose)
    )
    return Motion(name=f"ship_{sea_state}", t_s=t, pose=pose, params=params, notes=notes)
