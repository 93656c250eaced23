"""The shared input rules (lasmp/io/inputs.py): seeds, bounded numbers, and output files."""

import argparse
import os

import pytest

from lasmp.io.inputs import (
    SEED_MAX,
    InputError,
    check_out_file,
    check_seed,
    float_arg,
    int_arg,
    seed_arg,
    size_in_words,
)


@pytest.mark.parametrize("good", [0, 1, SEED_MAX, 7.0])
def test_a_seed_in_range_is_taken_as_an_int(good):
    assert check_seed(good) == int(good) and isinstance(check_seed(good), int)


@pytest.mark.parametrize("bad", [-1, SEED_MAX + 1, 2**64, 0.5, True, "3", None])
def test_a_seed_outside_the_range_or_not_an_integer_is_refused_by_name(bad):
    with pytest.raises(InputError, match=r"^env\.seed must be an integer in \[0, 2\*\*32 - 1\]"):
        check_seed(bad, "env.seed")


@pytest.mark.parametrize("text", ["-1", "4294967296", "1.5", "x", ""])
def test_the_seed_argument_refuses_what_check_seed_refuses(text):
    with pytest.raises(argparse.ArgumentTypeError, match="integer in"):
        seed_arg(text)
    assert seed_arg("4294967295") == SEED_MAX


def test_int_arg_holds_its_bounds():
    parse = int_arg(1, 10)
    assert parse("1") == 1 and parse("10") == 10
    for text in ("0", "11", "2.0", "nan"):
        with pytest.raises(argparse.ArgumentTypeError, match=r"in \[1, 10\]"):
            parse(text)


@pytest.mark.parametrize("text", ["nan", "inf", "-inf", "0", "-1", "abc"])
def test_float_arg_refuses_non_finite_and_out_of_range_numbers(text):
    with pytest.raises(argparse.ArgumentTypeError, match="finite number > 0"):
        float_arg(0.0, open_lo=True)(text)
    assert float_arg(0.0, open_lo=True)("0.5") == 0.5


def test_argparse_prints_the_rule_and_exits_2(capsys):
    p = argparse.ArgumentParser(prog="x")
    p.add_argument("--seed", type=seed_arg)
    with pytest.raises(SystemExit) as e:
        p.parse_args(["--seed", "-1"])
    assert e.value.code == 2
    assert "argument --seed: must be an integer in [0, 2**32 - 1], got '-1'" in capsys.readouterr().err


def test_an_out_file_with_an_unknown_extension_is_refused(tmp_path):
    with pytest.raises(InputError, match=r"--video .*out\.avi: unknown extension '\.avi'; use \.mp4"):
        check_out_file(tmp_path / "out.avi", suffixes=(".mp4",), force=False, option="--video")


def test_an_existing_out_file_is_refused_unless_forced(tmp_path):
    f = tmp_path / "a.png"
    f.write_bytes(b"old")
    with pytest.raises(InputError, match="already exists: choose another --snapshots, or pass --force"):
        check_out_file(f, suffixes=(".png",), force=False, option="--snapshots")
    assert check_out_file(f, suffixes=(".png",), force=True, option="--snapshots") == f
    assert f.read_bytes() == b"old"


def test_a_directory_in_place_of_the_file_is_refused_even_with_force(tmp_path):
    (tmp_path / "d.png").mkdir()
    with pytest.raises(InputError, match="is a directory"):
        check_out_file(tmp_path / "d.png", suffixes=(".png",), force=True, option="--snapshots")


def test_missing_directories_are_allowed_and_not_created(tmp_path):
    target = tmp_path / "new" / "deeper" / "v.mp4"
    assert check_out_file(target, suffixes=(".mp4",), force=False, option="--video") == target
    assert not (tmp_path / "new").exists()


def test_a_file_in_place_of_the_directory_is_refused(tmp_path):
    (tmp_path / "f").write_text("")
    with pytest.raises(InputError, match="is not a directory"):
        check_out_file(tmp_path / "f" / "v.mp4", suffixes=(".mp4",), force=False, option="--video")


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes through a directory's mode bits")
def test_a_read_only_directory_is_refused(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir(mode=0o555)
    with pytest.raises(InputError, match="is not writable"):
        check_out_file(ro / "v.mp4", suffixes=(".mp4",), force=False, option="--video")


def test_sizes_in_words_keep_three_digits():
    # evaluate's refusal once read "8 KiB free ... need at least 8 KiB" (8,192 and 8,992 bytes)
    assert size_in_words(8192) == "8 KiB" and size_in_words(8992) == "8.78 KiB"
    assert size_in_words(999) == "999 B" and size_in_words(3 << 30) == "3 GiB"
    assert size_in_words(5000 << 40) == "5000 TiB"
