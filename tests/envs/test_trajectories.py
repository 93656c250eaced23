"""Tests for lasmp.envs.trajectories (fast)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import BSpline, CubicSpline
from scipy.spatial import Delaunay

from lasmp.envs import trajectories as T

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def traj():
    return T.sample(300, T.TEST_RANGES, np.random.default_rng(123))


def _eval_all(tr, t):
    """Evaluate every row at each time of t: arrays (M, len(t), 6)."""
    m = len(tr)
    p, v, a = tr.evaluate(np.tile(t, m), np.repeat(np.arange(m), len(t)))
    return (x.reshape(m, len(t), 6) for x in (p, v, a))


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


def test_testing_split_matches_the_papers_statistics():
    """docs/trajectories.md: the paper's testing set has a mean path length of 7.12 m and mean speed of 0.69 m/s."""
    st = T.statistics(T.sample(2000, T.TEST_RANGES, np.random.default_rng(11)))["overall"]
    assert st["mean_path_length_m"] == pytest.approx(7.12, rel=0.10)
    assert st["mean_speed_mps"] == pytest.approx(0.69, rel=0.10)
    assert st["max_speed_mps"] < 15.0 and st["p99_acceleration_mps2"] > 0.0


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


def test_more_waypoints_longer_paths():
    rng = np.random.default_rng(1)
    stats = T.statistics(T.sample(400, T.TEST_RANGES, rng, n_waypoints=np.repeat([4, 16], 200)))
    few, many = stats["per_n"]["4"], stats["per_n"]["16"]
    assert many["mean_path_length_m"] > 1.5 * few["mean_path_length_m"]
    assert many["mean_speed_mps"] > few["mean_speed_mps"]
    assert stats["overall"]["num"] == 400 and few["num"] == 200


def test_statistics_of_a_straight_line():
    # a straight segment: length known, curvature ~0
    t = np.linspace(0.0, 4.0, 41)
    poses = np.zeros((1, 41, 6))
    poses[0, :, 0] = 0.5 * t  # x = 0.5 t  -> 2 m in 4 s
    st = T.statistics(T.from_samples(t, poses))
    assert st["overall"]["mean_path_length_m"] == pytest.approx(2.0, abs=1e-9)
    assert st["overall"]["mean_speed_mps"] == pytest.approx(0.5, abs=1e-9)
    assert st["overall"]["mean_curvature_per_m"] == pytest.approx(0.0, abs=1e-6)
    assert list(st["per_n"]) == ["-1"]


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


def test_save_load_round_trip(tmp_path, traj):
    path = tmp_path / "bench"  # no suffix: must be used verbatim
    T.save(path, traj, meta={"seed": 123})
    assert path.exists() and not (tmp_path / "bench.npz").exists()
    assert [f for f in os.listdir(tmp_path) if f.startswith(".tmp")] == []
    back = T.load(path)
    assert back.meta["seed"] == 123
    t = np.random.default_rng(0).uniform(-1, 11, size=len(traj))
    for x, y in zip(traj.evaluate(t), back.evaluate(t), strict=True):
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(back.n_waypoints, traj.n_waypoints)
    T.save(tmp_path / "again.npz", back)
    again = T.load(tmp_path / "again.npz")
    np.testing.assert_array_equal(again.coeffs, traj.coeffs)


def _user_samples(m=3, k=30, seed=0):
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 6.0, k)
    poses = np.cumsum(rng.normal(0, 0.05, size=(m, k, 6)), axis=1)
    poses -= poses[:, :1]
    return t, poses


def test_user_samples_round_trip(tmp_path):
    t, poses = _user_samples()
    u = T.from_samples(t, poses)
    assert list(u.n_waypoints) == [-1, -1, -1]
    np.testing.assert_allclose(u.duration_s, 6.0)
    p, _, _ = u.evaluate(np.tile(t, 3), np.repeat(np.arange(3), len(t)))
    np.testing.assert_allclose(p.reshape(3, len(t), 6), poses, atol=1e-12)
    cs = CubicSpline(t, poses[2])  # not-a-knot
    tt = np.linspace(0, 6, 77)
    np.testing.assert_allclose(u.evaluate(tt, np.full(77, 2))[0], cs(tt), atol=1e-10)
    T.save(tmp_path / "user.npz", u)
    with np.load(tmp_path / "user.npz") as z:
        assert str(z["kind"]) == "samples" and z["t_s"].shape == (30,)
    back = T.load(tmp_path / "user.npz")
    for x, y in zip(u.evaluate(np.full(3, 2.2)), back.evaluate(np.full(3, 2.2)), strict=True):
        np.testing.assert_array_equal(x, y)


def test_from_samples_rejects_bad_input():
    t, poses = _user_samples()
    bad = poses.copy()
    bad[1, 0, 2] = 0.3
    with pytest.raises(T.TrajectoryFileError, match="initial pose"):
        T.from_samples(t, bad)
    with pytest.raises(T.TrajectoryFileError, match="strictly increasing"):
        T.from_samples(np.r_[t[:5], t[4], t[6:]], poses)
    with pytest.raises(T.TrajectoryFileError, match="start at 0"):
        T.from_samples(t + 1.0, poses)
    with pytest.raises(T.TrajectoryFileError, match=r"\(M, K, 6\)"):
        T.from_samples(t, poses[..., :5])
    inf = poses.copy()
    inf[0, 3, 1] = np.inf
    with pytest.raises(T.TrajectoryFileError, match="finite"):
        T.from_samples(t, inf)


# ---- malformed files: one test per kind of problem ------------------------------------------
def _write_waypoints_file(path, **override):
    tr = T.sample(5, T.TEST_RANGES, np.random.default_rng(0))
    d = {
        "format": np.array(T.FORMAT_NAME),
        "version": np.array(T.FORMAT_VERSION),
        "kind": np.array("waypoints"),
        "spline": np.array("approximating"),
        "spline_degree": np.array(T.DEFAULT_DEGREE),
        "knot_times_s": tr.knot_times_s.copy(),
        "waypoints": tr.knot_poses.copy(),
        "n_waypoints": tr.n_waypoints.copy(),
    }
    d.update(override)
    d = {k: v for k, v in d.items() if v is not None}
    np.savez(path, **d)
    return tr


def test_file_missing_key(tmp_path):
    p = tmp_path / "f.npz"
    _write_waypoints_file(p, n_waypoints=None)
    with pytest.raises(T.TrajectoryFileError, match=r"f\.npz.*missing key 'n_waypoints'"):
        T.load(p)


def test_file_wrong_format_and_version(tmp_path):
    p = tmp_path / "f.npz"
    _write_waypoints_file(p, format=np.array("something-else"))
    with pytest.raises(T.TrajectoryFileError, match="format"):
        T.load(p)
    _write_waypoints_file(p, version=np.array(3))
    with pytest.raises(T.TrajectoryFileError, match="unsupported version 3, expected 2"):
        T.load(p)


def test_old_version_file_gets_a_clear_error(tmp_path):
    """A version-1 file (the old interpolating generator, no construction recorded) is never misread."""
    p = tmp_path / "old.npz"
    _write_waypoints_file(p, version=np.array(1), spline=None, spline_degree=None)
    with pytest.raises(
        T.TrajectoryFileError, match=r"old\.npz: unsupported version 1, expected 2.*Regenerate"
    ):
        T.load(p)


def test_file_records_the_construction(tmp_path):
    p = tmp_path / "s.npz"
    for spec in (T.SplineSpec(), T.SplineSpec("interpolating"), T.SplineSpec(degree=5)):
        tr = T.sample(6, T.TEST_RANGES, np.random.default_rng(4), spline=spec)
        T.save(p, tr)
        with np.load(p) as z:
            assert str(z["spline"]) == spec.kind and int(z["spline_degree"]) == spec.degree
        back = T.load(p)
        t = np.full(6, 3.3)
        np.testing.assert_array_equal(back.evaluate(t)[0], tr.evaluate(t)[0])
    _write_waypoints_file(p, spline=np.array("bezier"))
    with pytest.raises(T.TrajectoryFileError, match="unknown trajectory kind 'bezier'"):
        T.load(p)


def test_file_nan_in_waypoints(tmp_path):
    p = tmp_path / "f.npz"
    tr = T.sample(5, T.TEST_RANGES, np.random.default_rng(0))
    wp = tr.knot_poses.copy()
    wp[2, 2, 4] = np.nan
    _write_waypoints_file(p, waypoints=wp)
    with pytest.raises(T.TrajectoryFileError, match="NaN in the poses"):
        T.load(p)


def test_file_non_increasing_times(tmp_path):
    p = tmp_path / "f.npz"
    tr = T.sample(5, T.TEST_RANGES, np.random.default_rng(0))
    t = tr.knot_times_s.copy()
    t[1, 3] = t[1, 2]
    _write_waypoints_file(p, knot_times_s=t)
    with pytest.raises(T.TrajectoryFileError, match="strictly increasing"):
        T.load(p)


def test_file_not_starting_at_zero_pose(tmp_path):
    p = tmp_path / "f.npz"
    tr = T.sample(5, T.TEST_RANGES, np.random.default_rng(0))
    wp = tr.knot_poses.copy()
    wp[0, 0, 0] = 0.2
    _write_waypoints_file(p, waypoints=wp)
    with pytest.raises(T.TrajectoryFileError, match="initial pose"):
        T.load(p)


def test_file_wrong_shape(tmp_path):
    p = tmp_path / "f.npz"
    tr = T.sample(5, T.TEST_RANGES, np.random.default_rng(0))
    _write_waypoints_file(p, waypoints=tr.knot_poses[..., :3].copy())
    with pytest.raises(T.TrajectoryFileError, match=r"\(M, K, 6\)"):
        T.load(p)


def test_file_not_npz_or_truncated(tmp_path):
    txt = tmp_path / "notes.npz"
    txt.write_text("hello")
    with pytest.raises(T.TrajectoryFileError, match=r"notes\.npz.*not a readable \.npz"):
        T.load(txt)
    good = tmp_path / "good.npz"
    T.save(good, T.sample(20, T.TEST_RANGES, np.random.default_rng(0)))
    cut = tmp_path / "cut.npz"
    cut.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    with pytest.raises(T.TrajectoryFileError, match=r"cut\.npz"):
        T.load(cut)
    npy = tmp_path / "arr.npy"
    np.save(npy, np.zeros(3))
    with pytest.raises(T.TrajectoryFileError, match="not an .npz"):
        T.load(npy)
    with pytest.raises(T.TrajectoryFileError, match="no such"):
        T.load(tmp_path / "absent.npz")


# ---- CLI ------------------------------------------------------------------------------------
def _cli(*args):
    return subprocess.run(
        [sys.executable, "-m", "lasmp.envs.trajectories", *args],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_cli_stats_json():
    r = _cli("stats", "--split", "test", "--num", "200", "--seed", "0", "--json")
    assert r.returncode == 0, r.stderr
    st = json.loads(r.stdout)
    assert st["num"] == 200
    for block in [st["overall"], *st["per_n"].values()]:
        for key in T.STAT_COLUMNS:
            assert key in block
    assert set(st["per_n"]) <= {str(n) for n in range(4, 17)}
    assert sum(b["num"] for b in st["per_n"].values()) == 200


def test_cli_bad_arguments():
    r = _cli("stats", "--split", "val")
    assert r.returncode == 2 and "invalid choice" in r.stderr


def test_cli_plot_and_generate(tmp_path):
    out = tmp_path / "traj.png"
    r = _cli("plot", "--out", str(out), "--num", "30")
    assert r.returncode == 0, r.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    f = tmp_path / "set.npz"
    r = _cli("generate", "--split", "train", "--num", "20", "--seed", "5", "--out", str(f))
    assert r.returncode == 0, r.stderr
    loaded = T.load(f)
    ref = T.sample(20, T.TRAIN_RANGES, np.random.default_rng(5))
    np.testing.assert_array_equal(loaded.coeffs, ref.coeffs)
    assert loaded.meta == {"split": "train", "seed": 5, "num": 20}


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


def test_statistics_of_long_recordings_evaluate_in_passes_of_bounded_size(monkeypatch):
    """60 rows of 200 s at dt 0.02 (600,600 samples): more than one pass allows, so two passes, with
    the same statistics as one row per pass."""
    from lasmp.envs.trajectories import stats as S

    t = np.linspace(0.0, 200.0, 41)
    poses = np.zeros((60, len(t), 6))
    poses[:, :, 0] = 0.05 * t * np.linspace(0.5, 1.5, 60)[:, None]
    traj = T.from_samples(t, poses)
    sizes = []
    evaluate = type(traj).evaluate
    monkeypatch.setattr(
        type(traj), "evaluate", lambda self, *a: sizes.append(len(a[0])) or evaluate(self, *a)
    )
    st = T.statistics(traj)
    assert len(sizes) == 2 and max(sizes) <= S._CHUNK_SAMPLES
    assert st == T.statistics(traj, chunk=1)
