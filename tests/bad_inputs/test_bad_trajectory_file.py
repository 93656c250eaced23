"""Trajectory files (`lasmp.envs.trajectories.load`): unreadable, malformed or unphysical files are
refused (or warned about) naming the file and the problem; physical ones load."""

from __future__ import annotations

import io
import math
import os
import struct
import time
import warnings
import zipfile
import zlib
from pathlib import Path

import numpy as np
import pytest
from badkit import (
    _generated,
    _line_samples,
    _pose_far,
    _raw,
    _samples,
    _traj_case,
    _waypoint_far,
    call,
    files,
    refused,
)

from lasmp.envs import trajectories as trj


# -- trajectory files ----------------------------------------------------------------------------
def _set(**values):
    return lambda a: a.update({k: np.array(v) for k, v in values.items()})


def _times_nan_inside(a):
    a["t_s"][3] = np.nan


def _times_reversed(a):
    a["t_s"][3], a["t_s"][4] = a["t_s"][4], a["t_s"][3]


def _times_late(a):
    a["t_s"] += 1.0


def _pose_start_off(a):
    a["poses"][0, 0, 2] = 0.5


def _pose_inf(a):
    a["poses"][0, 4, 1] = np.inf


def _yaw_many_turns(a):
    a["poses"][0, 5, 5] = 1e4


def _fast_jump(a):
    a["poses"][0, 5:, 0] += 100.0  # 100 m in one second


def _path_in_a_tenth(a):
    a["knot_times_s"] = a["knot_times_s"] / 100.0  # the whole 10 s path in 0.1 s


def _count_off(a):
    a["n_waypoints"] = a["n_waypoints"] + 1


def _drop(key):
    return lambda a: a.pop(key)


def _truncated_npz(path: Path) -> Path:
    _traj_case("waypoints")(path)
    path.write_bytes(path.read_bytes()[:300])
    return path


def _single_npy(path: Path) -> Path:
    with open(path, "wb") as f:
        np.save(f, np.zeros(3))
    return path


TRAJECTORY_REFUSED = {
    "a missing file": (lambda path: path, "no such trajectory file"),
    "a FIFO, which would block": (lambda path: os.mkfifo(path) or path, "not a regular file"),
    "a text file": (_raw(b"x, y, z\n0, 0, 0\n"), "not a readable .npz"),
    "a truncated file": (_truncated_npz, "not a readable .npz"),
    "a single .npy array": (_single_npy, "single .npy"),
    "no format key": (_traj_case("samples", _drop("format")), "missing key 'format'"),
    "another format": (_traj_case("samples", _set(format="something-else")), "format is"),
    "version 1": (_traj_case("waypoints", _set(version=1)), "unsupported version 1"),
    "version 3": (_traj_case("waypoints", _set(version=3)), "unsupported version 3"),
    "an unknown kind": (_traj_case("samples", _set(kind="spline")), "unknown kind"),
    "NaN inside the times": (_traj_case("samples", _times_nan_inside), "NaN"),
    "times out of order": (_traj_case("samples", _times_reversed), "strictly increasing"),
    "times that start late": (_traj_case("samples", _times_late), "start at 0"),
    "a path that starts away from the platform": (_traj_case("samples", _pose_start_off), "initial pose"),
    "an infinite pose": (_traj_case("samples", _pose_inf), "finite"),
    "poses of 5 values": (_traj_case("samples", lambda a: a.update(poses=a["poses"][..., :5])), "poses"),
    "integer times": (_traj_case("samples", lambda a: a.update(t_s=np.arange(11))), "float"),
    "a waypoint count that disagrees": (_traj_case("waypoints", _count_off), "n_waypoints"),
    "an unknown spline": (_traj_case("waypoints", _set(spline="bezier")), "bezier"),
    "meta that is not JSON": (_traj_case("samples", _set(meta_json="{not json")), "meta_json"),
    "no waypoints": (_traj_case("waypoints", _drop("waypoints")), "missing key 'waypoints'"),
    "a sample 1,000 km away": (_traj_case("samples", _pose_far), "physical range"),
    "a waypoint 1,000 km away": (_traj_case("waypoints", _waypoint_far), "physical range"),
    "a yaw of 10,000 rad": (_traj_case("samples", _yaw_many_turns), "physical range"),
}


@pytest.mark.parametrize("case", sorted(TRAJECTORY_REFUSED))
def test_a_bad_trajectory_file_is_refused_naming_the_file_and_the_problem(tmp_path, case):
    make, pattern = TRAJECTORY_REFUSED[case]
    path = make(tmp_path / "traj.npz")
    before = files(tmp_path)
    with pytest.raises(trj.TrajectoryFileError, match=pattern) as err:
        trj.load(path)
    assert str(path) in str(err.value)
    assert files(tmp_path) == before


TRAJECTORY_ABSURD = {
    "a whole generated path in 0.1 s": _traj_case("waypoints", _path_in_a_tenth),
    "a whole user path in 0.1 s": _traj_case(
        "samples", lambda a: a.update(t_s=a["t_s"] / 100.0, poses=a["poses"] * 10.0)
    ),
    "100 m in a second": _traj_case("samples", _fast_jump),
}


@pytest.mark.parametrize("case", sorted(TRAJECTORY_ABSURD))
def test_a_trajectory_far_outside_any_physical_motion_is_refused_or_warned_about(tmp_path, case):
    path = TRAJECTORY_ABSURD[case](tmp_path / "traj.npz")
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        try:
            trj.load(path)
        except trj.TrajectoryFileError as err:
            assert "physical range" in str(err) and str(path) in str(err)
            return
    assert any("physical range" in str(w.message) and str(path) in str(w.message) for w in seen), [
        str(w.message) for w in seen
    ]


@pytest.mark.parametrize("kind", ["a generated set", "a 360 m train ride at 18 m/s"])
def test_a_physical_trajectory_file_loads_without_a_warning(tmp_path, kind):
    path = tmp_path / "traj.npz"
    if kind == "a generated set":
        np.savez(path, **_generated(50))
    else:
        t = np.linspace(0.0, 20.0, 2001)
        poses = np.zeros((1, len(t), 6))
        poses[0, :, 0] = 18.0 * t
        np.savez(path, **_samples(t, poses))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        trj.load(path)


# -- an .npz member's size, checked from its header before it is loaded (B_bomb, J07) ------------
MIB = 1 << 20


def bomb_npz(path: Path, arrays: dict, key: str, shape: tuple[int, ...], data_mib: int | None = None) -> Path:
    """An .npz of `arrays` whose member `key` is a float64 array of zeros of `shape`, deflated: 2 GiB
    of zeros take 2 MB. `data_mib`: the MiB of zeros that really follow the header (default: all it
    declares; fewer: a header that lies). Built by hand in a moment: after a full flush the deflate
    state is reset, so every MiB of zeros compresses to the same block. Its CRC is left 0: a reader
    that checks the header first never reads that far (the old one inflated it all, then failed)."""
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": shape})
    header = header.getvalue()
    mib = math.prod(shape) * 8 // MIB if data_mib is None else data_mib
    c = zlib.compressobj(9, zlib.DEFLATED, -15)
    head = c.compress(header) + c.flush(zlib.Z_FULL_FLUSH)
    block = c.compress(bytes(MIB)) + c.flush(zlib.Z_FULL_FLUSH)
    data = head + block * mib + c.flush()
    size, name = len(header) + mib * MIB, f"{key}.npy".encode()
    assert size < 2**32  # no zip64 needed
    local = struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, 8, 0, 0x21, 0, len(data), size, len(name), 0)
    central = struct.pack(
        "<IHHHHHHIIIHHHHHII",
        0x02014B50,
        20,
        20,
        0,
        8,
        0,
        0x21,
        0,
        len(data),
        size,
        len(name),
        0,
        0,
        0,
        0,
        0,
        0,
    )
    with open(path, "wb") as f:
        f.write(local + name + data)
        offset = f.tell()
        f.write(central + name)
        f.write(struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, 1, 1, len(central + name), offset, 0))
    with zipfile.ZipFile(path, "a") as zf:
        for k, a in arrays.items():
            if k != key:
                buf = io.BytesIO()
                np.lib.format.write_array(buf, a, allow_pickle=False)
                zf.writestr(f"{k}.npy", buf.getvalue())
    return path


NPZ_REFUSED = {
    "2 GiB of waypoints in a 2 MB file": (
        lambda p: bomb_npz(p, _generated(), "waypoints", (2**28,)),
        r"more than 1\.0 GiB in memory \('waypoints': a float64 array of shape \(268435456,\), 2\.0 GiB\)",
    ),
    "a header that declares 8 GiB of poses": (
        lambda p: bomb_npz(p, _samples(*_line_samples()), "poses", (2**30,), data_mib=8),
        r"'poses': a float64 array of shape \(1073741824,\), 8\.0 GiB",
    ),
    "a header that declares more than the member holds": (
        lambda p: bomb_npz(p, _generated(), "waypoints", (4 * MIB,), data_mib=1),
        r"member 'waypoints\.npy' holds \d+ bytes, but its header declares .*truncated or corrupt",
    ),
}


@pytest.mark.parametrize("case", sorted(NPZ_REFUSED))
def test_an_npz_member_too_large_or_lying_is_refused_from_its_header_before_loading(tmp_path, case):
    make, pattern = NPZ_REFUSED[case]
    path = make(tmp_path / "traj.npz")
    assert path.stat().st_size < 3 * MIB
    started = time.monotonic()
    with pytest.raises(trj.TrajectoryFileError, match=pattern) as err:
        trj.load(path)
    assert time.monotonic() - started < 2.0 and str(path) in str(err.value)


def test_trajectories_stats_of_a_bomb_gives_one_line_in_a_moment(tmp_path):
    """J07: `python -m lasmp.envs.trajectories stats --file` spent 37 s and 8 GiB on such a file."""
    path = bomb_npz(tmp_path / "traj.npz", _generated(), "waypoints", (2**28,))
    started = time.monotonic()
    out = call(trj.main, ["stats", "--file", str(path)])
    refused(out, r"traj\.npz: its arrays would take more than 1\.0 GiB")
    assert time.monotonic() - started < 5.0 and len(out.text.strip().splitlines()) == 1, out.text


def test_a_generated_set_within_the_limit_still_loads(tmp_path):
    np.savez_compressed(tmp_path / "traj.npz", **_generated(20))  # compressed members are fine
    assert len(trj.load(tmp_path / "traj.npz")) == 20
