"""The trajectory file format (``.npz``, version 2): :func:`save`, :func:`load`, and helpers.

``format`` = "lasmp-trajectories", ``version`` = 2, ``kind`` = one of

* "waypoints" (generated sets, compact): ``knot_times_s`` (M, Kmax) float64 and
  ``waypoints`` (M, Kmax, 6) float64 -- the knots *including* knot 0 (t = 0, zero pose) --
  padded at the end of each row with NaN; ``n_waypoints`` (M,) int (row m has
  ``n_waypoints[m] + 1`` knots); ``spline`` ("approximating" or "interpolating") and
  ``spline_degree`` (int): the construction, so the file rebuilds the same motion whatever
  today's defaults are.
* "samples" (user-made): ``t_s`` (K,) shared times, or (M, K) per-row times padded at the
  end with NaN, and ``poses`` (M, K, 6) (NaN where the times are NaN). Rebuilt with
  not-a-knot ends.

Optional ``meta_json``: a JSON string (e.g. split and seed), available as ``traj.meta``.
A motion far outside any platform's physical range (a waypoint 1,000 km away, a whole path in a
tenth of a second) is refused, and one well beyond the hardest we know is warned about
(:func:`check_physical`, ``PHYSICAL_RANGE``).
Version 1 files (interpolating-cubic waypoints, with no record of the spline construction) are
refused with an error that says how to regenerate them.

:func:`read_npz`, :func:`check_version`, :func:`waypoint_arrays` and :func:`waypoints_from_arrays`
are shared with the benchmark file (:mod:`lasmp.eval.benchmark`), which stores its trajectories
in the "waypoints" layout.
"""

from __future__ import annotations

import json
import math
import os
import warnings
import zipfile

import numpy as np

from lasmp.envs.trajectories.splines import KIND_NAMES, SAMPLES, PiecewisePoly, SplineSpec
from lasmp.envs.trajectories.user_made import TrajectoryFileError, check_knots
from lasmp.io.atomic import atomic_open

FORMAT_NAME = "lasmp-trajectories"
FORMAT_VERSION = 2

# quantity: (unit, warn above, refuse above), of the motion the spline makes (knots included for the
# positions). The hardest motions we know stay far below the warnings: the generated sets with
# interpolating splines (11 m/s, 73 m/s^2, 63 rad/s^2) and the real-motion suite (a 131 m train ride
# at 18 m/s, a lift's emergency stop at 6 m/s^2); above the refusals no vehicle moves
PHYSICAL_RANGE = {
    "position": ("m", 1e3, 1e4),
    "angle": ("rad", 20.0, 100.0),
    "speed": ("m/s", 50.0, 340.0),
    "angular speed": ("rad/s", 30.0, 100.0),
    "acceleration": ("m/s^2", 150.0, 1e3),
    "angular acceleration": ("rad/s^2", 150.0, 1e3),
}
# the most memory the arrays of one .npz file may take (check_npz_members): 100 times Xi_eval's 10,000
# trajectories; a user-made set of 10,000 rows sampled every 0.02 s over 10 s takes 230 MiB
MAX_NPZ_BYTES = 2**30
_PEAK_POINTS = np.linspace(0.0, 1.0, 3)  # where each polynomial piece is evaluated: ends and middle


def _peaks(traj: PiecewisePoly) -> dict[str, np.ndarray]:
    """Per row, the largest value of each PHYSICAL_RANGE quantity over its polynomial pieces (each
    evaluated at _PEAK_POINTS of its length) and, for the positions, over its knots."""
    c = traj.coeffs  # (M, S, D+1, 6): pos = sum_j c_j tau^j on each piece
    valid = np.arange(c.shape[1])[None, :] < traj.n_segments[:, None]  # (M, S)
    b = np.where(np.isfinite(traj.breaks_s), traj.breaks_s, 0.0)
    h = np.where(valid, np.diff(b, axis=1), 0.0)  # the pieces' lengths, s (0 for padding)
    tau = (h[:, :, None] * _PEAK_POINTS)[..., None]  # (M, S, P, 1)
    pos = np.broadcast_to(c[:, :, None, -1], tau.shape[:3] + (6,)).copy()
    vel, half_acc = np.zeros_like(pos), np.zeros_like(pos)
    for j in range(c.shape[2] - 2, -1, -1):  # Horner with derivatives, as PiecewisePoly.evaluate
        half_acc = half_acc * tau + vel
        vel = vel * tau + pos
        pos = pos * tau + c[:, :, None, j]
    acc = 2.0 * half_acc
    mask = valid[:, :, None]

    def peak(x, lin: bool):
        v = np.linalg.norm(x[..., :3], axis=-1) if lin else np.abs(x[..., 3:]).max(axis=-1)
        return np.where(mask, v, 0.0).max(axis=(1, 2))

    knots = np.nan_to_num(traj.knot_poses)
    return {
        "position": np.maximum(peak(pos, True), np.linalg.norm(knots[..., :3], axis=-1).max(axis=1)),
        "angle": np.maximum(peak(pos, False), np.abs(knots[..., 3:]).max(axis=(1, 2))),
        "speed": peak(vel, True),
        "angular speed": peak(vel, False),
        "acceleration": peak(acc, True),
        "angular acceleration": peak(acc, False),
    }


def check_physical(traj: PiecewisePoly, path: str, error: type[Exception] = TrajectoryFileError) -> None:
    """Raise `error` for a motion beyond PHYSICAL_RANGE's refusals (naming the row, the quantity and
    the path's duration); warn once for those beyond its warnings."""
    if len(traj) == 0:
        return
    peaks = _peaks(traj)
    unusual = []
    for name, (unit, warn, refuse) in PHYSICAL_RANGE.items():
        row = int(np.argmax(peaks[name]))
        value = float(peaks[name][row])
        said = f"row {row}: {name} {value:.3g} {unit} (its path lasts {float(traj.duration_s[row]):.3g} s)"
        if not value <= refuse:  # NaN included
            raise error(
                f"{path}: {said} is far outside the physical range of a platform's motion (refused above "
                f"{refuse:g} {unit}): check the file's units and times"
            )
        if value > warn:
            unusual.append(f"{said}, above {warn:g} {unit}")
    if unusual:
        warnings.warn(
            f"{path}: beyond the physical range of any platform motion we know: {'; '.join(unusual)}. "
            "Check the file's units and times",
            stacklevel=3,
        )


def waypoint_arrays(traj: PiecewisePoly) -> dict[str, np.ndarray]:
    """The "waypoints" layout of a generated set (one construction): knots, N, spline kind and degree."""
    kinds, degrees = np.unique(traj.kind), np.unique(traj.degree)
    if len(kinds) != 1 or int(kinds[0]) == SAMPLES or len(degrees) != 1:
        raise ValueError(
            "a waypoints file holds generated rows of one construction (kind and degree); "
            f"got kinds {[KIND_NAMES[k] for k in kinds]} and degrees {degrees.tolist()}"
        )
    return {
        "knot_times_s": np.ascontiguousarray(traj.knot_times_s, dtype=np.float64),
        "waypoints": np.ascontiguousarray(traj.knot_poses, dtype=np.float64),
        "n_waypoints": np.ascontiguousarray(traj.n_knots - 1, dtype=np.int64),
        "spline": np.array(KIND_NAMES[int(kinds[0])]),
        "spline_degree": np.array(int(degrees[0]), dtype=np.int64),
    }


def save(path, traj: PiecewisePoly, meta: dict | None = None) -> None:
    """Write ``traj`` to ``path`` (used verbatim, no suffix added) atomically (temp file + os.replace)."""
    path = os.fspath(path)
    arrays: dict[str, np.ndarray] = {"format": np.array(FORMAT_NAME), "version": np.array(FORMAT_VERSION)}
    if np.all(traj.kind == SAMPLES):
        t = traj.knot_times_s
        shared = bool(np.all(traj.n_knots == t.shape[1])) and bool(np.all(t == t[:1]))
        arrays.update(kind=np.array("samples"), t_s=t[0].copy() if shared else t, poses=traj.knot_poses)
    elif np.any(traj.kind == SAMPLES):
        raise ValueError("save: cannot store a set mixing generated and user-made rows; save them separately")
    else:
        arrays.update(kind=np.array("waypoints"), **waypoint_arrays(traj))
    meta = {**traj.meta, **(meta or {})}
    if meta:
        arrays["meta_json"] = np.array(json.dumps(meta))
    with atomic_open(path) as f:
        np.savez(f, **arrays)  # a file object: savez appends no ".npz"


def _human(nbytes: int) -> str:
    return f"{nbytes / 2**30:.1f} GiB" if nbytes >= 2**30 else f"{nbytes / 2**20:.1f} MiB"


def _member_header(f) -> tuple[tuple[int, ...], np.dtype, int]:
    """(shape, dtype, header length) of the .npy array an open zip member starts with, from its header
    alone (numpy's own readers; headers over 10,000 bytes are refused by them)."""
    version = np.lib.format.read_magic(f)
    if version == (1, 0):
        shape, _, dtype = np.lib.format.read_array_header_1_0(f)
    elif version == (2, 0):
        shape, _, dtype = np.lib.format.read_array_header_2_0(f)
    else:  # 3.0 (a utf-8 header): numpy's reader of it is private (numpy 2: in _format_impl)
        impl = getattr(np.lib, "_format_impl", np.lib.format)
        shape, _, dtype = impl._read_array_header(f, version)
    return tuple(int(n) for n in shape), dtype, f.tell()


def check_npz_members(path: str, error: type[Exception], max_bytes: int = MAX_NPZ_BYTES) -> None:
    """Raise `error` unless `path` is a zip archive whose members, read from their headers only, fit
    in `max_bytes` of memory together. Why: np.load allocates the shape an array's header declares
    and inflates a compressed member in full, so a file of 8 MB can hold an 8 GiB array of zeros
    (it took `trajectories stats` 37 s and 8 GiB); here nothing is inflated beyond the headers, and
    a member whose size disagrees with its header (truncated, or a header that lies) is refused."""
    try:
        with zipfile.ZipFile(path) as zf:
            total, largest = 0, ("", 0, "")
            for info in zf.infolist():
                with zf.open(info) as f:
                    if f.read(6) == b"\x93NUMPY":
                        f.seek(0)
                        shape, dtype, header = _member_header(f)
                        nbytes = math.prod(shape) * dtype.itemsize
                        what = f"{dtype} array of shape {shape}"
                    else:  # np.load returns any other member as its bytes
                        header, nbytes, what = 0, info.file_size, "member"
                if nbytes > largest[1]:
                    largest = (info.filename.removesuffix(".npy"), nbytes, what)
                total += nbytes
                if total > max_bytes:
                    name, size, kind = largest
                    raise error(
                        f"{path}: its arrays would take more than {_human(max_bytes)} in memory ({name!r}: a "
                        f"{kind}, {_human(size)}): refused before loading them. A corrupt or hostile "
                        "file? (Xi_eval's 10,000 trajectories take 10 MiB)"
                    )
                if header and info.file_size != header + nbytes:
                    raise error(
                        f"{path}: member {info.filename!r} holds {info.file_size} bytes, but its header "
                        f"declares a {what} ({header + nbytes} bytes): truncated or corrupt"
                    )
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, KeyError) as exc:
        if isinstance(exc, error):
            raise
        raise error(f"{path}: not a readable .npz archive (truncated or corrupt?): {exc}") from None


def read_npz(path: str, error: type[Exception], max_bytes: int = MAX_NPZ_BYTES):
    """Read every array of an .npz file, each checked from its header first (check_npz_members); return
    `get(key, optional=False)`, which raises `error` naming the file and a missing key (or returns
    None for a missing optional one). An unreadable or non-.npz file raises `error` too. Every .npz
    reader (trajectory and benchmark files) goes through here."""
    try:
        with open(path, "rb") as f:
            single = f.read(6) == b"\x93NUMPY"
    except OSError as exc:
        raise error(f"{path}: cannot be read: {exc.strerror or exc}") from None
    if single:
        raise error(f"{path}: not an .npz archive (it holds a single .npy array)")
    check_npz_members(path, error, max_bytes)
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, KeyError) as exc:
        raise error(f"{path}: not a readable .npz archive (truncated or corrupt?): {exc}") from None

    def get(key: str, optional: bool = False) -> np.ndarray | None:
        if key not in data:
            if optional:
                return None
            raise error(f"{path}: missing key {key!r} (keys present: {sorted(data)})")
        return data[key]

    return get


def _text(get, path: str, key: str, error: type[Exception]) -> str:
    v = get(key)
    if v.shape != () or v.dtype.kind != "U":
        raise error(f"{path}: key {key!r} must be a string")
    return str(v)


def check_version(get, path: str, expected: int, error: type[Exception], regenerate: str) -> None:
    """Refuse a file of another format version, saying how to make a current one."""
    version = get("version")
    if version.shape != () or version.dtype.kind not in "iu":
        raise error(f"{path}: 'version' must be an integer scalar, got {version.dtype} {version.shape}")
    if int(version) != expected:
        hint = (
            " Version 1 files hold interpolating-cubic waypoints with no record of the spline "
            "construction; they cannot be read as today's approximating B-splines."
            if int(version) < expected
            else ""
        )
        raise error(f"{path}: unsupported version {int(version)}, expected {expected}.{hint} {regenerate}")


def waypoints_from_arrays(get, path: str, error: type[Exception]) -> PiecewisePoly:
    """Validate and build the "waypoints" layout (waypoint_arrays) read through `get`."""
    t, p, nw = get("knot_times_s"), get("waypoints"), get("n_waypoints")
    for key, arr in (("knot_times_s", t), ("waypoints", p)):
        if arr.dtype.kind != "f":
            raise error(f"{path}: {key!r} must be float, got {arr.dtype}")
    if t.ndim != 2 or t.shape[0] < 1 or p.shape != t.shape + (6,):
        raise error(
            f"{path}: wrong shape: 'knot_times_s' must be (M, K) and 'waypoints' (M, K, 6), "
            f"got {t.shape} and {p.shape}"
        )
    if nw.dtype.kind not in "iu" or nw.shape != (t.shape[0],):
        raise error(
            f"{path}: wrong shape: 'n_waypoints' must be int ({t.shape[0]},), got {nw.dtype} {nw.shape}"
        )
    kind = _text(get, path, "spline", error)
    degree = get("spline_degree")
    if degree.shape != () or degree.dtype.kind not in "iu":
        raise error(f"{path}: 'spline_degree' must be an integer scalar, got {degree.dtype} {degree.shape}")
    try:
        spec = SplineSpec(kind, int(degree))
    except ValueError as exc:
        raise error(f"{path}: {exc}") from None
    try:
        nk = check_knots(t.astype(np.float64), p.astype(np.float64), path)
    except TrajectoryFileError as exc:  # its message names the file already
        raise error(str(exc)) from None
    if np.any(nk != nw + 1):
        raise error(f"{path}: 'n_waypoints' disagrees with the number of knots (NaN padding) in some rows")
    traj = PiecewisePoly.from_knots(t, p, nk, spec.code, spec.degree, nw)
    check_physical(traj, path, error)
    return traj


def load(path) -> PiecewisePoly:
    """Read and validate a trajectory file; any problem raises TrajectoryFileError naming file and problem."""
    path = os.fspath(path)
    if os.path.exists(path) and not os.path.isfile(path):  # a FIFO would block, /dev/zero never end
        raise TrajectoryFileError(f"{path}: not a regular file; give a trajectory file (.npz)")
    if not os.path.isfile(path):
        raise TrajectoryFileError(f"{path}: no such trajectory file")
    get = read_npz(path, TrajectoryFileError)
    err = TrajectoryFileError
    if _text(get, path, "format", err) != FORMAT_NAME:
        raise err(f"{path}: format is {_text(get, path, 'format', err)!r}, expected {FORMAT_NAME!r}")
    check_version(
        get, path, FORMAT_VERSION, err, "Regenerate it with `python -m lasmp.envs.trajectories generate`."
    )
    kind = _text(get, path, "kind", err)
    if kind == "waypoints":
        traj = waypoints_from_arrays(get, path, err)
    elif kind == "samples":
        t, p = get("t_s"), get("poses")
        if t.dtype.kind != "f" or p.dtype.kind != "f":
            raise err(f"{path}: 't_s' and 'poses' must be float arrays")
        if t.ndim == 1:
            if p.ndim != 3 or p.shape[1:] != (t.shape[0], 6):
                raise err(f"{path}: 'poses' must be (M, K={t.shape[0]}, 6), got {p.shape}")
            t = np.broadcast_to(t, p.shape[:2])
        nk = check_knots(np.asarray(t, np.float64), p.astype(np.float64), path)
        traj = PiecewisePoly.from_knots(t, p, nk, SAMPLES, 3, np.full(len(nk), -1))
        check_physical(traj, path)
    else:
        raise err(f"{path}: unknown kind {kind!r}; valid: 'waypoints', 'samples'")
    if get("meta_json", optional=True) is not None:
        try:
            traj.meta = json.loads(_text(get, path, "meta_json", err))
        except json.JSONDecodeError as exc:
            raise err(f"{path}: 'meta_json' is not valid JSON ({exc})") from None
    return traj
