"""Benchmark files (`lasmp.eval.benchmark.load`): a bad file is refused naming the file and the
problem; a sound one loads."""

from __future__ import annotations

import numpy as np
import pytest
from badkit import _bench_case, _raw, _scale, _waypoint_far

from lasmp.eval import benchmark as bm

# -- benchmark files -----------------------------------------------------------------------------
BENCHMARK_REFUSED = {
    "a missing file": (lambda path: path, "no such benchmark file"),
    "a text file": (_raw(b"not a benchmark"), "not an .npz"),
    "another format": (_bench_case(lambda a: a.update(format=np.array("lasmp-trajectories"))), "format is"),
    "version 1": (_bench_case(lambda a: a.update(version=np.array(1))), "unsupported version 1"),
    "no joint gains": (_bench_case(lambda a: a.pop("robot_joint_kp")), "missing key 'robot_joint_kp'"),
    "a NaN gain": (_bench_case(_scale("robot_joint_kp", np.nan)), "non-finite"),
    "damping of 11 joints": (
        _bench_case(lambda a: a.update(robot_joint_kd=a["robot_joint_kd"][:, :11])),
        "wrong shape",
    ),
    "a negative trunk mass": (_bench_case(_scale("robot_trunk_mass_kg", -4.0)), "robot_trunk_mass_kg"),
    "a trunk without mass": (_bench_case(_scale("robot_trunk_mass_kg", 0.0)), "robot_trunk_mass_kg"),
    "a trunk of 1,000 t": (_bench_case(_scale("robot_trunk_mass_kg", 1e6)), "robot_trunk_mass_kg"),
    "a negative friction": (_bench_case(_scale("robot_foot_friction", -1.0)), "robot_foot_friction"),
    "a friction of 100": (_bench_case(_scale("robot_foot_friction", 100.0)), "robot_foot_friction"),
    "a centre of mass 3 m off": (_bench_case(_scale("robot_com_shift_m", 3.0, (0, 0))), "robot_com_shift_m"),
    "a negative joint stiffness": (_bench_case(_scale("robot_joint_kp", -40.0, (0, 0))), "robot_joint_kp"),
    "a negative joint damping": (_bench_case(_scale("robot_joint_kd", -1.0, (0, 0))), "robot_joint_kd"),
    "a negative platform stiffness": (
        _bench_case(_scale("robot_platform_kp_factor", -1.0, (0, 0))),
        "robot_platform_kp_factor",
    ),
    "a negative platform damping": (
        _bench_case(_scale("robot_platform_kd_factor", -0.02, (0, 0))),
        "robot_platform_kd_factor",
    ),
    "a waypoint 1,000 km away": (_bench_case(_waypoint_far), "physical range"),
}


@pytest.mark.parametrize("case", sorted(BENCHMARK_REFUSED))
def test_a_bad_benchmark_file_is_refused_naming_the_file_and_the_problem(tmp_path, case):
    make, pattern = BENCHMARK_REFUSED[case]
    path = make(tmp_path / "bench.npz")
    with pytest.raises(bm.BenchmarkFileError, match=pattern) as err:
        bm.load(path)
    assert str(path) in str(err.value)


def test_a_sound_benchmark_file_loads(tmp_path):
    path = _bench_case(lambda a: None)(tmp_path / "bench.npz")
    assert bm.load(path).num_robots == 2
