"""The trajectory and real-motion `generate` (and `plot`) commands as a careless user runs them: an
existing file, an unknown extension, a read-only or full disk, a number that means nothing, flags that
would be ignored. Each is refused in one line before any work, or fails in one line naming the file
and leaves nothing behind; an existing file is replaced only with --force.

The benchmark's `generate` has its own tests (test_bad_benchmark_file.py)."""

from __future__ import annotations

import numpy as np
import pytest
from badkit import call, refused, succeeded

from lasmp.envs import trajectories as trj
from lasmp.envs.trajectories.cli import main as trajectories_main
from lasmp.eval.real_motion.__main__ import main as real_motion_main

SCENARIO = "lift_up"  # the quickest real-motion scenario to build


def trajectories(*args: str):
    return call(trajectories_main, list(args))


def real_motion(*args: str):
    return call(real_motion_main, list(args))


def one_error_line(out, *needles: str) -> None:
    refused(out)
    lines = [line for line in out.text.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and all(n in lines[0] for n in needles), out.text


# ---------------------------------------------------------------------------------------------
# python -m lasmp.envs.trajectories generate / plot
# ---------------------------------------------------------------------------------------------
def test_trajectories_generate_does_not_replace_a_file_without_force(tmp_path):
    out = tmp_path / "set.npz"
    out.write_bytes(b"an earlier set")
    refused(trajectories("generate", "--num", "3", "--out", str(out)), "already exists", "--force")
    assert out.read_bytes() == b"an earlier set"
    succeeded(trajectories("generate", "--num", "3", "--out", str(out), "--force"))
    assert len(trj.load(out)) == 3


@pytest.mark.parametrize(
    ("cmd", "name", "known"), [("generate", "set.txt", ".npz"), ("plot", "fig.xyz", ".png")]
)
def test_trajectories_unknown_extension_is_refused_before_sampling(tmp_path, cmd, name, known):
    out = trajectories(cmd, "--num", "3", "--out", str(tmp_path / name))
    one_error_line(out, name, "unknown extension", known)
    assert out.code == 2 and list(tmp_path.iterdir()) == []


def test_trajectories_plot_does_not_replace_a_figure_without_force(tmp_path):
    fig = tmp_path / "fig.png"
    fig.write_bytes(b"an earlier figure")
    refused(trajectories("plot", "--num", "3", "--out", str(fig)), "already exists", "--force")
    assert fig.read_bytes() == b"an earlier figure"


@pytest.mark.parametrize("where", ["read-only disk", "a file as directory"])
def test_trajectories_generate_into_an_unwritable_place_is_refused_in_one_line(tmp_path, tmpfs, where):
    if where == "read-only disk":
        parent, reason = tmpfs(read_only=True), "not writable"
    else:
        parent, reason = tmp_path / "afile", "not a directory"
        parent.write_text("a file")
    out = trajectories("generate", "--num", "3", "--out", str(parent / "set.npz"))
    one_error_line(out, "set.npz", reason)
    assert out.code == 2


def test_trajectories_generate_on_a_full_disk_is_one_line_naming_the_file_and_leaves_nothing(tmpfs):
    full = tmpfs(size="4k")
    out = trajectories("generate", "--num", "200", "--out", str(full / "set.npz"))
    assert out.code == 1
    one_error_line(out, str(full / "set.npz"), "No space left on device")
    assert list(full.iterdir()) == []


@pytest.mark.parametrize(
    ("args", "pattern"),
    [
        (["generate", "--seed", "-1"], "argument --seed: must be an integer in"),
        (["generate", "--seed", str(2**64)], "argument --seed: must be an integer in"),
        (["generate", "--num", "0"], "argument --num: must be an integer >= 1"),
        (["generate", "--degree", "99"], r"argument --degree: must be an integer in \[3, 15\]"),
        (["stats", "--num", "3", "--dt", "nan"], "argument --dt: must be a finite number > 0"),
        (["stats", "--num", "3", "--dt", "0"], "argument --dt: must be a finite number > 0"),
    ],
)
def test_trajectories_numbers_out_of_range_are_refused_naming_the_option(tmp_path, args, pattern):
    if args[0] == "generate":
        args = [*args, "--out", str(tmp_path / "set.npz")]
    out = trajectories(*args)
    refused(out, pattern)
    assert out.code == 2 and list(tmp_path.iterdir()) == []


def test_trajectories_sampling_options_with_a_file_are_refused_not_ignored(tmp_path):
    path = tmp_path / "set.npz"
    trj.save(path, trj.sample(3, trj.ranges_for_split("test"), np.random.default_rng(0)))
    refused(trajectories("stats", "--file", str(path), "--seed", "7"), "give --file or the sampling options")
    succeeded(trajectories("stats", "--file", str(path), "--json"))


# ---------------------------------------------------------------------------------------------
# python -m lasmp.eval.real_motion generate / plot (M03)
# ---------------------------------------------------------------------------------------------
def test_real_motion_generate_does_not_replace_a_file_without_force(tmp_path):
    out = tmp_path / "real_motion.npz"
    out.write_bytes(b"an earlier suite")
    refused(real_motion("generate", "--scenarios", SCENARIO, "--out", str(out)), "already exists", "--force")
    assert out.read_bytes() == b"an earlier suite"
    succeeded(real_motion("generate", "--scenarios", SCENARIO, "--out", str(out), "--force"))
    assert len(trj.load(out)) == 1


def test_real_motion_generate_refuses_an_unknown_extension_and_a_read_only_disk(tmp_path, tmpfs):
    one_error_line(
        real_motion("generate", "--scenarios", SCENARIO, "--out", str(tmp_path / "suite.txt")),
        "unknown extension",
        ".npz",
    )
    ro = tmpfs(read_only=True)
    one_error_line(
        real_motion("generate", "--scenarios", SCENARIO, "--out", str(ro / "suite.npz")), "not writable"
    )
    assert [p.name for p in tmp_path.iterdir()] == [ro.name] and list(ro.iterdir()) == []


def test_real_motion_generate_on_a_full_disk_is_one_line_naming_the_file(tmpfs):
    full = tmpfs(size="4k")
    out = real_motion("generate", "--scenarios", SCENARIO, "--out", str(full / "suite.npz"))
    assert out.code == 1
    one_error_line(out, str(full / "suite.npz"), "No space left on device")
    assert list(full.iterdir()) == []


def test_real_motion_plot_does_not_replace_a_figure_without_force(tmp_path):
    fig = tmp_path / f"{SCENARIO}.png"
    fig.write_bytes(b"an earlier figure")
    refused(real_motion("plot", "--scenarios", SCENARIO, "--out", str(tmp_path)), fig.name, "--force")
    assert fig.read_bytes() == b"an earlier figure"
