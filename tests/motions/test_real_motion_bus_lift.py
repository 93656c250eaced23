"""Tests for the jerk-limited profiles, the city bus and the lift of the real-motion suite (fast)."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from lasmp.envs import trajectories as trj
from lasmp.motions import bus as B
from lasmp.motions import lift as L
from lasmp.motions import profiles as P
from lasmp.motions.motion import derivatives, to_trajectories

REL = 1e-6  # analytic phases: peaks equal the parameters to rounding


def _num_derivs(prof: P.JerkProfile, dt: float = 1e-3):
    """Sampled history of a profile and its numerical derivatives on a fine grid."""
    t = np.arange(0.0, prof.duration_s + dt / 2, dt)
    k = prof.sample(t)
    v = np.gradient(k.pos_m, t)
    a = np.gradient(k.vel_mps, t)
    return k, v, a


# --- profiles ----------------------------------------------------------------------------------------


def test_velocity_change_trapezoid_reaches_exact_limits():
    prof = P.velocity_change(2.0, 10.0, a_max_mps2=1.5, j_max_mps3=2.0)
    pk = prof.peaks()
    assert pk.jerk_mps3 == pytest.approx(2.0, rel=REL)
    assert pk.acc_mps2 == pytest.approx(1.5, rel=REL)
    assert pk.vel_mps == pytest.approx(10.0, rel=REL)
    p_end, v_end, a_end = prof.end_state
    assert v_end == pytest.approx(10.0, rel=1e-12) and abs(a_end) < 1e-12
    # T = dv / a + a / j; symmetric pulse: distance = mean speed * T
    assert prof.duration_s == pytest.approx(8.0 / 1.5 + 1.5 / 2.0, rel=1e-12)
    assert p_end == pytest.approx(6.0 * prof.duration_s, rel=1e-12)
    # sampled: the plateau holds a_max, never more; positions and velocities agree
    k, v_num, a_num = _num_derivs(prof)
    assert np.max(k.acc_mps2) == pytest.approx(1.5, rel=REL) and np.max(k.acc_mps2) <= 1.5 + 1e-12
    assert np.max(np.abs(k.jerk_mps3)) == pytest.approx(2.0, rel=REL)
    np.testing.assert_allclose(v_num[1:-1], k.vel_mps[1:-1], atol=2.0 * 1e-6)
    np.testing.assert_allclose(a_num[1:-1], k.acc_mps2[1:-1], atol=2.0 * 1e-3)


def test_velocity_change_triangular_when_a_max_not_reached():
    # dv = 0.5 < a^2 / j = 1.125: the acceleration is a triangle peaking at sqrt(dv j) = 1.0
    prof = P.velocity_change(5.0, 4.5, a_max_mps2=1.5, j_max_mps3=2.0)
    pk = prof.peaks()
    assert pk.acc_mps2 == pytest.approx(1.0, rel=REL) and pk.acc_mps2 < 1.5
    assert pk.jerk_mps3 == pytest.approx(2.0, rel=REL)
    assert prof.duration_s == pytest.approx(2.0 * math.sqrt(0.5 / 2.0), rel=1e-12)
    k, _, _ = _num_derivs(prof)
    assert np.min(k.acc_mps2) == pytest.approx(-1.0, rel=1e-4) and np.max(k.acc_mps2) <= 1e-12  # decreasing
    assert prof.end_state[1] == pytest.approx(4.5, rel=1e-12)
    assert P.velocity_change(3.0, 3.0, 1.0, 1.0).duration_s == 0.0


def _d_of_v(v, a, j):
    """Distance of accelerating 0 -> v and back (independent of the module's closed forms)."""
    t_acc = v / a + a / j if v * j >= a * a else 2.0 * math.sqrt(v / j)
    return v * t_acc


@pytest.mark.parametrize(
    "distance_m, v_max, a_max, j_max, reach_v, reach_a",
    [
        (12.0, 1.6, 1.0, 1.5, True, True),  # full 7 phases
        (3.0, 1.6, 1.0, 1.5, False, True),  # v_max not reached, a_max reached
        (0.1, 1.6, 1.0, 1.5, False, False),  # neither reached
        (5.0, 0.5, 1.0, 1.5, True, False),  # v_max reached before a_max (v_max < a^2 / j)
        (-7.5, 2.5, 1.2, 2.0, True, True),  # downward
    ],
)
def test_s_curve_distance_and_limits(distance_m, v_max, a_max, j_max, reach_v, reach_a):
    prof = P.s_curve(distance_m, v_max, a_max, j_max)
    p_end, v_end, a_end = prof.end_state
    assert p_end == pytest.approx(distance_m, rel=1e-12)
    assert abs(v_end) < 1e-12 and abs(a_end) < 1e-12
    pk = prof.peaks()
    assert pk.jerk_mps3 == pytest.approx(j_max, rel=REL)
    assert pk.vel_mps <= v_max * (1 + 1e-12) and pk.acc_mps2 <= a_max * (1 + 1e-12)
    assert (pk.vel_mps == pytest.approx(v_max, rel=REL)) is reach_v
    assert (pk.acc_mps2 == pytest.approx(a_max, rel=REL)) is reach_a
    d = abs(distance_m)
    if reach_v:  # T = d / v + t_acc(v) (the cruise fills the distance the ramps leave)
        t_acc = v_max / a_max + a_max / j_max if reach_a else 2.0 * math.sqrt(v_max / j_max)
        assert prof.duration_s == pytest.approx(d / v_max + t_acc, rel=1e-9)
    else:  # no cruise: the peak speed is the root of D(v) = d
        assert _d_of_v(pk.vel_mps, a_max, j_max) == pytest.approx(d, rel=1e-9)
    if not reach_a:  # triangular ramps: the peak acceleration is sqrt(v_peak j)
        assert pk.acc_mps2 == pytest.approx(math.sqrt(pk.vel_mps * j_max), rel=1e-9)
    # sampled on a grid: position covers the distance, speed and acceleration do not overshoot
    k, v_num, a_num = _num_derivs(prof)
    assert k.pos_m[-1] == pytest.approx(distance_m, abs=1e-6)
    assert np.max(np.abs(v_num)) == pytest.approx(pk.vel_mps, rel=1e-4)
    assert np.max(np.abs(a_num)) <= pk.acc_mps2 * (1 + 1e-3)
    assert np.all(np.diff(k.pos_m) * math.copysign(1.0, distance_m) >= -1e-12)  # monotone


def test_concatenate_and_sample_outside():
    prof = P.concatenate(
        [
            P.hold(1.0),
            P.velocity_change(0.0, 5.0, 1.0, 2.0),
            P.hold(2.0, 5.0),
            P.velocity_change(5.0, 0.0, 2.0, 4.0),
        ]
    )
    acc_up = 5.0 / 1.0 + 1.0 / 2.0
    acc_down = 5.0 / 2.0 + 2.0 / 4.0
    assert prof.duration_s == pytest.approx(1.0 + acc_up + 2.0 + acc_down, rel=1e-12)
    assert prof.end_state[0] == pytest.approx(2.5 * acc_up + 10.0 + 2.5 * acc_down, rel=1e-12)
    k = prof.sample([-1.0, 0.5, prof.duration_s + 3.0])
    np.testing.assert_allclose(k.vel_mps, 0.0, atol=1e-12)  # at rest before, in the hold and after
    assert k.pos_m[2] == pytest.approx(prof.end_state[0], rel=1e-12)
    cruise = P.hold(2.0, 3.0).sample([4.0])  # zero jerk continues past the end
    assert cruise.pos_m[0] == pytest.approx(12.0) and cruise.vel_mps[0] == pytest.approx(3.0)
    with pytest.raises(ValueError, match="starts at v"):
        P.concatenate([P.velocity_change(0.0, 5.0, 1.0, 2.0), P.hold(1.0, 3.0)])


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: P.velocity_change(0.0, 1.0, -1.0, 1.0), "a_max_mps2"),
        (lambda: P.velocity_change(0.0, 1.0, 1.0, 0.0), "j_max_mps3"),
        (lambda: P.s_curve(1.0, -1.0, 1.0, 1.0), "v_max_mps"),
        (lambda: P.s_curve(float("nan"), 1.0, 1.0, 1.0), "distance_m"),
        (lambda: P.hold(-1.0), "duration_s"),
    ],
)
def test_profiles_reject_bad_input(call, match):
    with pytest.raises(ValueError, match=match):
        call()


# --- lift ----------------------------------------------------------------------------------------------


def _vaj(m):
    v, a = derivatives(m)
    j = np.gradient(a, m.t_s, axis=0)
    return v, a, j


@pytest.mark.parametrize(
    "variant, kwargs",
    [
        ("up", {}),
        ("down", {}),
        ("up", {"travel_m": 20.0, "v_max_mps": 2.5, "a_max_mps2": 1.2, "j_max_mps3": 2.0}),
        ("down", {"travel_m": 6.0, "v_max_mps": 1.0, "a_max_mps2": 0.8, "j_max_mps3": 1.0}),
    ],
)
def test_lift_peaks_equal_parameters(variant, kwargs):
    m = L.lift(variant, **kwargs)
    v_max = kwargs.get("v_max_mps", L.V_MAX_MPS)
    a_max = kwargs.get("a_max_mps2", L.A_MAX_MPS2)
    j_max = kwargs.get("j_max_mps3", L.J_MAX_MPS3)
    v, a, j = _vaj(m)
    # inside each constant-jerk phase the sampled position is an exact cubic, so the central
    # differences reproduce the plateaus; near the phase joints they only average (never exceed)
    assert np.max(np.abs(v[:, 2])) == pytest.approx(v_max, rel=REL)
    assert np.max(np.abs(a[:, 2])) == pytest.approx(a_max, rel=REL)
    assert np.max(np.abs(j[:, 2])) == pytest.approx(j_max, rel=REL)
    np.testing.assert_allclose(m.pose[:, [0, 1, 3, 4, 5]], 0.0)


def test_lift_up_goes_up_down_goes_down_from_rest_to_rest():
    up, down = L.lift("up"), L.lift("down")
    for m, sign in ((up, 1.0), (down, -1.0)):
        z = m.pose[:, 2]
        assert m.duration_s >= 10.0
        np.testing.assert_array_equal(m.pose[0], 0.0)
        assert z[-1] == pytest.approx(sign * L.TRAVEL_M, abs=1e-9)
        assert np.all(sign * np.diff(z) >= -1e-12)  # monotone
        hold_n = int(L.HOLD_S / m.dt_s)
        v, _ = derivatives(m)
        assert np.max(np.abs(v[: hold_n - 1, 2])) < 1e-12  # at rest during the initial hold
        assert np.max(np.abs(v[-50:, 2])) < 1e-9  # and at rest at the end
        assert m.params["trip_end_s"] < m.duration_s
    np.testing.assert_allclose(up.pose[:, 2], -down.pose[:, 2], atol=1e-12)


@pytest.mark.parametrize("decel", [L.EMERGENCY_DECEL_MPS2, 0.3 * L.G_N_MPS2])
def test_lift_emergency_stop_deceleration_equals_parameter(decel):
    m = L.lift("emergency_stop", emergency_decel_mps2=decel)
    v, a, _ = _vaj(m)
    k_stop = int(np.argmin(a[:, 2]))
    assert a[k_stop, 2] == pytest.approx(-decel, rel=REL)
    assert v[:, 2].max() == pytest.approx(L.V_MAX_MPS, rel=REL)  # tripped at rated speed
    assert v[k_stop, 2] > 0  # decelerating while going up
    # the retardation is held for v / decel minus one onset time (the ramps take the rest)
    held = np.sum(np.abs(a[:, 2] + decel) < 1e-6 * decel) * m.dt_s
    assert held == pytest.approx(L.V_MAX_MPS / decel - L.EMERGENCY_ONSET_S, abs=6 * m.dt_s)
    assert np.max(np.abs(v[-50:, 2])) < 1e-9 and m.pose[-1, 2] > 0  # stopped, above where it started
    # the normal trip's peak deceleration is a_max: the emergency one is far harder
    assert decel > 2.5 * L.A_MAX_MPS2


def test_lift_rejects_bad_input_and_trips_that_do_not_fit():
    with pytest.raises(ValueError, match="variant"):
        L.lift("sideways")
    with pytest.raises(ValueError, match="v_max_mps"):
        L.lift("up", v_max_mps=-1.0)
    with pytest.raises(ValueError, match="travel_m"):
        L.lift("up", travel_m=0.0)
    with pytest.raises(ValueError, match="emergency_decel_mps2"):
        L.lift("emergency_stop", emergency_decel_mps2=-3.0)
    with pytest.raises(ValueError, match="does not fit"):
        L.lift("up", travel_m=100.0)
    with pytest.raises(ValueError, match="rated speed"):
        L.lift("emergency_stop", travel_m=3.0)  # never cruises at v_max


# --- bus -----------------------------------------------------------------------------------------------

CLEAN = {"road_class": None, "floor_offset_m": (0.0, 0.0, 0.0)}  # the CG on a smooth road


def _along_across(m):
    """Acceleration along and across (left-positive) the heading, from the sampled world motion."""
    _, a = derivatives(m)
    psi = m.pose[:, 5]
    along = a[:, 0] * np.cos(psi) + a[:, 1] * np.sin(psi)
    across = -a[:, 0] * np.sin(psi) + a[:, 1] * np.cos(psi)
    return along, across


@pytest.mark.parametrize(
    "variant, kwargs, decel",
    [
        ("stop_and_go", {}, B.BRAKE_MPS2),
        ("stop_and_go", {"brake_mps2": 1.2, "duration_s": 25.0}, 1.2),
        ("emergency_brake", {}, B.EMERGENCY_DECEL_MPS2),
        ("emergency_brake", {"emergency_decel_mps2": 6.0}, 6.0),
    ],
)
def test_bus_braking_deceleration_equals_parameter(variant, kwargs, decel):
    m = B.city_bus(variant, **CLEAN, **kwargs)
    along, _ = _along_across(m)
    assert np.min(along) == pytest.approx(-decel, rel=1e-4)
    assert np.max(along) == pytest.approx(B.ACCEL_MPS2, rel=1e-4)  # the pull-away
    v, _ = derivatives(m)
    assert np.max(np.hypot(v[:, 0], v[:, 1])) == pytest.approx(B.CRUISE_SPEED_MPS, rel=1e-6)


@pytest.mark.parametrize("a_lat, turn", [(B.A_LAT_MPS2, B.TURN_ANGLE_RAD), (1.0, -0.5)])
def test_bus_lateral_acceleration_in_turn_equals_parameter(a_lat, turn):
    m = B.city_bus("stop_and_go", a_lat_mps2=a_lat, turn_angle_rad=turn, **CLEAN)
    _, across = _along_across(m)
    peak = across[np.argmax(np.abs(across))]
    assert peak == pytest.approx(math.copysign(a_lat, turn), rel=1e-4)  # left turn: acceleration to the left
    assert m.pose[-1, 5] == pytest.approx(turn, abs=1e-9)  # the heading turned by the turn angle
    assert np.max(np.abs(m.pose[:, 5])) <= 2.6


def _body_response_peak(height, length, speed, freq_hz, zeta, shape):
    """Peak of the base-excited 1-DoF sprung mass over a hump, by ODE integration (independent)."""
    w = 2.0 * math.pi * freq_hz
    r = (length**2 / 4 + height**2) / (2 * height)

    def road(t):
        x = t * speed
        if not 0.0 <= x <= length:
            return 0.0
        if shape == "half_sine":
            return height * math.sin(math.pi * x / length)
        return math.sqrt(r * r - (x - length / 2) ** 2) - (r - height)

    # H(s) = (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2) in controllable canonical form (input: road only)
    def rhs(t, x):
        return [x[1], -w * w * x[0] - 2 * zeta * w * x[1] + road(t)]

    t_end = length / speed + 4.0
    sol = solve_ivp(rhs, (0.0, t_end), [0.0, 0.0], max_step=2e-3, rtol=1e-8, atol=1e-11, dense_output=True)
    t = np.linspace(0.0, t_end, 20001)
    x1, x2 = sol.sol(t)
    return float(np.max(w * w * x1 + 2 * zeta * w * x2))


@pytest.mark.parametrize("shape, speed", [("circular", B.CRUISE_SPEED_MPS), ("half_sine", 5.0)])
def test_bus_bump_lifts_each_axle_by_the_filtered_height_rear_after_wheelbase_over_v(shape, speed):
    a_f, b_r = B.CG_TO_FRONT_AXLE_M, B.WHEELBASE_M - B.CG_TO_FRONT_AXLE_M
    common = {"road_class": None, "pitch_gradient_rad_per_mps2": 0.0, "bump_shape": shape}
    common.update(cruise_speed_mps=speed, turn_angle_rad=0.2, duration_s=25.0)
    # a floor point above an axle rides that axle's heave (the pitch lever arm cancels the CG heave)
    front = B.city_bus("stop_and_go", floor_offset_m=(a_f, 0.0, 0.0), **common)
    rear = B.city_bus("stop_and_go", floor_offset_m=(-b_r, 0.0, 0.0), **common)
    expected = _body_response_peak(
        B.BUMP_HEIGHT_M, B.BUMP_LENGTH_M, speed, B.BODY_FREQ_HZ, B.BODY_DAMPING_RATIO, shape
    )
    assert expected > 0.5 * B.BUMP_HEIGHT_M  # the suspension passes a hump of this length
    zf, zr = front.pose[:, 2], rear.pose[:, 2]
    assert np.max(zf) == pytest.approx(expected, rel=0.01)
    assert np.max(zr) == pytest.approx(expected, rel=0.01)
    # the rear axle rides the same hump one wheelbase later: the heave signals are shifted copies
    lags = np.arange(1, int(2.0 / front.dt_s))
    corr = [np.dot(zf[:-k], zr[k:]) for k in lags]
    lag_s = lags[int(np.argmax(corr))] * front.dt_s
    assert lag_s == pytest.approx(B.WHEELBASE_M / speed, abs=1.01 * front.dt_s)
    ev = front.params["events"]
    assert ev["bump_rear_s"][0] - ev["bump_front_s"][0] == pytest.approx(B.WHEELBASE_M / speed, rel=1e-6)
    # between the hits the bus pitches nose up (front high), then nose down (rear high)
    cg = B.city_bus("stop_and_go", floor_offset_m=(0.0, 0.0, 0.0), **common)
    k_f, k_r = np.argmax(zf), np.argmax(zr)
    assert cg.pose[k_f, 4] < 0 < cg.pose[k_r, 4]


def test_bus_slow_long_hump_is_followed_quasi_statically_and_pothole_dips():
    kw = {"road_class": None, "bump_length_m": 40.0, "duration_s": 30.0, "floor_offset_m": (0.0, 0.0, 0.0)}
    m = B.city_bus("stop_and_go", **kw)
    assert np.max(m.pose[:, 2]) == pytest.approx(B.BUMP_HEIGHT_M, rel=0.03)
    pothole = B.city_bus("stop_and_go", **{**kw, "bump_height_m": -0.05})
    assert np.min(pothole.pose[:, 2]) == pytest.approx(-0.05, rel=0.03)
    assert np.max(pothole.pose[:, 2]) < 0.1 * 0.05  # no rise worth the name (a small rebound)


def test_bus_roll_in_turn_and_pitch_under_braking_follow_the_gradients():
    m = B.city_bus("stop_and_go", **CLEAN)
    ev = m.params["events"]
    t = m.t_s
    # 0.3 s before the end of the turn's plateau (a_lat ramps down for a / j = 0.75 s): settled roll
    k_turn = np.searchsorted(t, ev["turn_end_s"][0] - B.A_LAT_MPS2 / B.JERK_MPS3 - 0.3)
    assert m.pose[k_turn, 3] == pytest.approx(B.ROLL_GRADIENT_RAD_PER_MPS2 * B.A_LAT_MPS2, rel=0.02)
    assert m.pose[k_turn, 3] > 0  # left turn: the body leans out to the right (left side up)
    k_brake = np.searchsorted(t, ev["stop_s"][0] - B.BRAKE_MPS2 / B.JERK_MPS3 - 0.3)
    assert m.pose[k_brake, 4] == pytest.approx(B.PITCH_GRADIENT_RAD_PER_MPS2 * B.BRAKE_MPS2, rel=0.02)
    k_pull = np.searchsorted(t, ev["cruise_s"][0] - B.ACCEL_MPS2 / B.JERK_MPS3 - 0.3)
    assert m.pose[k_pull, 4] == pytest.approx(
        -B.PITCH_GRADIENT_RAD_PER_MPS2 * B.ACCEL_MPS2, rel=0.02
    )  # squat


@pytest.mark.parametrize("variant", B.VARIANTS)
def test_bus_starts_at_rest_is_deterministic_and_yaw_bounded(variant):
    m = B.city_bus(variant)
    assert m.duration_s >= 10.0
    np.testing.assert_array_equal(m.pose[0], 0.0)
    v, _ = derivatives(m)
    hold_n = int(B.HOLD_S / m.dt_s)
    assert np.max(np.abs(v[: hold_n - 1])) < 1e-12
    assert np.max(np.abs(m.pose[:, 5])) <= 2.6
    assert np.max(np.abs(v[-3, :2])) < 0.01  # stopped (the body still settles by millimetres)
    np.testing.assert_array_equal(B.city_bus(variant, seed=3).pose, B.city_bus(variant, seed=3).pose)
    assert not np.allclose(B.city_bus(variant, seed=3).pose[:, 2], m.pose[:, 2])  # the road differs
    smooth = B.city_bus(variant, road_class=None, seed=1)
    np.testing.assert_array_equal(smooth.pose, B.city_bus(variant, road_class=None, seed=2).pose)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"variant": "tram"}, "variant"),
        ({"brake_mps2": -1.0}, "brake_mps2"),
        ({"cruise_speed_mps": 0.0}, "cruise_speed_mps"),
        ({"turn_angle_rad": 3.0}, "turn_angle_rad"),
        ({"bump_length_m": -2.0}, "bump_length_m"),
        ({"road_class": "Z"}, "road_class"),
        ({"stops": 0}, "stops"),
        ({"duration_s": 12.0}, "does not fit"),
        ({"stops": 2}, "does not fit"),
    ],
)
def test_bus_rejects_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        B.city_bus(**kwargs)


# --- file round trip -----------------------------------------------------------------------------------


def test_motions_round_trip_through_the_trajectory_file(tmp_path):
    motions = [B.city_bus("stop_and_go"), B.city_bus("emergency_brake")] + [L.lift(v) for v in L.VARIANTS]
    path = tmp_path / "s.npz"
    trj.save(path, to_trajectories(motions))
    loaded = trj.load(path)
    assert len(loaded) == len(motions)
    for row, m in enumerate(motions):
        pose, _, _ = loaded.evaluate(m.t_s, np.full(len(m.t_s), row))
        np.testing.assert_allclose(pose, m.pose, rtol=0, atol=1e-9)
