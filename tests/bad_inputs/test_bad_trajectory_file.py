"""Trajectory files (`lasmp.envs.trajectories.load`): unreadable, malformed or unphysical files are
refused (or warned about) naming the file and the problem; physical ones load."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from badkit import _generated, _pose_far, _raw, _samples, _traj_case, _waypoint_far, files

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
