"""The LAS-MP+ screening table (docs/screening.md) from results/screen/<candidate>/seed<k>/.

    python scripts/screen_table.py

Per candidate and seed: collision on Xi_eval's first 2,000 episodes (metrics_2000.json; for the paper's
recipe, the three-seed study's runs at 450 iterations, read from their episodes.csv.gz: `lasmp` under the
bfloat16 learner, `lasmp_float32` under float32, the learner of the screening runs on a CPU without
AVX-512), the height violation and the world tilt (rotation deviation) there, the stance, and
the mirror evaluation on the first 1,024 (mirror_1024.json) where it ran, and the collision rate where
the policies fail most (docs/screening.md#where-the-policies-fail): in the episodes whose trunk CoM is
shifted 0.2 m or more sideways, and in those of N >= 11 waypoints (from episodes_2000.csv.gz, or, where
the records are no longer in the tree, from hard_cases_2000.json, which `--store-hard-cases` wrote from
them with their digest).

    python scripts/screen_table.py [--store-hard-cases]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from lasmp.eval import episodes as ep
from lasmp.eval import metrics
from lasmp.io.atomic import atomic_open
from lasmp.io.inputs import InputError, read_json

ROOT = Path(__file__).resolve().parents[1]
SCREEN = ROOT / "results" / "screen"
# the paper's recipe: candidate -> the study's runs (bfloat16 learner; float32 learner, seeds 0 and 1)
BASELINES = {
    "lasmp": ROOT / "results" / "study" / "lasmp",
    "lasmp_float32": ROOT / "results" / "study" / "float32_learner" / "lasmp",
}


def _fmt(x, f=".3f"):
    return "–" if x is None else format(x, f)


def hard_cases(episodes: dict) -> tuple[float, float]:
    """The collision rate of the first 2,000 episodes with |CoM y| >= 0.2 m, and with N >= 11."""
    first = episodes["episode"] < 2000
    collided = episodes["collided"] > 0.5
    wide = first & (abs(episodes["com_shift_y_m"]) >= 0.2)
    many = first & (episodes["n_waypoints"] >= 11)
    return float(collided[wide].mean()), float(collided[many].mean())


RECORDS_2000 = "episodes_2000.csv.gz"
HARD_CASES_FILE = "hard_cases_2000.json"  # the two hard-case rates, kept when the records leave the tree


def store_hard_cases(seed_dir: Path) -> Path:
    """Write `seed_dir`'s hard-case rates, computed from its records, with the records' digest."""
    records = seed_dir / RECORDS_2000
    wide, many = hard_cases(ep.read_csv(records))
    out = seed_dir / HARD_CASES_FILE
    entry = {
        "collision_com_y_ge_0.2m": wide,
        "collision_n_waypoints_ge_11": many,
        "records": RECORDS_2000,
        "records_digest": ep.file_digest(records)["sha256"],
    }
    with atomic_open(out, "w") as f:
        json.dump(entry, f, indent=1)
        f.write("\n")
    return out


def stored_hard_cases(seed_dir: Path) -> tuple[float, float]:
    """The hard cases from the records where they are, else from what `store_hard_cases` kept."""
    if (seed_dir / RECORDS_2000).exists():
        return hard_cases(ep.read_csv(seed_dir / RECORDS_2000))
    kept = read_json(seed_dir / HARD_CASES_FILE)
    return kept["collision_com_y_ge_0.2m"], kept["collision_n_waypoints_ge_11"]


def row(cand: str, seed_dir: Path) -> str | None:
    m2000 = seed_dir / "metrics_2000.json"
    if m2000.exists():
        r = read_json(m2000)
        summary, gait = r["metrics"], r.get("gait") or {}
        wide, many = stored_hard_cases(seed_dir)
    elif cand not in BASELINES:  # trained only part of the way (a policy checkpoint kept): no row yet
        return None
    else:  # the paper's recipe: the study's run of this seed, from its records (derived data)
        records = ep.episodes_path(BASELINES[cand] / seed_dir.name)
        if not records.exists():
            return None
        rows = ep.read_csv(records)
        first = rows["episode"] < 2000
        # as evaluate.py summarizes its 2,000 episodes: the mean over 10 consecutive batches
        per_episode = {
            "collision": rows["collided"][first],
            **{m: rows[m][first] for m in metrics.METRICS[1:]},
        }
        summary, gait = metrics.summarize(per_episode), {}
        wide, many = hard_cases(rows)
    coll, height, tilt = (
        summary[m]["mean"] for m in ("collision_rate", "height_violation_rate", "rotation_deviation_rad")
    )
    mirror_file = seed_dir / "mirror_1024.json"
    mirror = read_json(mirror_file) if mirror_file.exists() else {}
    mr = mirror.get("mirror", {})
    gait = gait or mirror.get("gait", {})
    legs = mr.get("original_legs"), mr.get("mirrored_legs_as_original")
    legs_txt = (
        "–" if legs[0] is None else " / ".join("".join(f"{v} " for v in d.values()).strip() for d in legs)
    )
    return (
        f"| {cand} | {seed_dir.name[4:]} | {_fmt(coll)} | {_fmt(height)} | {_fmt(tilt)} | {_fmt(gait.get('four_feet_step_share'))} | "
        f"{_fmt(gait.get('episodes_with_foot_up_over_2s'))} | {_fmt(gait.get('median_longest_air_s'), '.2f')} | "
        f"{_fmt(mr.get('failure_overlap'))} | {legs_txt} | {_fmt(wide)} | {_fmt(many)} |"
    )


def main(argv: list[str] | None = None) -> None:
    """Print the table; a record that is missing or unreadable ends it with one line naming the file."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--store-hard-cases", action="store_true", help=f"write {HARD_CASES_FILE} beside every {RECORDS_2000}"
    )
    args = parser.parse_args(argv)
    try:
        if args.store_hard_cases:
            for records in sorted(SCREEN.glob(f"*/seed*/{RECORDS_2000}")):
                print(f"wrote {store_hard_cases(records.parent)}")
            return
        print_table()
    except (ep.EpisodesFileError, InputError) as err:  # the one line that names the file (and how to fix it)
        raise SystemExit(f"error: {err}") from None


def print_table() -> None:
    print(
        "| candidate | seed | collision (2,000) | height violation (2,000) | world tilt (rad) | steps on four feet | episodes with a foot "
        "up > 2 s | median longest air phase (s) | mirror overlap (1,024) | failures per leg FR FL RR RL: "
        "original / twins relabelled | collision, \\|CoM y\\| >= 0.2 m | collision, N >= 11 |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    screened = {p.name: p for p in SCREEN.iterdir() if p.is_dir()}
    missing = []  # the baselines' seed directories whose records are not in the tree
    for cand in sorted({*screened, *BASELINES}):
        # a baseline's seeds: its mirror evaluation's directories where it has them, else the study's
        source = screened.get(cand, BASELINES.get(cand))
        for seed_dir in sorted(p for p in source.glob("seed*") if p.is_dir()):  # not seed<k>.commands
            if cand == "lasmp_float32" and seed_dir.name == "seed2":  # float32 to 244, then bfloat16
                continue
            line = row(cand, seed_dir)
            if line:
                print(line)
            elif cand in BASELINES:
                missing.append(BASELINES[cand] / seed_dir.name)
    if missing:
        dirs = " ".join(str(d.relative_to(ROOT)) for d in missing)
        print(f"\nThe paper's recipe's rows need the study's records: python -m lasmp.eval.regenerate {dirs}")


if __name__ == "__main__":
    main()
