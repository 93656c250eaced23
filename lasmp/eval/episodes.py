"""One record per benchmark episode (`episodes.csv.gz`) and a physics bound on what any controller can do.

A benchmark figure is a mean over episodes that differ wildly: a 4-waypoint drift and a 16-waypoint
0.7 rad tumble count the same. The per-episode record says which episodes fail, and whether the
world left the robot any chance (docs/evaluation.md#episodescsvgz).

The platform probe's columns (PROBE_COLUMNS) come from `lasmp.eval.platform_probe`.

The CSV: a header row, then one row per episode in benchmark order; empty cells are "no value"
(NaN: no counted step, no collision, no probe). evaluate.py writes it gzip-compressed (10,000 rows
are 5 MB of text); records written before that are plain `episodes.csv`. `read_csv` reads either
back, checked (each episode in one row); `episodes_path` finds a directory's.
"""

from __future__ import annotations

import csv
import gzip
import hashlib
import io
import zlib
from pathlib import Path

import numpy as np

from lasmp.envs.moving_platform.scene import PLATFORM_JOINTS
from lasmp.eval.failure import FAILURE_KEYS
from lasmp.eval.gait import GAIT_KEYS
from lasmp.eval.metrics import EXTRA_METRICS, METRICS
from lasmp.io.atomic import atomic_open

AXES = tuple(j.removeprefix("plf_") for j in PLATFORM_JOINTS)  # x, y, z, yaw, pitch, roll
PROBE_COLUMNS = (
    "platform_tilt_max_rad",
    "platform_acc_max_mps2",
    "block_offset_max_m",
    "block_contact_lost",
    "forced",
    "forced_time_s",
)
PER_EPISODE_METRICS = tuple(m for m in METRICS + EXTRA_METRICS if m != "collision_rate")
COLUMNS = (
    "episode",
    "n_waypoints",
    "robot",
    "trunk_mass_kg",
    "com_shift_x_m",
    "com_shift_y_m",
    "com_shift_z_m",
    "foot_friction",
    "joint_kp_mean",
    "joint_kd_mean",
    *(f"platform_kp_factor_{a}" for a in AXES),
    *(f"platform_kd_factor_{a}" for a in AXES),
    "collided",
    "collision_time_s",
    "collision_cause",
    "steps",
    *PER_EPISODE_METRICS,
    *PROBE_COLUMNS,
)
TEXT_COLUMNS = ("collision_cause",)
# written since the stance (lasmp/eval/gait.py) and the state at failure (lasmp/eval/failure.py) were
# measured; read where present, NaN in older files
OPTIONAL_COLUMNS = (*GAIT_KEYS, *FAILURE_KEYS)
WRITTEN_COLUMNS = (*COLUMNS, *OPTIONAL_COLUMNS)


# evaluate.py's per-episode records, gzip-compressed; older evaluation directories hold the plain .csv
EPISODES_FILE = "episodes.csv.gz"
MIRROR_EPISODES_FILE = "episodes_mirror.csv.gz"
GZIP_MAGIC = b"\x1f\x8b"  # the first two bytes of every gzip file


class EpisodesFileError(ValueError):
    """An episodes file is missing or malformed; the message names the file and the problem."""


def episodes_path(directory: str | Path) -> Path:
    """An evaluation directory's record: its episodes.csv.gz, else the plain episodes.csv of an
    evaluation made before evaluate.py compressed it; the .csv.gz when there is neither, so that
    reading it names the file evaluate.py writes."""
    directory = Path(directory)
    plain = directory / EPISODES_FILE.removesuffix(".gz")
    compressed = directory / EPISODES_FILE
    return plain if plain.is_file() and not compressed.is_file() else compressed


REGENERATE = "python -m lasmp.eval.regenerate"  # lasmp/eval/regenerate.py


def missing_records(path: str | Path) -> str:
    """The one line a reader of a missing episodes file says: the records are derived data, not
    committed (a clone stays light), and one command makes them again from the run's policy."""
    path = Path(path)
    return (
        f"{path}: no such file; per-episode records are derived data: regenerate them with "
        f"`{REGENERATE} {path.parent}` (or evaluate.py writes them beside metrics.json)"
    )


# -- the records' digest -----------------------------------------------------------------------
# metrics.json's key: episodes file name -> the digest of its records (`table_digest`)
DIGEST_KEY = "episode_records"
COLUMN_DIGEST_HEX = 16  # per column, enough to tell which columns differ


def _digest(columns: list[str], cells: dict[str, list[str]]) -> dict:
    per_column = {c: hashlib.sha256("\n".join(cells[c]).encode()).hexdigest() for c in columns}
    whole = hashlib.sha256("\n".join(f"{c}:{per_column[c]}" for c in columns).encode()).hexdigest()
    return {
        "sha256": whole,
        "rows": len(cells[columns[0]]) if columns else 0,
        "columns": {c: h[:COLUMN_DIGEST_HEX] for c, h in per_column.items()},
    }


def table_digest(table: dict[str, np.ndarray], columns: tuple[str, ...] = WRITTEN_COLUMNS) -> dict:
    """The digest of the records `write_csv(path, table, columns)` writes: a SHA-256 over every column's
    cells as the CSV holds them (full float precision, an empty cell for no value), and a short one per
    column. Why cells, not bytes: the same records give the same digest whatever the file's
    compression, and a parsed file gives it again (`file_digest`), so a regenerated file can be checked
    against the digest metrics.json kept after the file itself was removed."""
    n = len(table[columns[0]])
    table = {**{c: np.full(n, np.nan) for c in OPTIONAL_COLUMNS}, **table}
    return _digest(list(columns), {c: [_cell(v) for v in table[c]] for c in columns})


def file_digest(path: str | Path, columns: list[str] | None = None) -> dict:
    """`table_digest` of an episodes file (plain or gzip-compressed CSV), over the columns its header
    names (or `columns`, in that order: a digest taken before a column was added covers the others):
    each cell parsed and written again as the CSV writer writes it (a number in full precision, text as
    it is), so that it equals the digest of the records it was written from."""
    path = Path(path)
    opener = gzip.open if _is_gzip(path) else open
    try:
        with opener(path, "rt", newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
    except (OSError, EOFError, zlib.error, UnicodeDecodeError, csv.Error) as err:
        raise EpisodesFileError(f"{path}: unreadable ({err})") from None
    if not rows:
        raise EpisodesFileError(f"{path}: empty (no header row)")
    header, body = rows[0], rows[1:]
    if any(len(row) != len(header) for row in body):
        raise EpisodesFileError(f"{path}: a row's cells do not match the header's {len(header)}")
    cells = {c: [_canonical(row[j]) for row in body] for j, c in enumerate(header)}
    if columns is not None:
        lacking = [c for c in columns if c not in cells]
        if lacking:
            raise EpisodesFileError(f"{path}: no column {lacking[0]!r}")
        return _digest(list(columns), {c: cells[c] for c in columns})
    return _digest(header, cells)


def _canonical(cell: str) -> str:
    """A CSV cell as `_cell` writes its value: a number in full precision, text unchanged."""
    if cell == "" or not _is_float(cell):
        return cell
    return _cell(float(cell))


def _is_gzip(path: Path) -> bool:
    with open(path, "rb") as f:
        return path.suffix == ".gz" or f.read(len(GZIP_MAGIC)) == GZIP_MAGIC


def digest_differences(stored: dict, got: dict) -> list[str]:
    """The columns whose records differ between two digests (a column one lacks included), and a
    row count that differs; empty when the digests match."""
    if stored["sha256"] == got["sha256"]:
        return []
    out = [f"rows {stored['rows']} -> {got['rows']}"] if stored["rows"] != got["rows"] else []
    a, b = stored["columns"], got["columns"]
    return out + [c for c in dict.fromkeys([*a, *b]) if a.get(c) != b.get(c)]


# -- the block ---------------------------------------------------------------------------------


def episode_table(
    bench, episodes: dict[str, np.ndarray], probe: dict[str, np.ndarray] | None
) -> dict[str, np.ndarray]:
    """COLUMNS -> (K,) arrays for the first K benchmark episodes: their trajectory's N, their robot's
    intrinsics, how they ended and their metrics (`run_benchmark`'s episodes), the probe's columns
    (NaN without a probe)."""
    k = len(episodes["collision"])
    traj_rows, robot_rows = bench.pairing(np.arange(k))
    rb = bench.robots
    t = {
        "episode": np.arange(k),
        "n_waypoints": np.asarray(bench.trajectories.n_waypoints)[traj_rows],
        "robot": robot_rows,
        "trunk_mass_kg": rb.trunk_mass_kg[robot_rows],
        **{f"com_shift_{a}_m": rb.com_shift_m[robot_rows, i] for i, a in enumerate("xyz")},
        "foot_friction": rb.foot_friction[robot_rows],
        "joint_kp_mean": rb.joint_kp[robot_rows].mean(axis=1),
        "joint_kd_mean": rb.joint_kd[robot_rows].mean(axis=1),
        **{f"platform_kp_factor_{a}": rb.platform_kp_factor[robot_rows, i] for i, a in enumerate(AXES)},
        **{f"platform_kd_factor_{a}": rb.platform_kd_factor[robot_rows, i] for i, a in enumerate(AXES)},
        "collided": episodes["collision"],
        "collision_time_s": episodes["collision_time_s"],
        "collision_cause": episodes["collision_cause"],
        "steps": episodes["steps"],
        **{m: episodes[m] for m in PER_EPISODE_METRICS},
        **{g: episodes[g] for g in GAIT_KEYS},
        **{f: episodes[f] for f in FAILURE_KEYS if f in episodes},
    }
    for key in PROBE_COLUMNS:
        t[key] = np.full(k, np.nan) if probe is None else probe[key]
    return t


def _cell(value) -> str:
    if isinstance(value, str):
        return value
    value = float(value)
    if not np.isfinite(value):
        return ""
    return str(int(value)) if value.is_integer() and abs(value) < 2**53 else repr(value)


def write_csv(path: Path, table: dict[str, np.ndarray], columns: tuple[str, ...] = WRITTEN_COLUMNS) -> None:
    """`table`'s `columns` (default: Xi_eval's) as CSV at `path`, atomically; gzip-compressed when
    `path` ends in .gz, with no time stamp in the gzip header (mtime 0), so that a rerun that gives
    the same table writes the same bytes."""
    text = io.StringIO()
    w = csv.writer(text, lineterminator="\n")
    w.writerow(columns)
    n = len(table[columns[0]])
    # an optional column the table lacks is written empty (a record made before it was measured)
    table = {**{c: np.full(n, np.nan) for c in OPTIONAL_COLUMNS}, **table}
    for i in range(n):
        w.writerow([_cell(table[c][i]) for c in columns])
    data = text.getvalue().encode()
    if Path(path).suffix == ".gz":
        data = gzip.compress(data, compresslevel=9, mtime=0)
    with atomic_open(path, "wb") as f:
        f.write(data)


def read_csv(path) -> dict[str, np.ndarray]:
    """An episodes file, plain or gzip-compressed CSV (told by its first two bytes or a .gz suffix),
    as COLUMNS -> arrays (float, NaN for empty cells; text columns as str)."""
    path = Path(path)
    if not path.is_file():
        raise EpisodesFileError(missing_records(path))
    compressed = path.suffix == ".gz"
    try:
        with open(path, "rb") as f:
            compressed = compressed or f.read(len(GZIP_MAGIC)) == GZIP_MAGIC
        with (gzip.open if compressed else open)(path, "rt", newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
    # a truncated gzip stream raises EOFError, a corrupt one zlib.error or gzip.BadGzipFile (an OSError)
    except (OSError, EOFError, zlib.error, UnicodeDecodeError, csv.Error) as err:
        what = "gzip-compressed CSV" if compressed else "CSV"
        raise EpisodesFileError(f"{path}: unreadable as {what} ({err})") from None
    if not rows:
        raise EpisodesFileError(f"{path}: empty (no header row)")
    header, body = rows[0], rows[1:]
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise EpisodesFileError(f"{path}: not an episodes file, columns missing: {', '.join(missing)}")
    if not body:
        raise EpisodesFileError(f"{path}: no episode rows")
    col = {c: header.index(c) for c in WRITTEN_COLUMNS if c in header}
    out = {}
    for c, j in col.items():
        try:
            cells = [row[j] for row in body]
        except IndexError:
            short = next(i for i, row in enumerate(body) if len(row) <= j)
            raise EpisodesFileError(
                f"{path}: row {short + 2} has {len(body[short])} cells, the header {len(header)}"
            ) from None
        if c in TEXT_COLUMNS:
            out[c] = np.array(cells, dtype=object)
            continue
        try:
            out[c] = np.array([float(x) if x != "" else np.nan for x in cells])
        except ValueError:
            bad = next(i for i, x in enumerate(cells) if x != "" and not _is_float(x))
            raise EpisodesFileError(
                f"{path}: row {bad + 2}, column {c!r}: not a number: {cells[bad]!r}"
            ) from None
    for c in OPTIONAL_COLUMNS:
        out.setdefault(c, np.full(len(body), np.nan))
    check_episode_keys(path, out["episode"])
    return out


def check_episode_keys(path, episode: np.ndarray) -> None:
    """Each row's `episode` is a whole number >= 0, and no episode has two rows: every figure read
    from the record counts each episode once (a row pasted twice would count its collision twice).
    EpisodesFileError naming the file, the episode and its rows (as numbered in the file)."""
    bad = np.flatnonzero(~np.isfinite(episode) | (episode < 0) | (episode != np.round(episode)))
    if len(bad):
        raise EpisodesFileError(
            f"{path}: row {bad[0] + 2}: the episode must be a whole number >= 0, got {episode[bad[0]]!r}"
        )
    keys, counts = np.unique(episode, return_counts=True)
    if (counts > 1).any():
        k = int(np.argmax(counts > 1))
        rows = np.flatnonzero(episode == keys[k]) + 2
        raise EpisodesFileError(
            f"{path}: episode {int(keys[k])} appears {counts[k]} times (rows "
            f"{', '.join(map(str, rows[:4]))}{', ...' if len(rows) > 4 else ''}); a record holds each "
            "episode once: remove the repeated rows, or evaluate again"
        )


def _is_float(x: str) -> bool:
    try:
        float(x)
        return True
    except ValueError:
        return False
