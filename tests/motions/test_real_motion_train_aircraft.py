"""Train (curve, track vibration) and aircraft (Dryden turbulence) real-motion generators, noise tools.

The expected values are computed here from the published formulas (MIL-F-8785C Dryden spectra,
EN 13803 cant relations, FRA track spectra) and the inputs, not read back from the generators.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate, signal
from scipy.spatial.transform import Rotation

from lasmp.envs import trajectories as trj
from lasmp.motions.aircraft import aircraft, dryden_roll_tf, dryden_vertical_tf
from lasmp.motions.motion import derivatives, to_trajectories
from lasmp.motions.noise import filtered_white_noise, random_phase_noise
from lasmp.motions.rail import track_psd_m2_per_rad_m, train

G = 9.81
E_RAIL_M = 1.5  # EN 13803 rail-centre distance for 1435 mm gauge


def dryden_w_psd(omega, sigma, scale_m, v):
    """MIL-F-8785C Dryden vertical-gust PSD, one-sided per rad/s."""
    r = (scale_m * omega / v) ** 2
    return sigma**2 * scale_m / (np.pi * v) * (1 + 3 * r) / (1 + r) ** 2


def dryden_p_psd(omega, sigma, scale_m, v, span_m):
    """MIL-F-8785C Dryden roll-gust PSD, one-sided per rad/s."""
    return (
        sigma**2
        / (v * scale_m)
        * 0.8
        * (np.pi * scale_m / (4 * span_m)) ** (1 / 3)
        / (1 + (4 * span_m * omega / (np.pi * v)) ** 2)
    )


def body_specific_force(m):
    """Specific force (acceleration minus gravity) in the platform's body frame, (K, 3)."""
    _, acc = derivatives(m)
    rot = Rotation.from_euler("ZYX", m.pose[:, [5, 4, 3]])
    return rot.inv().apply(acc[:, :3] + np.array([0.0, 0.0, G]))


# ---------------------------------------------------------------------------------------------
# noise tools and the Dryden forming filters
# ---------------------------------------------------------------------------------------------
def test_dryden_vertical_filter_matches_sigma_and_the_dryden_psd():
    sigma, scale_m, v, dt = 2.0, 533.4, 130.0, 0.02
    n = 1_000_000  # 20,000 s = 4,900 correlation lengths L / V
    w = filtered_white_noise(*dryden_vertical_tf(sigma, scale_m, v), n, dt, seed=3, warmup_s=50.0)
    assert abs(np.std(w) / sigma - 1.0) < 0.10
    # Welch: ~490 half-overlapping Hann segments -> ~5 % standard error per bin; each band below
    # averages >= 4 bins (<= 3 %); zero-order-hold and aliasing bias below 3 Hz at a 25 Hz Nyquist
    # is < 2 %. 15 % is more than 4 standard errors, and a wrong gain, scale length or
    # numerator (e.g. a first-order Dryden-u shape) misses by far more at one of these bands.
    f, g = signal.welch(w, fs=1.0 / dt, nperseg=4096)
    for fc in (0.1, 0.3, 1.0, 3.0):
        band = (f >= fc / 1.25) & (f <= fc * 1.25)
        expected = 2 * np.pi * dryden_w_psd(2 * np.pi * f[band], sigma, scale_m, v)  # per Hz
        assert abs(np.mean(g[band]) / np.mean(expected) - 1.0) < 0.15, fc


def test_dryden_roll_filter_variance_matches_the_roll_gust_spectrum():
    sigma, scale_m, v, span, dt = 3.0, 533.4, 130.0, 34.1, 0.02
    p = filtered_white_noise(*dryden_roll_tf(sigma, scale_m, v, span), 500_000, dt, seed=4)
    expected = integrate.quad(lambda om: dryden_p_psd(om, sigma, scale_m, v, span), 0, np.inf)[0]
    assert abs(np.var(p) / expected - 1.0) < 0.05  # p_g correlates over 4 b / (pi V) = 0.33 s


def test_random_phase_noise_has_the_band_limited_variance_and_shape():
    dt, n = 0.01, 60_000

    def psd(f):
        return 1e-3 / f**2

    x = random_phase_noise(psd, n, dt, f_min_hz=0.5, f_max_hz=5.0, seed=1)
    # deterministic amplitudes over one period: the variance is the Riemann sum of the PSD
    assert np.var(x) == pytest.approx(integrate.quad(psd, 0.5, 5.0)[0], rel=0.01)
    f, g = signal.welch(x, fs=1 / dt, nperseg=4096)
    inside = (f > 0.7) & (f < 4.5)
    assert np.allclose(g[inside] / psd(f[inside]), 1.0, atol=0.35)  # shape, per bin
    assert np.mean(g[(f > 6.0) & (f < 40.0)]) < 1e-3 * np.mean(g[inside])  # nothing outside the band


# ---------------------------------------------------------------------------------------------
# aircraft
# ---------------------------------------------------------------------------------------------
def test_aircraft_vertical_acceleration_and_roll_match_the_gust_response():
    m = aircraft("moderate", duration_s=2000.0, dt_s=0.02, seed=5, cabin_point_m=(0.0, 0.0, 0.0))
    p = m.params
    sigma, scale_m, v = p["sigma_w_mps"], p["scale_length_m"], p["airspeed_mps"]
    assert sigma == pytest.approx(9.44 * 0.3048, rel=0.01)  # MIL-F-8785C fig. 7, 1e-3 at 9843 ft
    # gust load factor: K = rho V C_La / (2 m / S), ISA rho(3000 m) = 0.9093
    k = 0.9093 * 130.0 * 5.0 / (2 * 600.0)
    assert p["gust_rate_per_s"] == pytest.approx(k, rel=0.002)
    tau_u = 3 * 2.1 / 130.0

    def h2_az(om):
        s = 1j * om
        return np.abs(k * s / ((s + k) * (tau_u * s + 1))) ** 2

    def h2_roll(om):
        s = 1j * om
        return np.abs(1.0 / (s**2 + s + 0.25)) ** 2  # tau_r = 1 s, omega_a = 0.5 rad/s

    rms_az = np.sqrt(
        integrate.quad(lambda om: h2_az(om) * dryden_w_psd(om, sigma, scale_m, v), 0, np.inf, limit=400)[0]
    )
    rms_roll = np.sqrt(
        integrate.quad(
            lambda om: h2_roll(om) * dryden_p_psd(om, sigma, scale_m, v, 34.1), 0, np.inf, limit=400
        )[0]
    )
    _, acc = derivatives(m)
    steady = (m.t_s > 10.0) & (m.t_s < m.t_s[-1] - 1.0)
    # ~1000 correlation times of a_z (~2 s) -> ~3 % standard error on the RMS; roll (~4 s) ~4 %
    assert np.sqrt(np.mean(acc[steady, 2] ** 2)) == pytest.approx(rms_az, rel=0.12)
    assert np.sqrt(np.mean(m.pose[steady, 3] ** 2)) == pytest.approx(rms_roll, rel=0.15)
    # coordinated turn: the banked lift turns the aircraft, so the world sees a lateral
    # acceleration but the robot hardly any sideways pull (what is left is the gust lift
    # increment applied vertically, a_z sin(phi): second order)
    f_body = body_specific_force(m)[steady]
    assert np.sqrt(np.mean(f_body[:, 1] ** 2)) < 0.15 * np.sqrt(np.mean(acc[steady, 1] ** 2))
    assert np.all(m.pose[:, 4] == 0.0)


def test_moderate_turbulence_gives_larger_vertical_acceleration_than_light():
    rms = {}
    for intensity in ("light", "moderate", "severe"):
        _, acc = derivatives(aircraft(intensity, seed=2))
        rms[intensity] = np.sqrt(np.mean(acc[:, 2] ** 2))
    assert rms["light"] < rms["moderate"] < rms["severe"]
    # same seed, linear model: the ratio is the MIL-F-8785C sigma ratio at 9843 ft (9.44 / 6.04 ft/s)
    assert rms["moderate"] / rms["light"] == pytest.approx(9.44 / 6.04, rel=0.02)
    assert 0.2 < rms["light"] < 2.0  # m/s^2: light turbulence is felt but is not a 1 g event


# ---------------------------------------------------------------------------------------------
# train
# ---------------------------------------------------------------------------------------------
def test_train_arc_lateral_acceleration_and_roll_follow_the_cant():
    v, radius, cant_mm = 40.0, 1200.0, 120.0
    m = train("curve", speed_mps=v, radius_m=radius, cant_mm=cant_mm, transition_m=100.0, vibration=False)
    arc = np.flatnonzero(m.t_s > (200.0 + 100.0) / v + 0.2)[:-3]  # past the transition, away from the end
    assert len(arc) > 500
    f_body = body_specific_force(m)[arc]
    a_q_en13803 = v**2 / radius - G * cant_mm / 1000.0 / E_RAIL_M  # uncompensated lateral acceleration
    assert np.allclose(f_body[:, 1], a_q_en13803, rtol=0.03)
    assert np.allclose(
        m.pose[arc, 3], -np.arcsin(cant_mm / 1000.0 / E_RAIL_M), atol=1e-9
    )  # roll = cant angle
    assert np.allclose(f_body[:, 0], 0.0, atol=1e-6)  # constant speed: no longitudinal force
    # with no cant the full centripetal acceleration is felt
    flat = train("curve", speed_mps=v, radius_m=radius, cant_mm=0.0, transition_m=100.0, vibration=False)
    assert np.allclose(body_specific_force(flat)[arc, 1], v**2 / radius, rtol=1e-3)


def test_train_transition_curvature_and_cant_ramp_linearly():
    v, radius, length, straight, cant_mm = 44.0, 1500.0, 150.0, 180.0, 90.0
    m = train(
        "curve",
        speed_mps=v,
        radius_m=radius,
        transition_m=length,
        straight_m=straight,
        cant_mm=cant_mm,
        vibration=False,
    )
    vel, _ = derivatives(m)
    curvature = vel[:, 5] / v  # yaw rate / speed
    u = v * m.t_s - straight  # distance into the transition
    tr = (u > 2.0) & (u < length - 2.0)
    assert np.allclose(curvature[tr], u[tr] / (length * radius), rtol=1e-6, atol=1e-9)
    assert np.allclose(m.pose[tr, 3], -np.arcsin(cant_mm / 1000.0 / E_RAIL_M * u[tr] / length), atol=1e-9)
    assert np.all(np.abs(curvature[u < -2.0]) < 1e-12)  # straight
    arc = (u > length + 2.0) & (m.t_s < m.t_s[-1] - 0.1)
    assert np.allclose(curvature[arc], 1.0 / radius, rtol=1e-6)
    # the clothoid's heading: u^2 / (2 L R) at its end, then the arc turns at 1 / R
    assert m.pose[-1, 5] == pytest.approx(
        length / (2 * radius) + (v * m.t_s[-1] - straight - length) / radius, rel=1e-9
    )


def test_train_vertical_vibration_rms_matches_the_fra_spectrum_through_the_suspension():
    v, a_v_cm2, omega_c = 45.0, 0.5376, 0.8245  # FRA class 4 vertical profile (Hamid and Yang 1981)
    m = train("straight", speed_mps=v, track_class=4, duration_s=300.0, seed=7)
    f_lo, f_hi = v / 300.0, v / 1.5  # wavelengths 300 m .. 1.5 m (below the 20 Hz cap at 45 m/s)
    assert m.params["synthesis_band_hz"] == pytest.approx([f_lo, min(f_hi, 20.0)])

    def s_temporal(f):  # m^2 / Hz
        om = 2 * np.pi * f / v
        return 1e-4 * 0.25 * a_v_cm2 * omega_c**2 / (om**2 * (om**2 + omega_c**2)) * 2 * np.pi / v

    def h2(f):  # base-excited body, 1 Hz, zeta 0.2
        s, wn = 2j * np.pi * f, 2 * np.pi * 1.0
        return np.abs((0.4 * wn * s + wn**2) / (s**2 + 0.4 * wn * s + wn**2)) ** 2

    expected = np.sqrt(integrate.quad(lambda f: s_temporal(f) * h2(f), f_lo, min(f_hi, 20.0), limit=200)[0])
    z = m.pose[m.t_s > 5.0, 2]
    # random-phase synthesis has exact variance over its 300-s period; the 2-s fade-in, the filter
    # transient and the finite frequency grid (1/300 Hz) leave ~1 %: 5 % tolerance
    assert np.sqrt(np.mean(z**2)) == pytest.approx(expected, rel=0.05)
    assert 0.005 < expected < 0.05  # class 4 track: centimetres of long-wave profile
    # a better track class is smoother: class 6 A_v = 0.0339 -> RMS ratio sqrt(0.0339 / 0.5376)
    z6 = train("straight", speed_mps=v, track_class=6, duration_s=300.0, seed=7).pose[m.t_s > 5.0, 2]
    assert np.sqrt(np.mean(z6**2)) / expected == pytest.approx(np.sqrt(0.0339 / 0.5376), rel=0.05)


# FRA class -> (A_v cm^2 rad/m, Omega_s rad/m) as tabulated by Hamid and Yang (1981); Omega_c 0.8245
FRA_CROSS_LEVEL = {4: (0.5376, 1.1312), 5: (0.2095, 0.8209), 6: (0.0339, 0.4380)}


def fra_cross_level_psd(omega, track_class):
    """FRA cross-level PSD, m^2 / (rad/m), with the class's own roll-off wavenumber Omega_s."""
    a_v, omega_s = FRA_CROSS_LEVEL[track_class]
    return 1e-4 * 4 * 0.25 * a_v * 0.8245**2 / ((omega**2 + 0.8245**2) * (omega**2 + omega_s**2))


@pytest.mark.parametrize("track_class", [4, 5, 6])
def test_fra_cross_level_rolls_off_at_the_class_own_omega_s(track_class):
    omega = np.geomspace(2 * np.pi / 300.0, 2 * np.pi / 1.5, 50)
    got = track_psd_m2_per_rad_m(omega, "roll", track_class)
    np.testing.assert_allclose(got, fra_cross_level_psd(omega, track_class), rtol=1e-12)
    # at long wavelengths S_c -> 4 k A_v / Omega_s^2: a larger Omega_s (class 4) means less cross-level
    # than one Omega_s for every class would give, by (Omega_s / 0.4380)^2 (6.7x for class 4, 3.5x for 5)
    a_v, omega_s = FRA_CROSS_LEVEL[track_class]
    assert got[0] == pytest.approx(1e-4 * a_v / omega_s**2, rel=0.05)
    # the profile and alignment spectra do not involve Omega_s
    vertical = track_psd_m2_per_rad_m(omega, "vertical", track_class)
    np.testing.assert_allclose(
        vertical / track_psd_m2_per_rad_m(omega, "vertical", 6), a_v / 0.0339, rtol=1e-12
    )


@pytest.mark.parametrize("track_class", [4, 5])
def test_train_roll_vibration_rms_matches_the_class_cross_level_spectrum(track_class):
    v = 40.0
    m = train("straight", speed_mps=v, track_class=track_class, duration_s=300.0, seed=11)
    f_lo, f_hi = m.params["synthesis_band_hz"]

    def h2(f):  # base-excited body roll, 0.8 Hz, zeta 0.2
        s, wn = 2j * np.pi * f, 2 * np.pi * 0.8
        return np.abs((0.4 * wn * s + wn**2) / (s**2 + 0.4 * wn * s + wn**2)) ** 2

    def s_roll(f):  # cross-level met at speed v, per Hz, as a track roll angle c / e
        return fra_cross_level_psd(2 * np.pi * f / v, track_class) * 2 * np.pi / v / E_RAIL_M**2

    expected = np.sqrt(integrate.quad(lambda f: s_roll(f) * h2(f), f_lo, f_hi, limit=200)[0])
    roll = m.pose[m.t_s > 5.0, 3]
    assert np.sqrt(np.mean(roll**2)) == pytest.approx(expected, rel=0.05)


def test_train_curve_that_cannot_be_reached_or_turns_too_far_is_refused():
    with pytest.raises(ValueError, match="arc starts"):
        train("curve", speed_mps=10.0)  # 200 m straight + 120 m transition > 200 m in 20 s
    with pytest.raises(ValueError, match="heading"):
        train("curve", radius_m=200.0, cant_mm=0.0)


# ---------------------------------------------------------------------------------------------
# common properties
# ---------------------------------------------------------------------------------------------
DEFAULT_MOTIONS = {
    "train_curve": lambda seed=0: train("curve", seed=seed),
    "train_straight": lambda seed=0: train("straight", seed=seed),
    "aircraft_light": lambda seed=0: aircraft("light", seed=seed),
    "aircraft_moderate": lambda seed=0: aircraft("moderate", seed=seed),
}


@pytest.mark.parametrize("name", list(DEFAULT_MOTIONS))
def test_default_motions_start_at_rest_last_long_enough_and_keep_yaw_in_range(name):
    m = DEFAULT_MOTIONS[name]()
    assert m.name == name
    assert m.duration_s >= 10.0
    assert np.all(m.pose[0] == 0.0)
    vel, acc = derivatives(m)
    assert np.all(np.abs(vel[0]) < 1e-6)
    assert np.all(np.abs(acc[0, 3:]) < 1e-3)  # rotations start smoothly too
    assert np.all(np.abs(m.pose[:, 5]) <= 2.6)
    assert np.all(np.abs(m.pose[:, 3:5]) < 0.7)
    assert np.std(m.pose[m.t_s > 3.0, 2]) > 1e-3  # something happens: vibration / turbulence heave
    assert m.notes


@pytest.mark.parametrize("name", list(DEFAULT_MOTIONS))
def test_motions_are_deterministic_for_a_seed_and_differ_for_another(name):
    a, b, c = DEFAULT_MOTIONS[name](0), DEFAULT_MOTIONS[name](0), DEFAULT_MOTIONS[name](1)
    assert np.array_equal(a.pose, b.pose)
    assert np.max(np.abs(a.pose[:, 2] - c.pose[:, 2])) > 1e-3


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: train("tunnel"), "variant"),
        (lambda: train("curve", speed_mps=0.0), "speed_mps"),
        (lambda: train("straight", speed_mps=-5.0), "speed_mps"),
        (lambda: train("curve", track_class=2), "track_class"),
        (lambda: train("curve", cant_mm=-10.0), "cant_mm"),
        (lambda: aircraft("extreme"), "intensity"),
        (lambda: aircraft("light", airspeed_mps=0.0), "airspeed_mps"),
        (lambda: aircraft("light", altitude_m=100.0), "altitude_m"),
        (lambda: aircraft("light", duration_s=0.0), "duration_s"),
    ],
)
def test_bad_input_raises_value_error_naming_the_problem(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_motions_round_trip_through_the_trajectory_file(tmp_path):
    motions = [train("curve"), train("straight"), aircraft("light"), aircraft("moderate")]
    path = tmp_path / "s.npz"
    trj.save(path, to_trajectories(motions))
    loaded = trj.load(path)
    assert len(loaded) == len(motions)
    for row, m in enumerate(motions):
        pos, _, _ = loaded.evaluate(m.t_s, np.full(len(m.t_s), row))
        assert np.max(np.abs(pos - m.pose)) < 1e-9, m.name
    assert [s["name"] for s in loaded.meta["scenarios"]] == [m.name for m in motions]
    assert loaded.meta["scenarios"][0]["params"]["radius_m"] == 1500.0
