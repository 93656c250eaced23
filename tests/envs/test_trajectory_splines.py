"""lasmp.envs.trajectories' generated sets (fast): the split's ranges, the approximating and
interpolating splines against scipy, rest at both ends, C2 continuity, reproducibility, and the
rows of a set replaced, on the host and on the device copy the env steps."""

import numpy as np
import pytest
from scipy.interpolate import BSpline, CubicSpline
from scipy.spatial import Delaunay

from lasmp.envs import trajectories as T


def test_ranges_and_split():
    assert (
        T.ranges_for_split("train").n_waypoints_min == 5 and T.ranges_for_split("train").n_waypoints_max == 15
    )
    assert (
        T.ranges_for_split("test").n_waypoints_min == 4 and T.ranges_for_split("test").n_waypoints_max == 16
    )
    assert T.TEST_RANGES.high[2] == 5.0 and T.TEST_RANGES.low[5] == -2.6
    with pytest.raises(ValueError, match="split"):
        T.ranges_for_split("val")


@pytest.fixture(scope="module")
def interp():
    return T.sample(100, T.TEST_RANGES, np.random.default_rng(123), spline=T.SplineSpec("interpolating"))


def _control_points(tr, m):
    """The control polygon of an approximating row: [0 x3, w_1..w_N, w_N x2]."""
    wp = tr.knot_poses[m, : tr.n_knots[m]]
    return np.concatenate([wp[:1], wp[:1], wp, wp[-1:], wp[-1:]])


def test_waypoints_in_ranges(traj):
    r = T.TEST_RANGES
    assert set(np.unique(traj.n_waypoints)) == set(range(4, 17))
    assert np.all(traj.kind == T.APPROXIMATING) and np.all(traj.degree == T.DEFAULT_DEGREE)
    for m in range(len(traj)):
        n = traj.n_knots[m]
        assert n == traj.n_waypoints[m] + 1
        wp = traj.knot_poses[m, 1:n]
        assert np.all(wp >= np.array(r.low)) and np.all(wp <= np.array(r.high))
        assert traj.knot_times_s[m, n - 1] == 10.0


def test_path_stays_in_convex_hull_of_control_points(traj):
    t = np.linspace(0.0, 10.0, 201)
    for m in range(0, len(traj), 5):
        ctrl = _control_points(traj, m)
        p = traj.evaluate(t, np.full(len(t), m))[0]
        # every channel within its control points' range (the hull's bounding box, all six channels) ...
        assert np.all(p >= ctrl.min(0) - 1e-9) and np.all(p <= ctrl.max(0) + 1e-9)
        # ... and the translational path inside the 3-D convex hull of the control points
        hull = Delaunay(ctrl[:, :3])
        assert np.all(hull.find_simplex(p[:, :3], tol=1e-9) >= 0), m


def test_matches_scipy_bspline_of_the_control_points(traj):
    rng = np.random.default_rng(0)
    rows = rng.integers(0, len(traj), size=4000)
    t = rng.uniform(0.0, 10.0, size=4000)
    p, v, a = traj.evaluate(t, rows)
    for m in np.unique(rows)[:60]:
        ctrl = _control_points(traj, m)
        k = min(T.DEFAULT_DEGREE, len(ctrl) - 1)
        knots = np.r_[np.zeros(k), np.linspace(0.0, 10.0, len(ctrl) - k + 1), np.full(k, 10.0)]
        spl = BSpline(knots, ctrl, k)
        sel = rows == m
        np.testing.assert_allclose(p[sel], spl(t[sel]), atol=1e-9)
        np.testing.assert_allclose(v[sel], spl(t[sel], 1), atol=1e-8)
        np.testing.assert_allclose(a[sel], spl(t[sel], 2), atol=1e-7)


def test_interpolating_kind_passes_through_waypoints(interp):
    assert np.all(interp.kind == T.INTERPOLATING)
    for m in range(len(interp)):
        n = interp.n_knots[m]
        t = interp.knot_times_s[m, :n]
        np.testing.assert_allclose(t, np.arange(n) * 10.0 / (n - 1), rtol=0, atol=1e-12)
        p, _, _ = interp.evaluate(t, np.full(n, m))
        np.testing.assert_allclose(p, interp.knot_poses[m, :n], atol=1e-10)
        cs = CubicSpline(t, interp.knot_poses[m, :n], bc_type="clamped")
        tt = np.linspace(0, 10, 53)
        np.testing.assert_allclose(interp.evaluate(tt, np.full(53, m))[1], cs(tt, 1), atol=1e-9)


@pytest.mark.parametrize("which", ["traj", "interp"])
def test_starts_at_rest_and_ends_at_rest(which, request):
    tr = request.getfixturevalue(which)
    m = len(tr)
    p, v, a = tr.evaluate(np.zeros(m))
    assert np.abs(p).max() < 1e-12 and np.abs(v).max() < 1e-10
    if which == "traj":  # triple end control points: the acceleration is zero too (C2 with the rest)
        assert np.abs(a).max() < 1e-9
    p_end, v_end, _ = tr.evaluate(np.full(m, 10.0))
    np.testing.assert_allclose(v_end, 0.0, atol=1e-12)
    _, v_before, a_before = tr.evaluate(np.full(m, 10.0 - 1e-7))
    assert np.abs(v_before).max() < 1e-4
    if which == "traj":
        assert np.abs(a_before).max() < 1e-4
        ends = np.array([tr.knot_poses[r, tr.n_knots[r] - 1] for r in range(m)])
        np.testing.assert_allclose(p_end, ends, atol=1e-9)  # it ends at the last waypoint
    p_after, v_after, a_after = tr.evaluate(np.full(m, 25.0))
    np.testing.assert_array_equal(p_after, p_end)
    assert np.all(v_after == 0.0) and np.all(a_after == 0.0)
    p_neg, _, _ = tr.evaluate(np.full(m, -3.0))
    assert np.all(p_neg == 0.0)


@pytest.mark.parametrize("which", ["traj", "interp"])
def test_c2_continuity_at_breaks(which, request):
    tr = request.getfixturevalue(which)
    eps = 1e-7
    worst = np.zeros(3)
    checked = 0
    for m in range(0, len(tr), 7):
        inner = tr.breaks_s[m, 1 : tr.n_segments[m]]
        checked += len(inner)
        rows = np.full(len(inner), m)
        left = tr.evaluate(inner - eps, rows)
        right = tr.evaluate(inner + eps, rows)
        for i in range(3):
            worst[i] = max(worst[i], np.abs(left[i] - right[i]).max(initial=0.0))
    assert checked > 10
    # jumps would be O(1); continuous quantities differ by O(eps * next derivative)
    assert worst[0] < 1e-5 and worst[1] < 1e-4 and worst[2] < 1e-3, worst


def test_reproducible_and_seed_dependent():
    a = T.sample(50, T.TRAIN_RANGES, np.random.default_rng(7))
    b = T.sample(50, T.TRAIN_RANGES, np.random.default_rng(7))
    c = T.sample(50, T.TRAIN_RANGES, np.random.default_rng(8))
    for name in ("knot_times_s", "knot_poses", "coeffs", "breaks_s", "n_waypoints"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert not np.array_equal(np.nan_to_num(a.knot_poses), np.nan_to_num(c.knot_poses))


def test_spline_spec_rejects_bad_kind_and_degree():
    with pytest.raises(ValueError, match="unknown trajectory kind"):
        T.SplineSpec("bezier")
    with pytest.raises(ValueError, match="degree"):
        T.SplineSpec(degree=2)


def test_subset_and_replace_rows(traj):
    sub = traj.subset([3, 10])
    t = np.array([2.5, 7.1])
    np.testing.assert_array_equal(sub.evaluate(t)[0], traj.evaluate(t, [3, 10])[0])
    small = T.sample(4, T.TEST_RANGES, np.random.default_rng(2), n_waypoints=4)
    big = T.sample(2, T.TEST_RANGES, np.random.default_rng(3), n_waypoints=16)
    small.replace_rows([1, 2], big)
    assert small.knot_times_s.shape[1] == 17
    t = np.full(4, 6.3)
    ref = T.sample(4, T.TEST_RANGES, np.random.default_rng(2), n_waypoints=4).evaluate(t)[0]
    p = small.evaluate(t)[0]
    np.testing.assert_array_equal(p[[0, 3]], ref[[0, 3]])
    np.testing.assert_array_equal(p[[1, 2]], big.evaluate(t[:2])[0])
    assert list(small.n_waypoints) == [4, 16, 16, 4]


def test_device_copy_evaluates_as_the_host_set_and_takes_new_rows():
    """DevicePoly (what the env's step evaluates) gives the host PiecewisePoly's pose and velocity,
    bit for bit, before and after rows of other shapes (more segments, another degree) replace some."""
    import torch

    from lasmp.envs.trajectories.device import DevicePoly

    rng = np.random.default_rng(0)
    ranges = T.ranges_for_split("train")
    host = T.sample(6, ranges, rng, n_waypoints=5)
    dev = DevicePoly(host, "cpu", torch.float64)
    t = np.concatenate([rng.uniform(0.0, 12.0, 18), [0.0, 10.0, 25.0]])  # inside, at the ends, past the end
    rows = np.arange(len(t)) % 6

    def check():
        pos, vel, _ = host.evaluate(t, rows)
        pos_d, vel_d = dev.evaluate(torch.from_numpy(t), torch.from_numpy(rows))
        np.testing.assert_array_equal(pos_d.numpy(), pos)
        np.testing.assert_array_equal(vel_d.numpy(), vel)
        pos_only, none = dev.evaluate(torch.from_numpy(t), torch.from_numpy(rows), velocity=False)
        assert none is None
        np.testing.assert_array_equal(pos_only.numpy(), pos)

    check()
    longer = T.sample(2, ranges, rng, n_waypoints=15)  # more segments than the set holds
    poses = 0.1 * rng.normal(size=(1, 40, 6))
    poses[:, 0] = 0.0  # a trajectory starts at the platform's initial pose
    user = T.from_samples(np.linspace(0.0, 10.0, 40), poses)  # cubic: lower degree
    for ids, new in (([1, 4], longer), ([2], user)):
        host.replace_rows(np.array(ids), new)
        dev.replace_rows(torch.tensor(ids), new)
        check()
    assert dev.coeffs.shape[1] == host.coeffs.shape[1] > 5
