"""The benchmarks, Xi_eval (the test set) and the validation set: make, read and describe their files.

The sets, their draw and the pairing of episodes with robots: lasmp/eval/benchmark_set.py; the
file, written bit for bit and checked on load: lasmp/eval/benchmark_file.py. This module is their
face: `load_or_make`, the validation set's check and the command line; it re-exports the names its
users read (`bm.generate`, `bm.save`, `bm.load`, ...).

Make them::

    python -m lasmp.eval.benchmark generate                  # -> benchmarks/xi_eval.npz, seed 0 (--force to replace)
    python -m lasmp.eval.benchmark generate --set validation # -> benchmarks/validation.npz, seed 1, 2,000 episodes
    python -m lasmp.eval.benchmark info benchmarks/xi_eval.npz [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import sys

from lasmp.envs import trajectories as T
from lasmp.eval.benchmark_file import (
    FORMAT_NAME,
    FORMAT_VERSION,
    ROBOT_FIELDS,
    ROBOT_UNITS,
    BenchmarkFileError,
    _save_new,
    load,
    save,
)
from lasmp.eval.benchmark_set import (
    DEFAULT_NUM_ROBOTS,
    DEFAULT_NUM_TRAJECTORIES,
    DEFAULT_PATH,
    MAX_ROBOTS,
    MAX_TRAJECTORIES,
    SETS,
    VALIDATION,
    XI_EVAL,
    Benchmark,
    BenchmarkSet,
    episode_draws,
    generate,
    generate_set,
)
from lasmp.io.atomic import claim_output
from lasmp.io.inputs import InputError, check_out_file, int_arg, seed_arg
from lasmp.io.inputs import file_sha256 as sha256

# the names the benchmark's users read here (bm.generate, bm.save, ...), wherever they are defined
__all__ = [
    "DEFAULT_NUM_ROBOTS",
    "DEFAULT_NUM_TRAJECTORIES",
    "DEFAULT_PATH",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "MAX_ROBOTS",
    "MAX_TRAJECTORIES",
    "ROBOT_FIELDS",
    "ROBOT_UNITS",
    "SETS",
    "VALIDATION",
    "XI_EVAL",
    "Benchmark",
    "BenchmarkFileError",
    "BenchmarkSet",
    "check_validation",
    "describe",
    "episode_draws",
    "generate",
    "generate_set",
    "load",
    "load_or_make",
    "main",
    "save",
]


def check_validation(bench: Benchmark, path) -> Benchmark:
    """`bench` as a validation benchmark: refused (BenchmarkFileError) if it is Xi_eval's draw, since a
    choice made on it would be made on the test set. A loaded file holds exactly what its seed draws
    (`load`), so Xi_eval's seed is the one way a file can hold Xi_eval's motions and robots."""
    if bench.seed == XI_EVAL.seed:
        raise BenchmarkFileError(
            f"{path}: drawn from seed {bench.seed}, Xi_eval's: the validation benchmark must not be the test "
            f"set (choices are made on validation; Xi_eval is read only for a final row). Make it with "
            f"`python -m lasmp.eval.benchmark generate --set validation` (seed {VALIDATION.seed})"
        )
    return bench


def load_or_make(which: BenchmarkSet, path=None) -> Benchmark:
    """The benchmark `which` from `path` (default: its own file, drawn and written on first use); a
    validation set is checked not to be Xi_eval (`check_validation`).

    The first use writes the file with `_save_new`, not with a claim: whole (a temporary file, then
    linked into place) and never over a file that appeared meanwhile. Two processes drawing it at
    once (two evaluations started together on a fresh clone) both succeed: the first to finish puts
    its file in place and the other reads that one, which holds the same bytes (the draw is
    deterministic). A claim would be worse here: its empty placeholder is what a third process
    would find and fail to read."""
    path = os.fspath(path or which.path)
    if os.path.lexists(path) or path != which.path:
        bench = load(path)
    else:
        print(
            f"{path} not found: generating it (seed {which.seed}, {which.num_trajectories:,} trajectories, "
            f"{which.num_robots:,} robots)",
            file=sys.stderr,
        )
        bench = generate_set(which)
        if not _save_new(path, bench):  # another process drew it first (the same bytes), or a file appeared
            bench = load(path)
    return check_validation(bench, path) if which is VALIDATION else bench


def describe(path, bench: Benchmark) -> dict:
    """File facts and trajectory statistics (lasmp.envs.trajectories.statistics, overall and per N)."""
    return {
        "path": os.fspath(path),
        "bytes": os.path.getsize(path),
        "sha256": sha256(path),
        "seed": bench.seed,
        "num_trajectories": bench.num_trajectories,
        "num_robots": bench.num_robots,
        "statistics": T.statistics(bench.trajectories),
    }


def _report(info: dict, as_json: bool) -> None:
    if as_json:
        print(json.dumps(info))
        return
    print(
        f"{info['path']}: {info['bytes']} bytes, sha256 {info['sha256']}\n"
        f"seed {info['seed']}, {info['num_trajectories']} trajectories, {info['num_robots']} robots"
    )
    T.print_table(info["statistics"])


def main(argv=None) -> int:
    """The CLI (module docstring). `generate` checks --out's extension and claims the file
    (lasmp.io.atomic.claim_output: an existing file only with --force) before drawing anything; a user's error or a failed write is one
    line `error: ...` and exit code 2."""
    ap = argparse.ArgumentParser(prog="python -m lasmp.eval.benchmark", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    pg = sub.add_parser("generate", help="draw Xi_eval and write it")
    pg.add_argument(
        "--set",
        choices=sorted(SETS),
        default=XI_EVAL.name,
        help="which benchmark: its file, seed and sizes (default xi_eval); the options below override them",
    )
    pg.add_argument("--out", help=f"a .npz file (default: the set's, {DEFAULT_PATH} for xi_eval)")
    pg.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    pg.add_argument("--seed", type=seed_arg, help="in [0, 2**32 - 1] (default: the set's)")
    pg.add_argument("--num-trajectories", type=int_arg(1, MAX_TRAJECTORIES), help="default: the set's")
    pg.add_argument("--num-robots", type=int_arg(1, MAX_ROBOTS), help="default: the set's")
    pg.add_argument("--json", action="store_true", help="print one JSON object only")
    pi = sub.add_parser("info", help="statistics and sha256 of an existing file")
    pi.add_argument("file")
    pi.add_argument("--json", action="store_true", help="print one JSON object only")
    args = ap.parse_args(argv)
    try:
        if args.cmd == "generate":
            which = SETS[args.set]
            # extension and directory checked here; the file itself claimed (create-exclusive) below
            path = check_out_file(args.out or which.path, suffixes=(".npz",), force=True, option="--out")
            with claim_output(path, force=args.force, option="--out"):
                bench = generate(
                    args.num_trajectories or which.num_trajectories,
                    args.num_robots or which.num_robots,
                    which.seed if args.seed is None else args.seed,
                )
                if which is VALIDATION:
                    check_validation(bench, path)  # before anything is written
                save(path, bench)
        else:
            path = args.file
            bench = load(path)
    except (BenchmarkFileError, InputError, OSError) as exc:  # OSError: a full disk (AtomicWriteError)
        print(f"error: {exc}", file=sys.stderr)
        return 2
    try:
        _report(describe(path, bench), args.json)
    except BrokenPipeError:  # piped into `head`, which has read enough: no traceback
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0


if __name__ == "__main__":
    sys.exit(main())
