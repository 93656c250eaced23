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

Make it::

    python -m lasmp.eval.benchmark generate            # -> benchmarks/xi_eval.npz, seed 0
    python -m lasmp.eval.benchmark info benchmarks/xi_eval.npz [--json]
"""

from __future__ import annotations

import argparse
import hashlib
import io
import json
import os
import sys
import zipfile
from dataclasses import dataclass

import numpy as np

from lasmp.atomic import atomic_open
from lasmp.config import DomainRandCfg
from lasmp.envs import trajectories as T
from lasmp.envs.moving_platform.domain_rand import Intrinsics, sample_intrinsics

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


# robot array key -> its physical range [low, high] (the bounds DomainRandRanges.validate allows any
# randomization range to take): a value outside (a negative mass or friction) would give NaN metrics
ROBOT_RANGES = {
    "robot_trunk_mass_kg": (0.5, 50.0),
    "robot_com_shift_m": (-0.5, 0.5),
    "robot_foot_friction": (0.0, 5.0),
    "robot_joint_kp": (0.0, 500.0),
    "robot_joint_kd": (0.0, 50.0),
    "robot_platform_kp_factor": (0.0, 100.0),
    "robot_platform_kd_factor": (0.0, 100.0),
}


class BenchmarkFileError(ValueError):
    """A benchmark file is missing or malformed; the message names the file and the problem."""


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
        low, high = ROBOT_RANGES[key]
        outside = (a < low) | (a > high)
        if np.any(outside):
            row = int(np.flatnonzero(outside.reshape(r, -1).any(axis=1))[0])
            raise BenchmarkFileError(
                f"{path}: {key!r} of robot {row} is {a[row].tolist()}, outside its physical range "
                f"[{low:g}, {high:g}]"
            )
        robots[name] = a.astype(np.float64)
    return Benchmark(traj, Intrinsics(**robots), int(get("seed")))


def sha256(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


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
    ap = argparse.ArgumentParser(prog="python -m lasmp.eval.benchmark", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    pg = sub.add_parser("generate", help="draw Xi_eval and write it")
    pg.add_argument("--out", default=DEFAULT_PATH)
    pg.add_argument("--seed", type=int, default=0)
    pg.add_argument("--num-trajectories", type=int, default=DEFAULT_NUM_TRAJECTORIES)
    pg.add_argument("--num-robots", type=int, default=DEFAULT_NUM_ROBOTS)
    pg.add_argument("--json", action="store_true", help="print one JSON object only")
    pi = sub.add_parser("info", help="statistics and sha256 of an existing file")
    pi.add_argument("file")
    pi.add_argument("--json", action="store_true", help="print one JSON object only")
    args = ap.parse_args(argv)
    if args.cmd == "generate":
        if args.num_trajectories < 1 or args.num_robots < 1:
            ap.error("--num-trajectories and --num-robots must be >= 1")
        bench = generate(args.num_trajectories, args.num_robots, args.seed)
        save(args.out, bench)
        path = args.out
    else:
        path = args.file
        try:
            bench = load(path)
        except BenchmarkFileError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
    _report(describe(path, bench), args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
