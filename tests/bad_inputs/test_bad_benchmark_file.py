"""Benchmark files (`lasmp.eval.benchmark.load`): a bad file is refused naming the file and the
problem, a file whose values lost their meaning (Kp and Kd swapped, rows reordered) included; a sound
one loads. And its `generate` command: options checked up front, an existing file kept without
--force, a write error in one line."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest
from badkit import _bench_case, _raw, _scale, _waypoint_far, call, files, refused, succeeded
from test_bad_trajectory_file import bomb_npz

from lasmp.eval import benchmark as bm

# -- benchmark files -----------------------------------------------------------------------------
BENCHMARK_REFUSED = {
    "a missing file": (lambda path: path, "no such benchmark file"),
    "a FIFO, which would block": (lambda path: os.mkfifo(path) or path, "not a regular file"),
    "a text file": (_raw(b"not a benchmark"), "not an .npz"),
    "another format": (_bench_case(lambda a: a.update(format=np.array("lasmp-trajectories"))), "format is"),
    "version 1": (_bench_case(lambda a: a.update(version=np.array(1))), "unsupported version 1"),
    "no joint gains": (_bench_case(lambda a: a.pop("robot_joint_kp")), "missing key 'robot_joint_kp'"),
    "a NaN gain": (_bench_case(_scale("robot_joint_kp", np.nan)), "non-finite"),
    "damping of 11 joints": (
        _bench_case(lambda a: a.update(robot_joint_kd=a["robot_joint_kd"][:, :11])),
        "wrong shape",
    ),
    "a seed of -1": (_bench_case(lambda a: a.update(seed=np.array(-1))), r"its seed must be .*got -1"),
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
    # told as what is wrong with the times, not as the NaN padding of the poses they now point at
    "zeroed knot times": (
        _bench_case(lambda a: a.update(knot_times_s=np.where(np.isnan(a["knot_times_s"]), np.nan, 0.0))),
        "times must be strictly increasing",
    ),
    "knot times zeroed with their padding": (
        _bench_case(lambda a: a.update(knot_times_s=np.zeros_like(a["knot_times_s"]))),
        "times must be strictly increasing",
    ),
}


def _swap(a, b):
    return lambda arrays: arrays.update({a: arrays[b], b: arrays[a]})


def _zeros(*keys):
    return lambda arrays: arrays.update({k: np.zeros_like(arrays[k]) for k in keys})


def _reversed_rows(*keys):
    return lambda arrays: arrays.update({k: arrays[k][::-1].copy() for k in keys})


def _nudged(key, index, by):
    def change(arrays):
        arrays[key] = arrays[key].copy()
        arrays[key][index] += by

    return change


# values of the right shape and finite, whose meaning is wrong: each evaluated without a word before
BENCHMARK_MEANING = {
    "B_swap_kp_kd": (
        _swap("robot_joint_kp", "robot_joint_kd"),
        r"'robot_joint_kp' of robot 0 is .*outside the testing range \[32, 48\] N m/rad.*Kp and Kd swapped\?",
    ),
    "B_zero_joint_kp": (_zeros("robot_joint_kp"), r"'robot_joint_kp' of robot 0 is \[0\.0, .*\[32, 48\]"),
    "B_zero_platform_gains": (
        _zeros("robot_platform_kp_factor", "robot_platform_kd_factor"),
        r"'robot_platform_kp_factor' of robot 0 .*testing range \[0\.5, 2\]",
    ),
    "B_shuffled_mass": (
        _reversed_rows("robot_trunk_mass_kg"),
        r"'robot_trunk_mass_kg' differs from what its seed 0 draws \(4 trajectories, 2 robots\), first in row 0"
        r": the file was edited or its rows reordered",
    ),
    "trajectory rows reordered": (
        _reversed_rows("knot_times_s", "waypoints", "n_waypoints"),
        r"differs from what its seed 0 draws .*--seed 0 --num-trajectories 4 --num-robots 2",
    ),
    "a waypoint moved within the ranges": (
        _nudged("waypoints", (1, 1, 0), 0.01),
        r"'waypoints' differs.*row 1",
    ),
    "a friction edited within the ranges": (
        _nudged("robot_foot_friction", 1, 1e-6),
        r"'robot_foot_friction' differs",
    ),
    "another seed recorded": (lambda a: a.update(seed=np.array(7)), r"seed 7 draws"),
}


@pytest.mark.parametrize("case", sorted(BENCHMARK_MEANING))
def test_a_benchmark_whose_values_lost_their_meaning_is_refused(tmp_path, case):
    change, pattern = BENCHMARK_MEANING[case]
    path = _bench_case(change)(tmp_path / "bench.npz")
    with pytest.raises(bm.BenchmarkFileError, match=pattern) as err:
        bm.load(path)
    assert str(err.value).startswith(f"{path}: ")


def test_b_bomb_an_npz_holding_2_gib_in_2_mb_is_refused_before_loading(tmp_path):
    arrays = {}
    _bench_case(arrays.update)(tmp_path / "good.npz")
    path = bomb_npz(tmp_path / "bench.npz", arrays, "robot_joint_kp", (2**28,))
    started = time.monotonic()
    out = call(bm.main, ["info", str(path)])
    refused(out, r"bench\.npz: its arrays would take more than 1\.0 GiB .*'robot_joint_kp'")
    assert time.monotonic() - started < 5.0


@pytest.mark.parametrize("case", sorted(BENCHMARK_REFUSED))
def test_a_bad_benchmark_file_is_refused_naming_the_file_and_the_problem(tmp_path, case):
    make, pattern = BENCHMARK_REFUSED[case]
    path = make(tmp_path / "bench.npz")
    with pytest.raises(bm.BenchmarkFileError, match=pattern) as err:
        bm.load(path)
    assert str(err.value).count(str(path)) == 1, str(err.value)


def test_a_sound_benchmark_file_loads(tmp_path):
    path = _bench_case(lambda a: None)(tmp_path / "bench.npz")
    assert bm.load(path).num_robots == 2


def test_xi_eval_as_evaluate_makes_it_on_first_use_passes_every_check(tmp_path):
    # benchmarks/xi_eval.npz is not in the repository: evaluate.py writes it from seed 0 on first use
    # (lasmp.eval.build.load_or_make_benchmark); made here the same way, so the test needs no other first
    path = tmp_path / "xi_eval.npz"
    bm.save(path, bm.generate())
    bench = bm.load(path)
    assert (bench.num_trajectories, bench.num_robots, bench.seed) == (10_000, 1_024, 0)


# -- the generate command ------------------------------------------------------------------------
def _generate(*args: str):
    return call(bm.main, ["generate", "--num-trajectories", "4", "--num-robots", "2", *args])


GENERATE_REFUSED = {
    "a seed of -1": (
        ["--seed", "-1"],
        r"argument --seed: must be an integer in \[0, 2\*\*32 - 1\], got '-1'",
    ),
    "a seed of 2**64": (["--seed", str(2**64)], r"argument --seed"),
    "a seed that is not a number": (["--seed", "one"], r"argument --seed"),
    "no trajectories": (
        ["--num-trajectories", "0"],
        r"argument --num-trajectories: must be an integer in \[1, ",
    ),
    "a million robots": (
        ["--num-robots", "1000000"],
        r"argument --num-robots: must be an integer in \[1, 100000\]",
    ),
    "half a robot": (["--num-robots", "0.5"], r"argument --num-robots"),
    "an unknown extension": (["--out", "xi.txt"], r"--out xi\.txt: unknown extension '\.txt'; use \.npz"),
    "a directory as --out": (["--out", "adir.npz"], r"--out adir\.npz is a directory"),
}


@pytest.mark.parametrize("case", sorted(GENERATE_REFUSED))
def test_benchmark_generate_refuses_a_bad_option_in_one_line_and_writes_nothing(tmp_path, case):
    args, pattern = GENERATE_REFUSED[case]
    (tmp_path / "adir.npz").mkdir()  # the working directory (conftest)
    out = call(
        bm.main,
        ["generate", "--out", str(tmp_path / "xi.npz"), *args]
        if "--out" not in args
        else ["generate", *args],
    )
    refused(out, pattern)
    assert files(tmp_path) == {}


def test_benchmark_generate_keeps_an_existing_file_without_force_and_replaces_it_with(tmp_path):
    path = tmp_path / "xi.npz"
    path.write_bytes(b"an older benchmark")
    out = _generate("--out", str(path))
    refused(out, r"xi\.npz already exists: choose another --out, or pass --force")
    assert path.read_bytes() == b"an older benchmark"
    succeeded(_generate("--out", str(path), "--force"))
    assert bm.load(path).num_robots == 2


def test_benchmark_generate_into_a_read_only_directory_is_refused_before_drawing(tmpfs):
    where = tmpfs(read_only=True)
    out = _generate("--out", str(where / "xi.npz"))
    refused(out, r"not writable")
    assert list(where.iterdir()) == []


def test_benchmark_generate_onto_a_full_disk_gives_one_line_naming_the_file(tmpfs):
    where = tmpfs(size="64k")
    out = call(
        bm.main,
        ["generate", "--num-trajectories", "400", "--num-robots", "2", "--out", str(where / "xi.npz")],
    )
    refused(out, r"cannot write .*xi\.npz: No space left on device")
    assert len(out.text.strip().splitlines()) == 1 and list(where.iterdir()) == []
