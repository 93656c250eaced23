"""The evaluation set Xi_eval (docs/method.md, Evaluation): fixed trajectories and fixed robots, one file.

Definition
    * ``trajectories``: M (default 10,000) platform trajectories drawn by
      :func:`lasmp.envs.trajectories.sample` with the *testing* ranges
      (``ranges_for_split("test")``: N uniform in 4..16, T = 10 s), from
      ``np.random.default_rng([seed, 0])``.
    * ``robots``: R (default 1,024) intrinsic-parameter draws
      (:func:`lasmp.envs.moving_platform.domain_rand.sample_intrinsics`) from the *testing* ranges
      of Table B (``DomainRandCfg().test``: trunk mass, CoM shift, foot friction, joint Kp/Kd and
      the platform PD gain factors), from ``np.random.default_rng([seed, 1])``.
      The two streams are independent: changing M does not change the robots. Changing M does
      change the trajectories (``sample`` draws all N first, then all waypoints), so for quick runs
      take the first K rows of the full set (:meth:`Benchmark.subset`), not a set drawn with M = K.
    * Pairing (fixed, method-independent): episode k replays trajectory k with robot k % R
      (:meth:`Benchmark.pairing`). Every method meets exactly the same (trajectory, robot) pairs.
    * Initial pose (ours): episode k starts at the heading (and offset) of its own draws,
      ``np.random.default_rng([seed, 2, k])`` (:meth:`Benchmark.initial_pose_draws`), so it starts
      the same whatever the controller, the number of envs or the order in which envs reset. Not
      stored: it follows from the seed.

File (``.npz``, :func:`save` / :func:`load`), bit-for-bit reproducible
    Written with our own ``zipfile`` writer: entries stored uncompressed, in a fixed order, with a
    fixed date (1980-01-01 00:00:00) and permissions, each the ``np.lib.format.write_array`` bytes
    (allow_pickle=False) of one array, so the same seed and sizes give the same bytes (and sha256).
    It is still an ordinary ``np.load``-able archive. Keys: ``format`` = "lasmp-benchmark",
    ``version`` = 2, ``seed``; the trajectories in the "waypoints" layout of the trajectory file
    format (``knot_times_s`` (M, K), ``waypoints`` (M, K, 6), NaN-padded, knot 0 = zero pose at
    t = 0 included; ``n_waypoints`` (M,); ``spline`` and ``spline_degree``, the construction:
    the default approximating B-spline); a version-1 file (the old interpolating splines) is
    refused with the command that regenerates it; the robots ``robot_trunk_mass_kg`` (R,),
    ``robot_com_shift_m`` (R, 3), ``robot_foot_friction`` (R,), ``robot_joint_kp`` (R, 12),
    ``robot_joint_kd`` (R, 12), ``robot_platform_kp_factor`` (R, 6),
    ``robot_platform_kd_factor`` (R, 6). Trajectory splines are rebuilt on load (bit-identical).
    The default set (seed 0, 10,000 x 1,024) is 9,939,608 bytes (~9.9 MB,
    sha256 0e049d82...) and takes a few seconds to generate, statistics included (one CPU).

Checked on load (:func:`load`), besides its structure: every robot value lies in Table B's testing
range, and every array is what the recorded seed and sizes generate (``_check_regenerates`` says
why), so an edited file (Kp and Kd swapped, rows reordered) is refused instead of evaluated.

The validation benchmark (ours, docs/evaluation.md#validation-and-test): 2,000 episodes drawn exactly
as Xi_eval is (this generator, the testing ranges, the same robots' count) from a seed of its own,
`VALIDATION.seed`. Every choice (a candidate, a budget, a checkpoint, the shipped seed) is made on it;
Xi_eval is read only for a final row. A validation file whose seed is Xi_eval's is refused
(`check_validation`): `load` already holds every array to what its seed draws, so a file with another
seed cannot hold Xi_eval's motions or robots.

Make them::

    python -m lasmp.eval.benchmark generate                  # -> benchmarks/xi_eval.npz, seed 0 (--force to replace)
    python -m lasmp.eval.benchmark generate --set validation # -> benchmarks/validation.npz, seed 1, 2,000 episodes
    python -m lasmp.eval.benchmark info benchmarks/xi_eval.npz [--json]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import sys
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lasmp.atomic import TEMPORARY_SUFFIX, AtomicWriteError, atomic_open, claim_output
from lasmp.config import DomainRandCfg
from lasmp.envs import trajectories as T
from lasmp.envs.moving_platform.domain_rand import Intrinsics, sample_intrinsics
from lasmp.inputs import InputError, check_out_file, check_seed, int_arg, seed_arg
from lasmp.inputs import file_sha256 as sha256

FORMAT_NAME = "lasmp-benchmark"
FORMAT_VERSION = 2  # 2: approximating B-splines, the construction recorded (spline, spline_degree)
DEFAULT_NUM_TRAJECTORIES = 10_000
DEFAULT_NUM_ROBOTS = 1_024
DEFAULT_PATH = os.path.join("benchmarks", "xi_eval.npz")
_ZIP_DATE = (1980, 1, 1, 0, 0, 0)
# robot array key -> (Intrinsics field, per-robot shape)
ROBOT_FIELDS = {
    "robot_trunk_mass_kg": ("trunk_mass_kg", ()),
    "robot_com_shift_m": ("com_shift_m", (3,)),
    "robot_foot_friction": ("foot_friction", ()),
    "robot_joint_kp": ("joint_kp", (12,)),
    "robot_joint_kd": ("joint_kd", (12,)),
    "robot_platform_kp_factor": ("platform_kp_factor", (6,)),
    "robot_platform_kd_factor": ("platform_kd_factor", (6,)),
}


# robots: Table B's testing ranges (DomainRandCfg().test), which every robot of Xi_eval is drawn from;
# a value outside is a file that is not Xi_eval (e.g. Kp and Kd swapped, every stiffness 0, no
# platform drive), which would evaluate without a word and give meaningless metrics
ROBOT_UNITS = {
    "robot_trunk_mass_kg": "kg",
    "robot_com_shift_m": "m",
    "robot_foot_friction": "",
    "robot_joint_kp": "N m/rad",
    "robot_joint_kd": "N m s/rad",
    "robot_platform_kp_factor": "(factor)",
    "robot_platform_kd_factor": "(factor)",
}
MAX_TRAJECTORIES = 100_000  # 10x the paper's set; more would take gigabytes (generate's bound)
MAX_ROBOTS = 100_000


class BenchmarkFileError(ValueError):
    """A benchmark file is missing or malformed; the message names the file and the problem."""


@dataclass(frozen=True)
class BenchmarkSet:
    """A named benchmark: where its file lives by default and what draws it."""

    name: str
    path: str
    seed: int
    num_trajectories: int
    num_robots: int = DEFAULT_NUM_ROBOTS


# the test set (the paper's Xi_eval: read only for a final row) and the validation set (ours: every
# choice is made on it), drawn by the same generator from different seeds
XI_EVAL = BenchmarkSet("xi_eval", DEFAULT_PATH, 0, DEFAULT_NUM_TRAJECTORIES)
VALIDATION = BenchmarkSet("validation", os.path.join("benchmarks", "validation.npz"), 1, 2_000)
SETS = {s.name: s for s in (XI_EVAL, VALIDATION)}


@dataclass
class Benchmark:
    """Xi_eval: M trajectories (testing ranges), R robots (testing intrinsics), the seed."""

    trajectories: T.PiecewisePoly
    robots: Intrinsics
    seed: int

    @property
    def num_trajectories(self) -> int:
        return len(self.trajectories)

    @property
    def num_episodes(self) -> int:
        """Episodes the set defines (episode k plays trajectory k)."""
        return len(self.trajectories)

    @property
    def num_robots(self) -> int:
        return int(self.robots.trunk_mass_kg.shape[0])

    def pairing(self, episodes) -> tuple[np.ndarray, np.ndarray]:
        """(trajectory rows, robot rows) of episodes k: trajectory k, robot k % R.

        Fixed and method-independent, so every method is scored on the same pairs.
        """
        k = np.asarray(episodes, dtype=np.int64)
        if k.size and (k.min() < 0 or k.max() >= self.num_trajectories):
            raise IndexError(f"episode indices must be in 0..{self.num_trajectories - 1}")
        return k.copy(), k % self.num_robots

    def initial_pose_draws(self, episodes) -> np.ndarray:
        """(n, 3) uniforms in [0, 1) from which episodes k start (the env maps them to a heading and
        an offset): stream [seed, 2, k] of each episode."""
        k = np.asarray(episodes, dtype=np.int64)
        return episode_draws([[self.seed, 2, int(e)] for e in k.ravel()])

    def subset(self, num_trajectories: int) -> Benchmark:
        """The first ``num_trajectories`` trajectories with the same robots (quick runs)."""
        if not 1 <= num_trajectories <= self.num_trajectories:
            raise ValueError(f"subset: need 1..{self.num_trajectories} trajectories, got {num_trajectories}")
        return Benchmark(self.trajectories.subset(np.arange(num_trajectories)), self.robots, self.seed)


def episode_draws(keys) -> np.ndarray:
    """(len(keys), 3) uniforms in [0, 1): row i from `np.random.default_rng(keys[i])`, a generator of
    the episode's own (its key: a list of non-negative ints). An episode's start then depends on
    nothing but its key."""
    return np.array([np.random.default_rng(key).random(3) for key in keys]).reshape(-1, 3)


def generate(
    num_trajectories: int = DEFAULT_NUM_TRAJECTORIES, num_robots: int = DEFAULT_NUM_ROBOTS, seed: int = 0
) -> Benchmark:
    """Draw Xi_eval (module docstring): trajectories from stream [seed, 0], robots from [seed, 1]."""
    if num_trajectories < 1 or num_robots < 1:
        raise ValueError(f"generate: need >= 1 trajectories and robots, got {num_trajectories}, {num_robots}")
    traj = T.sample(num_trajectories, T.ranges_for_split("test"), np.random.default_rng([seed, 0]))
    robots = sample_intrinsics(num_robots, DomainRandCfg().test, np.random.default_rng([seed, 1]))
    return Benchmark(traj, robots, int(seed))


def generate_set(which: BenchmarkSet) -> Benchmark:
    """The benchmark `which` names, drawn from its seed and sizes."""
    return generate(which.num_trajectories, which.num_robots, which.seed)


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


def _save_new(path, bench: Benchmark) -> bool:
    """`save` to `path` unless a file is there by the time the write is done (then False, that file
    untouched): the whole file is written under a temporary name beside `path` and hard-linked to
    `path` (link(2) fails on an existing name: create-exclusive, with the content complete). Where the
    file system has no hard links, it is renamed over `path`, which at worst replaces another
    process's draw by identical bytes. A failing file system is an AtomicWriteError naming `path`."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=TEMPORARY_SUFFIX, dir=path.parent)
        os.close(fd)
    except OSError as err:
        raise AtomicWriteError(path, err) from err
    try:
        try:
            save(tmp, bench)
        except AtomicWriteError as err:
            raise AtomicWriteError(path, err) from err
        try:
            os.link(tmp, path)
        except FileExistsError:
            return False
        except OSError:  # no hard links here (some network or FUSE file systems)
            os.replace(tmp, path)
        return True
    except AtomicWriteError:
        raise
    except OSError as err:
        raise AtomicWriteError(path, err) from err
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


def _arrays(bench: Benchmark) -> dict[str, np.ndarray]:
    out = {
        "format": np.array(FORMAT_NAME),
        "version": np.array(FORMAT_VERSION, dtype=np.int64),
        "seed": np.array(bench.seed, dtype=np.int64),
    }
    out.update(T.waypoint_arrays(bench.trajectories))
    for key, (name, _) in ROBOT_FIELDS.items():
        out[key] = np.ascontiguousarray(getattr(bench.robots, name), dtype=np.float64)
    return out


def save(path, bench: Benchmark) -> None:
    """Write ``bench`` to ``path`` (verbatim) atomically; the same content gives the same bytes."""
    with atomic_open(path) as f, zipfile.ZipFile(f, "w", compression=zipfile.ZIP_STORED) as zf:
        for key, arr in _arrays(bench).items():  # fixed insertion order
            buf = io.BytesIO()
            np.lib.format.write_array(buf, arr, allow_pickle=False)
            info = zipfile.ZipInfo(f"{key}.npy", date_time=_ZIP_DATE)
            info.compress_type = zipfile.ZIP_STORED
            info.external_attr = 0o644 << 16
            info.create_system = 3
            zf.writestr(info, buf.getvalue())


def load(path) -> Benchmark:
    """Read and validate a benchmark file; any problem raises BenchmarkFileError naming it."""
    path = os.fspath(path)
    if os.path.exists(path) and not os.path.isfile(path):  # a FIFO would block, /dev/zero never end
        raise BenchmarkFileError(f"{path}: not a regular file; give a benchmark file (.npz)")
    if not os.path.isfile(path):
        raise BenchmarkFileError(f"{path}: no such benchmark file")
    if not zipfile.is_zipfile(path):
        raise BenchmarkFileError(f"{path}: not an .npz (zip) archive")
    get = T.read_npz(path, BenchmarkFileError)

    fmt = get("format")
    if fmt.shape != () or fmt.dtype.kind != "U" or str(fmt) != FORMAT_NAME:
        raise BenchmarkFileError(f"{path}: format is {fmt!r}, expected {FORMAT_NAME!r}")
    T.check_version(
        get,
        path,
        FORMAT_VERSION,
        BenchmarkFileError,
        "Regenerate it with `python -m lasmp.eval.benchmark generate`.",
    )
    seed = get("seed")
    if seed.shape != () or seed.dtype.kind not in "iu":
        raise BenchmarkFileError(f"{path}: 'seed' must be an integer scalar, got {seed.dtype} {seed.shape}")
    traj = T.waypoints_from_arrays(get, path, BenchmarkFileError)

    robots, r = {}, None
    test = DomainRandCfg().test
    for key, (name, shape) in ROBOT_FIELDS.items():
        a = get(key)
        r = a.shape[0] if r is None and a.ndim >= 1 else r
        if a.dtype.kind != "f" or r is None or r < 1 or a.shape != (r, *shape):
            raise BenchmarkFileError(
                f"{path}: wrong shape/dtype: {key!r} must be float (R, {', '.join(map(str, shape))}) "
                f"with R = {r} robots, got {a.dtype} {a.shape}"
            )
        if not np.all(np.isfinite(a)):
            raise BenchmarkFileError(f"{path}: non-finite values (NaN/inf) in {key!r}")
        low, high = getattr(test, name)
        outside = (a < low) | (a > high)
        if np.any(outside):
            row = int(np.flatnonzero(outside.reshape(r, -1).any(axis=1))[0])
            raise BenchmarkFileError(
                f"{path}: {key!r} of robot {row} is {np.round(a[row], 4).tolist()}, outside the testing "
                f"range [{low:g}, {high:g}] {ROBOT_UNITS[key]} of Table B that every robot of Xi_eval is "
                f"drawn from{_swapped(key, a, test)}. Regenerate the file with `python -m "
                "lasmp.eval.benchmark generate`"
            )
        robots[name] = a.astype(np.float64)
    try:
        seed = check_seed(get("seed").item(), "its seed")
    except InputError as err:
        raise BenchmarkFileError(f"{path}: {err}") from None
    _check_regenerates(path, get, seed, len(traj), r)
    return Benchmark(traj, Intrinsics(**robots), seed)


def _swapped(key: str, a: np.ndarray, test) -> str:
    """A hint where joint stiffness and damping look exchanged."""
    other = {"robot_joint_kp": test.joint_kd, "robot_joint_kd": test.joint_kp}.get(key)
    if other is not None and np.all((a >= other[0]) & (a <= other[1])):
        return " (are Kp and Kd swapped?)"
    return ""


def _check_regenerates(path, get, seed: int, num_trajectories: int, num_robots: int) -> None:
    """Refuse a file whose arrays are not what its seed and sizes generate (`generate`).

    Why a regeneration and not only ranges: values inside the ranges can still be wrong (one array's
    rows reordered pairs each robot with another mass; an edited waypoint), and only the generator
    knows which value belongs to which row. A checksum stored in the file would change the bytes of
    the published Xi_eval (its sha256 is recorded with every result), and an edit can recompute
    one; the seed and sizes every file already records regenerate it bit for bit (the file is
    reproducible by design) in about 0.25 s for 10,000 x 1,024. A benchmark is therefore always the
    set its seed draws, so every method meets the same robots and motions."""
    want = _arrays(generate(num_trajectories, num_robots, seed))
    for key, expected in want.items():
        have = get(key)
        same = (
            have.shape == expected.shape and np.array_equal(have, expected, equal_nan=True)
            if expected.dtype.kind == "f"
            else have.shape == expected.shape and np.array_equal(have, expected)
        )
        if not same:
            where = ""
            if have.shape == expected.shape and have.ndim >= 1:
                differs = ~((have == expected) | (np.isnan(have) & np.isnan(expected)))
                row = int(np.flatnonzero(differs.reshape(len(have), -1).any(axis=1))[0])
                where = f", first in row {row}"
            raise BenchmarkFileError(
                f"{path}: {key!r} differs from what its seed {seed} draws ({num_trajectories} trajectories, "
                f"{num_robots} robots){where}: the file was edited or its rows reordered, so methods "
                "evaluated on it would not meet Xi_eval's robots and motions. Regenerate it: python -m "
                f"lasmp.eval.benchmark generate --seed {seed} --num-trajectories {num_trajectories} "
                f"--num-robots {num_robots} --out {path} --force"
            )


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
    (lasmp.atomic.claim_output: an existing file only with --force) before drawing anything; a user's error or a failed write is one
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
