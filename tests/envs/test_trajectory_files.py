"""Trajectory files and user samples (fast): a set saved and loaded unchanged, user-made samples
turned into a set (bad ones refused), and each kind of malformed file refused with a message that
names it."""

import os

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from lasmp.envs import trajectories as T


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
