"""Tests for lasmp.eval.benchmark (the evaluation set Xi_eval; fast, small sizes)."""

import hashlib
import io
import json
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from lasmp.config.base import DomainRandCfg
from lasmp.eval import benchmark as B

REPO = Path(__file__).resolve().parents[2]
M, R = 64, 16


@pytest.fixture(scope="module")
def bench():
    return B.generate(M, R, seed=3)


@pytest.fixture(scope="module")
def saved(bench, tmp_path_factory):
    path = tmp_path_factory.mktemp("bench") / "b.npz"
    B.save(path, bench)
    return path


def _eval_grid(traj, times):
    m = len(traj)
    pos, vel, acc = traj.evaluate(np.tile(times, m), np.repeat(np.arange(m), len(times)))
    return np.stack([pos, vel, acc])


def _rewrite(src, dst, change):
    """Copy the npz at src to dst with the arrays dict passed through change(dict) -> dict."""
    with np.load(src, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    data = change(data)
    with zipfile.ZipFile(dst, "w") as zf:
        for k, a in data.items():
            buf = io.BytesIO()
            np.lib.format.write_array(buf, a, allow_pickle=False)
            zf.writestr(f"{k}.npy", buf.getvalue())
    return dst


def test_same_seed_same_bytes_different_seed_different(tmp_path):
    a, b, c = tmp_path / "a.npz", tmp_path / "sub" / "b.npz", tmp_path / "c.npz"
    B.save(a, B.generate(M, R, seed=7))
    B.save(b, B.generate(M, R, seed=7))
    B.save(c, B.generate(M, R, seed=8))
    assert a.read_bytes() == b.read_bytes()
    assert B.sha256(a) == B.sha256(b) == hashlib.sha256(a.read_bytes()).hexdigest()
    assert a.read_bytes() != c.read_bytes() and B.sha256(a) != B.sha256(c)
    # the atomic write leaves no temporary file (lasmp.io.atomic names them ".<name>.<random>.tmp")
    assert sorted(p.name for p in tmp_path.rglob("*") if p.is_file()) == ["a.npz", "b.npz", "c.npz"]
    assert list(tmp_path.rglob("*.tmp")) == []


def test_roundtrip_bit_identical(bench, saved):
    back = B.load(saved)
    assert back.seed == 3 and back.num_trajectories == M and back.num_robots == R
    times = np.array([0.0, 0.013, 1.7, 5.0, 9.99, 10.0, 12.0])
    assert np.array_equal(_eval_grid(bench.trajectories, times), _eval_grid(back.trajectories, times))
    assert np.array_equal(bench.trajectories.n_waypoints, back.trajectories.n_waypoints)
    for _, (name, _) in B.ROBOT_FIELDS.items():
        assert np.array_equal(getattr(bench.robots, name), getattr(back.robots, name)), name
    with np.load(saved) as z:  # an ordinary npz with the documented keys
        assert str(z["format"]) == "lasmp-benchmark" and int(z["version"]) == 2
        assert str(z["spline"]) == "approximating" and int(z["spline_degree"]) == B.T.DEFAULT_DEGREE
        traj_keys = ("knot_times_s", "waypoints", "n_waypoints", "spline", "spline_degree")
        assert set(z.files) == {"format", "version", "seed", *traj_keys, *B.ROBOT_FIELDS}


def test_ranges(bench):
    test = DomainRandCfg().test
    for _, (name, shape) in B.ROBOT_FIELDS.items():
        lo, hi = getattr(test, name)
        v = getattr(bench.robots, name)
        assert v.shape == (R, *shape)
        assert np.all((v >= lo) & (v <= hi)), name
    nw = bench.trajectories.n_waypoints
    assert nw.min() >= 4 and nw.max() <= 16
    assert len(np.unique(B.generate(2000, 1, seed=0).trajectories.n_waypoints)) == 13  # all of 4..16
    # robots come from their own stream: independent of the number of trajectories
    other = B.generate(M + 5, R, seed=3)
    assert np.array_equal(other.robots.joint_kp, bench.robots.joint_kp)


def test_pairing_and_subset(bench):
    k = np.arange(M)
    traj_rows, robot_rows = bench.pairing(k)
    assert np.array_equal(traj_rows, k) and np.array_equal(robot_rows, k % R)
    with pytest.raises(IndexError):
        bench.pairing([M])
    sub = bench.subset(10)
    assert sub.num_trajectories == 10 and sub.robots is bench.robots and sub.seed == bench.seed
    times = np.array([0.5, 3.3, 9.0])
    assert np.array_equal(
        _eval_grid(sub.trajectories, times), _eval_grid(bench.trajectories.subset(range(10)), times)
    )
    with pytest.raises(ValueError):
        bench.subset(M + 1)


def test_missing_file(tmp_path):
    with pytest.raises(B.BenchmarkFileError, match="no such benchmark file"):
        B.load(tmp_path / "nope.npz")


def test_not_a_zip(tmp_path):
    p = tmp_path / "x.npz"
    p.write_bytes(b"hello, not a zip")
    with pytest.raises(B.BenchmarkFileError, match="not an .npz"):
        B.load(p)


def test_wrong_format(saved, tmp_path):
    p = _rewrite(saved, tmp_path / "f.npz", lambda d: {**d, "format": np.array("lasmp-trajectories")})
    with pytest.raises(B.BenchmarkFileError, match="format") as e:
        B.load(p)
    assert str(p) in str(e.value)


def test_old_version_is_refused_with_the_command_to_regenerate(saved, tmp_path):
    p = _rewrite(saved, tmp_path / "v1.npz", lambda d: {**d, "version": np.array(1, dtype=np.int64)})
    with pytest.raises(
        B.BenchmarkFileError, match=r"v1\.npz: unsupported version 1, expected 2.*benchmark generate"
    ):
        B.load(p)


def test_missing_key(saved, tmp_path):
    p = _rewrite(saved, tmp_path / "k.npz", lambda d: {k: v for k, v in d.items() if k != "robot_joint_kd"})
    with pytest.raises(B.BenchmarkFileError, match="missing key 'robot_joint_kd'"):
        B.load(p)


def test_nan_in_robot_array(saved, tmp_path):
    def change(d):
        a = d["robot_foot_friction"].copy()
        a[2] = np.nan
        return {**d, "robot_foot_friction": a}

    with pytest.raises(B.BenchmarkFileError, match="non-finite.*robot_foot_friction"):
        B.load(_rewrite(saved, tmp_path / "n.npz", change))


def test_wrong_shape(saved, tmp_path):
    p = _rewrite(
        saved, tmp_path / "s.npz", lambda d: {**d, "robot_com_shift_m": d["robot_com_shift_m"][:, :2]}
    )
    with pytest.raises(B.BenchmarkFileError, match="wrong shape.*robot_com_shift_m"):
        B.load(p)


def test_cli_generate_json(tmp_path):
    out = tmp_path / "cli.npz"
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "lasmp.eval.benchmark",
            "generate",
            "--out",
            str(out),
            "--seed",
            "3",
            "--num-trajectories",
            str(M),
            "--num-robots",
            str(R),
            "--json",
        ],
        capture_output=True,
        text=True,
        check=True,
        cwd=REPO,
        timeout=120,
    )
    info = json.loads(res.stdout)
    assert info["sha256"] == B.sha256(out) and info["bytes"] == out.stat().st_size
    assert info["num_trajectories"] == M and info["num_robots"] == R and info["seed"] == 3
    st = info["statistics"]
    assert st["overall"]["num"] == M and sum(b["num"] for b in st["per_n"].values()) == M
    assert set(st["per_n"]) <= {str(n) for n in range(4, 17)}
    # same seed and sizes as the fixture: the library and the CLI write the same bytes
    lib = tmp_path / "lib.npz"
    B.save(lib, B.generate(M, R, seed=3))
    assert lib.read_bytes() == out.read_bytes()
