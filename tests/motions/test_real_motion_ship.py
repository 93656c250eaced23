"""Tests for lasmp.motions.ship: the JONSWAP sea, the ship's responses, the deck motion (fast)."""

import json

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.signal import welch

from lasmp.envs import trajectories as trj
from lasmp.motions import ship as S
from lasmp.motions.motion import derivatives, to_trajectories

G_M_S2 = 9.81
LONG_DT_S = 0.5  # coarse samples for hour-long records: Nyquist 2 pi rad/s > the band's top for Tp >= 5 s


@pytest.fixture(scope="module")
def three_hour_sea():
    """3 h of sea state 4 elevation at 2 Hz: (t_s, eta_m, hs_m, tp_s)."""
    hs_m, tp_s = S.SEA_STATES["sea_state_4"]
    t_s = np.arange(0.0, 3 * 3600.0, LONG_DT_S)
    return t_s, S.wave_elevation(t_s, hs_m, tp_s, seed=3), hs_m, tp_s


@pytest.mark.parametrize("gamma", [1.0, 3.3, 5.0])
def test_jonswap_area_gives_hs_and_peaks_at_tp(gamma):
    hs_m, tp_s = 2.0, 9.0
    m0 = quad(lambda w: S.jonswap_spectrum(np.array([w]), hs_m, tp_s, gamma)[0], 0.0, np.inf, limit=300)[0]
    assert 4.0 * np.sqrt(m0) == pytest.approx(hs_m, rel=0.015)
    omega = np.linspace(0.05, 3.0, 30001)
    peak_omega = omega[np.argmax(S.jonswap_spectrum(omega, hs_m, tp_s, gamma))]
    assert peak_omega == pytest.approx(2 * np.pi / tp_s, rel=1e-3)


@pytest.mark.parametrize(
    ("hs_m", "tp_s", "gamma"),
    [
        (4.0, 6.0, 5.0),  # Tp / sqrt(Hs) = 3.0: a steep young sea
        (1.0, 3.6, 5.0),  # the lower edge, 3.6
        (4.0, 8.0, np.exp(5.75 - 1.15 * 4.0)),  # 4.0: in between, 3.16
        (1.0, 4.5, np.exp(5.75 - 1.15 * 4.5)),  # 4.5: 1.78
        (4.0, 10.0, 1.0),  # 5.0: the upper edge, Pierson-Moskowitz
        (1.0, 9.0, 1.0),  # 9.0: fully developed
    ],
)
def test_dnv_gamma_follows_the_rule_of_dnv_rp_c205(hs_m, tp_s, gamma):
    assert S.dnv_gamma(hs_m, tp_s) == pytest.approx(gamma, rel=1e-12)


def test_dnv_gamma_is_continuous_and_falls_with_the_period():
    r = np.linspace(2.0, 7.0, 501)
    g = np.array([S.dnv_gamma(1.0, x) for x in r])
    assert np.all(np.diff(g) <= 0) and g[0] == 5.0 and g[-1] == 1.0
    assert S.dnv_gamma(1.0, 3.6 + 1e-9) == pytest.approx(5.0, abs=0.01)  # exp(1.61) = 5.003
    assert S.dnv_gamma(1.0, 5.0 - 1e-9) == pytest.approx(1.0, abs=1e-6)
    assert S.dnv_gamma(4.0, 8.0) == S.dnv_gamma(1.0, 4.0)  # a function of Tp / sqrt(Hs) only
    with pytest.raises(ValueError, match="hs_m"):
        S.dnv_gamma(0.0, 8.0)


def test_every_sea_state_preset_is_pierson_moskowitz_by_the_dnv_rule():
    for name, (hs_m, tp_s) in S.SEA_STATES.items():
        assert tp_s / np.sqrt(hs_m) >= 5.0, name
        assert S.ship_deck(name, duration_s=1.0).params["gamma"] == 1.0
    # None (the default) takes the rule; an explicit gamma is kept and changes the sea
    default = S.ship_deck("sea_state_4", duration_s=30.0)
    np.testing.assert_array_equal(default.pose, S.ship_deck("sea_state_4", gamma=1.0, duration_s=30.0).pose)
    peaked = S.ship_deck("sea_state_4", gamma=3.3, duration_s=30.0)
    assert peaked.params["gamma"] == 3.3 and np.max(np.abs(peaked.pose - default.pose)) > 0.01
    np.testing.assert_allclose(
        S.jonswap_spectrum(np.linspace(0.2, 2.0, 50), 2.0, 6.0),
        S.jonswap_spectrum(np.linspace(0.2, 2.0, 50), 2.0, 6.0, S.dnv_gamma(2.0, 6.0)),
    )


def test_significant_height_of_a_long_record(three_hour_sea):
    _, eta_m, hs_m, _ = three_hour_sea
    assert abs(np.mean(eta_m)) < 0.02 * hs_m
    assert 4.0 * np.std(eta_m) == pytest.approx(hs_m, rel=0.10)


def test_significant_height_scales_with_hs():
    # the same draw with twice Hs: the record doubles (amplitudes are sqrt(S) ~ Hs; Tp / sqrt(Hs) >= 5
    # for both, so DNV's rule gives both the same gamma, 1)
    t_s = np.arange(0.0, 600.0, LONG_DT_S)
    eta_1 = S.wave_elevation(t_s, 1.0, 8.0, seed=5)
    eta_2 = S.wave_elevation(t_s, 2.0, 8.0, seed=5)
    np.testing.assert_allclose(eta_2, 2.0 * eta_1, atol=1e-12)


def test_spectral_peak_near_one_over_tp(three_hour_sea):
    t_s, eta_m, _, tp_s = three_hour_sea
    f_hz, psd = welch(eta_m, fs=1.0 / LONG_DT_S, nperseg=1024)
    assert f_hz[np.argmax(psd)] == pytest.approx(1.0 / tp_s, rel=0.10)
    # another peak period moves the peak (1 h is enough for the peak)
    t_short = t_s[: int(3600 / LONG_DT_S)]
    f_hz, psd = welch(S.wave_elevation(t_short, 1.88, 6.0, seed=3), fs=1.0 / LONG_DT_S, nperseg=1024)
    assert f_hz[np.argmax(psd)] == pytest.approx(1.0 / 6.0, rel=0.10)


def test_jittered_frequencies_do_not_repeat():
    comp = S.wave_components(1.88, 8.8, seed=1)
    assert len(comp.omega_rad_s) == S.N_COMPONENTS
    period_s = 2 * np.pi / comp.d_omega_rad_s  # the period an equally spaced grid would have
    t_s = np.arange(0.0, 600.0, LONG_DT_S)
    first, later = comp.elevation(t_s), comp.elevation(t_s + period_s)
    assert abs(np.corrcoef(first, later)[0, 1]) < 0.5
    # the same components on an equally spaced grid of multiples of dw repeat exactly: the check can fail
    first_bin = round(S.BAND_OVER_PEAK[0] * 2 * np.pi / 8.8 / comp.d_omega_rad_s)
    centred = S.WaveComponents(
        omega_rad_s=(first_bin + np.arange(len(comp.omega_rad_s))) * comp.d_omega_rad_s,
        amplitude_m=comp.amplitude_m,
        phase_rad=comp.phase_rad,
        d_omega_rad_s=comp.d_omega_rad_s,
    )
    assert np.corrcoef(centred.elevation(t_s), centred.elevation(t_s + period_s))[0, 1] > 0.999


@pytest.mark.parametrize("zeta", [0.05, 0.08, 0.3])
def test_second_order_gain(zeta):
    wn = 2 * np.pi / 12.0
    h = S.second_order_gain(np.array([0.0, wn, 10 * wn]), wn, zeta)
    assert h[0] == pytest.approx(1.0)  # unit static gain
    assert h[1] == pytest.approx(-1j / (2 * zeta))  # resonance: 1 / (2 zeta), 90 deg lag
    assert abs(h[2]) == pytest.approx(1.0 / abs(1 - 100 + 20j * zeta))  # ~ (wn / w)^2 above resonance


def _regular_wave(omega_rad_s, amplitude_m=0.1):
    return S.WaveComponents(np.array([omega_rad_s]), np.array([amplitude_m]), np.array([0.3]), 0.0)


def test_roll_resonance_in_a_regular_beam_wave():
    ship = S.MID_SIZE_SHIP
    wn = 2 * np.pi / ship.roll_period_s
    amplitude_m = 0.1

    def roll_per_slope(omega, heading_deg=90.0):
        """Roll amplitude over the wave-slope amplitude k a, from two periods of steady state."""
        t_s = np.linspace(0.0, 2 * 2 * np.pi / omega, 2001)
        roll = S.ship_response(t_s, _regular_wave(omega, amplitude_m), heading_deg, ship)[:, 1]
        return np.max(np.abs(roll)) / (omega**2 / G_M_S2 * amplitude_m)

    # at the natural frequency: the resonance gain 1 / (2 zeta) (the 16 m beam averages out < 1 %)
    assert roll_per_slope(wn) == pytest.approx(1 / (2 * ship.roll_damping_ratio), rel=0.02)
    # long waves: roll follows the wave slope; short waves are filtered out
    assert roll_per_slope(0.1 * wn) == pytest.approx(1.0, rel=0.02)
    assert roll_per_slope(3 * wn) < 0.2
    # the peak of the response curve is at the natural frequency
    scan = np.linspace(0.6 * wn, 1.4 * wn, 41)
    assert scan[np.argmax([roll_per_slope(w) for w in scan])] == pytest.approx(wn, rel=0.03)
    # head seas do not roll the ship
    assert roll_per_slope(wn, heading_deg=180.0) < 1e-9


@pytest.mark.parametrize("heading_deg", [0.0, 90.0, 180.0])
def test_long_waves_are_followed_quasi_statically_with_the_pose_signs(heading_deg):
    # a 20 km long regular wave: the ship rides the surface; heave = eta, and with x forward, y to
    # port, z up, R = Rz Ry Rx: pitch (bow down) = minus the slope along x, roll (port up) = the slope
    # along y, for eta(x, y, t) = a cos(w t - k (x cos mu + y sin mu) + phi)
    omega, amplitude_m, mu = 0.055, 0.1, np.radians(heading_deg)
    wave = _regular_wave(omega, amplitude_m)
    k = omega**2 / G_M_S2
    t_s = np.linspace(0.0, 2 * np.pi / omega, 501)
    heave, roll, pitch = S.ship_response(t_s, wave, heading_deg).T
    eta = amplitude_m * np.cos(omega * t_s + 0.3)
    slope_along = amplitude_m * k * np.sin(omega * t_s + 0.3)  # d eta / d(x cos mu + y sin mu) at 0
    np.testing.assert_allclose(heave, eta, atol=0.05 * amplitude_m)
    np.testing.assert_allclose(pitch, -slope_along * np.cos(mu), atol=0.05 * amplitude_m * k)
    np.testing.assert_allclose(roll, slope_along * np.sin(mu), atol=0.05 * amplitude_m * k)


def test_deck_point_forward_heaves_more_in_head_seas():
    kw = {"sea_state": "sea_state_5", "heading_deg": 180.0, "duration_s": 60.0, "seed": 2}
    forward = S.ship_deck(deck_offset_m=(20.0, 0.0, 0.0), **kw)
    at_cg = S.ship_deck(deck_offset_m=(0.0, 0.0, 0.0), **kw)
    np.testing.assert_allclose(forward.pose[:, 3:], at_cg.pose[:, 3:])  # same ship motion
    assert np.std(forward.pose[:, 2]) > 1.2 * np.std(at_cg.pose[:, 2])
    # the difference is the lever arm of the pitch rotation (deck_pose: z of R r, bow down = +pitch)
    pitch = forward.pose[:, 4]
    np.testing.assert_allclose(forward.pose[:, 2] - at_cg.pose[:, 2], -20.0 * np.sin(pitch), atol=1e-9)
    assert np.max(np.abs(pitch)) > 0.01
    assert np.max(np.abs(forward.pose[:, 3])) < 1e-9  # no roll in head seas


def test_motion_start_duration_and_seed():
    m = S.ship_deck()
    assert m.name == "ship_sea_state_4"
    assert m.duration_s >= 10.0 and m.dt_s == pytest.approx(0.01)
    assert np.all(np.isfinite(m.pose))
    assert np.all(m.pose[0] == 0.0)
    vel, _ = derivatives(m)
    assert np.max(np.abs(vel[0])) < 0.01 * np.max(np.abs(vel))  # ramp-in: starts from rest
    assert np.max(np.abs(m.pose[:, 2])) > 0.1  # and then it moves
    np.testing.assert_array_equal(S.ship_deck().pose, m.pose)  # deterministic for a seed
    assert np.max(np.abs(S.ship_deck(seed=1).pose - m.pose)) > 0.05
    params = json.loads(json.dumps(m.params))
    assert params["hs_m"] == S.SEA_STATES["sea_state_4"][0] and params["seed"] == 0
    assert params["deck_offset_m"] == list(S.DECK_OFFSET_M)


def test_overrides_and_presets():
    m = S.ship_deck("sea_state_3", hs_m=1.0, tp_s=6.0, duration_s=10.0)
    assert (m.params["hs_m"], m.params["tp_s"]) == (1.0, 6.0)
    # presets sit inside their WMO code bands and get rougher with the code
    bands = {"sea_state_3": (0.5, 1.25), "sea_state_4": (1.25, 2.5), "sea_state_5": (2.5, 4.0)}
    for name, (lo, hi) in bands.items():
        assert lo <= S.SEA_STATES[name][0] <= hi
    z_std = [np.std(S.ship_deck(name, duration_s=40.0).pose[:, 2]) for name in bands]
    assert z_std[0] < z_std[1] < z_std[2]


def test_notes_report_workspace_without_clipping():
    calm = S.ship_deck("sea_state_3", duration_s=30.0)
    assert "within the training workspace" in calm.notes
    storm = S.ship_deck("sea_state_5", hs_m=12.0, tp_s=12.0, heading_deg=90.0, duration_s=60.0)
    assert "EXCEEDS" in storm.notes
    assert np.ptp(storm.pose[:, 2]) > S.WORKSPACE_VERTICAL_RANGE_M  # not clipped to the workspace
    assert f"z range {np.ptp(storm.pose[:, 2]):.2f} m" in storm.notes


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"sea_state": "sea_state_9"}, "sea_state"),
        ({"hs_m": 0.0}, "hs_m"),
        ({"hs_m": float("nan")}, "hs_m"),
        ({"tp_s": -3.0}, "tp_s"),
        ({"gamma": 0.5}, "gamma"),
        ({"deck_offset_m": (20.0, 5.0)}, "deck_offset_m"),
        ({"duration_s": 0.0}, "duration_s"),
        ({"dt_s": -0.01}, "dt_s"),
        ({"dt_s": 1.0}, "dt_s"),  # too coarse for the sea's highest component
        ({"heading_deg": float("inf")}, "heading_deg"),
    ],
)
def test_bad_input_names_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        S.ship_deck(**kwargs)


def test_unknown_sea_state_lists_valid_ones():
    with pytest.raises(ValueError, match="sea_state_3.*sea_state_4.*sea_state_5"):
        S.ship_deck("hurricane")


def test_round_trip_through_trajectory_file(tmp_path):
    motions = [S.ship_deck("sea_state_4"), S.ship_deck("sea_state_5", heading_deg=90.0, seed=7)]
    trj.save(tmp_path / "s.npz", to_trajectories(motions))
    loaded = trj.load(tmp_path / "s.npz")
    assert len(loaded) == 2
    for row, m in enumerate(motions):
        pose, _, _ = loaded.evaluate(m.t_s, np.full(len(m.t_s), row))
        np.testing.assert_allclose(pose, m.pose, rtol=0, atol=1e-9)
    assert [s["name"] for s in loaded.meta["scenarios"]] == ["ship_sea_state_4", "ship_sea_state_5"]
    assert loaded.meta["scenarios"][1]["params"]["heading_deg"] == 90.0
