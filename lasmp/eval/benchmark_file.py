"""The benchmark file: its format, its writing and its checked reading.

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
"""

from __future__ import annotations

import contextlib
import io
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from lasmp.config.base import DomainRandCfg
from lasmp.envs import trajectories as T
from lasmp.envs.moving_platform.domain_rand import Intrinsics
from lasmp.eval.benchmark_set import Benchmark, generate
from lasmp.io.atomic import TEMPORARY_SUFFIX, AtomicWriteError, atomic_open
from lasmp.io.inputs import InputError, check_seed

FORMAT_NAME = "lasmp-benchmark"
FORMAT_VERSION = 2  # 2: approximating B-splines, the construction recorded (spline, spline_degree)
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


class BenchmarkFileError(ValueError):
    """A benchmark file is missing or malformed; the message names the file and the problem."""


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
