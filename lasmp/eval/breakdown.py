"""Where a method fails: the collision rate of an evaluation broken down by episode, from its record.

    python -m lasmp.eval.breakdown DIR [--plot out.png [--force]] [--late-s 8] [--episodes K] [--row LABEL]
                                       [--probe-from DIR2] [--baseline DIR3]

Reads DIR/episodes.csv.gz (written by evaluate.py; DIR/episodes.csv in evaluations made before it
compressed them) and prints, as Markdown tables, the collision rate (with the episode count behind
it) by number of waypoints N, by the platform's maximum tilt (bins of 0.1 rad, the last open), by
foot friction (bins of 0.1), by the trunk's CoM shift across (|y|) and up (z) (bins of 0.05 and 0.1 m;
training draws each axis from ±0.2 m, Xi_eval from ±0.25 m), forced vs not forced (the platform probe's
Coulomb block, lasmp.eval.episodes), the failures by cause (the first body that touched, or the fall),
and the share of failures that come after --late-s seconds (8 by default: the platform is often
still converging to its last waypoint when the episode ends). `--plot` draws the first three
breakdowns and the failure times (matplotlib; without it the plot is skipped
with a note); it does not replace an existing file without `--force`. A record with an episode in
two rows is refused (each figure counts an episode once). The tilt and forced tables need the
probe's columns; without them they say so.
`--episodes K` keeps Xi_eval's first K episodes (episode < K), so that an evaluation of all 10,000
compares with one of the first K (episode k is the same trajectory and robot in both).
`--probe-from DIR2` takes the probe's columns from another evaluation of the same episodes (one run
with the probe, e.g. Stand Still's, serves every run made with `--no-platform-probe`): the probe
replays only the platform and the episode's robot's foot friction, so it is the same for every
controller; the two files must hold the same episodes on the same robots.
The state at each failure (lasmp/eval/failure.py: the feet on the deck, the deck's and the trunk's
tilt at the collision step) is tabled where the record holds it. `--baseline DIR3` pairs the episodes
with another evaluation of them (Stand Still's) and counts the failures in the episodes it survives.
`--row LABEL` prints instead one row of docs/evaluation.md's table of runs (it needs the probe's
columns): collisions, those in forced episodes, in the tilt tail (with their share), the rate below
and in the tail, after --late-s (with their share), and the three commonest causes.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

import numpy as np

from lasmp.eval import failure
from lasmp.eval.episodes import PROBE_COLUMNS, EpisodesFileError, episodes_path, read_csv
from lasmp.io.atomic import AtomicWriteError, claim_output
from lasmp.io.inputs import InputError, check_out_file, float_arg, int_arg

TILT_BINS_RAD = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7)  # the last bin is [0.7, inf)
FRICTION_BINS = (0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3)  # the testing range, U(0.7, 1.3)
COM_Y_ABS_BINS_M = (0.0, 0.05, 0.1, 0.15, 0.2)  # the last bin, >= 0.2 m, lies beyond the training range
COM_Z_BINS_M = (-0.25, -0.2, -0.1, 0.0, 0.1, 0.2)
TAIL_TILT_RAD = 0.5


def rate_by(values: np.ndarray, collided: np.ndarray, groups) -> list[tuple[str, int, int]]:
    """(label, episodes, collisions) per group; `groups` is [(label, mask)]."""
    return [(label, int(mask.sum()), int(collided[mask].sum())) for label, mask in groups]


def primary_cause(cause: str) -> str:
    """The kind of the first thing that touched: trunk, hip, thigh, calf, or the fall / fault."""
    first = cause.split("+")[0]
    return (
        first.split("_", 1)[1] if first.count("_") == 1 and first[:2] in ("FR", "FL", "RR", "RL") else first
    )


def first_episodes(t: dict[str, np.ndarray], k: int) -> dict[str, np.ndarray]:
    """The rows of episodes 0..k-1; refuses a table that lacks any of them."""
    keep = t["episode"] < k
    if int(keep.sum()) != k:
        raise EpisodesFileError(f"asked for the first {k} episodes, the file has {int(keep.sum())} of them")
    return {c: v[keep] for c, v in t.items()}


def with_probe_from(t: dict[str, np.ndarray], other: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """`t` with PROBE_COLUMNS taken from `other`, row by episode; refuses a file that lacks one of
    t's episodes or pairs it with another robot (foot friction) or trajectory (N)."""
    row = {int(k): i for i, k in enumerate(other["episode"])}
    missing = [int(k) for k in t["episode"] if int(k) not in row]
    if missing:
        raise EpisodesFileError(
            f"--probe-from lacks {len(missing)} of the episodes, e.g. episode {missing[0]}"
        )
    idx = np.array([row[int(k)] for k in t["episode"]])
    for c in ("foot_friction", "n_waypoints"):
        if not np.array_equal(t[c], other[c][idx]):
            raise EpisodesFileError(f"--probe-from holds other episodes: its {c} differs")
    if not np.isfinite(other["platform_tilt_max_rad"][idx]).any():
        raise EpisodesFileError("--probe-from has no probe columns (run without --no-platform-probe)")
    return t | {c: other[c][idx] for c in PROBE_COLUMNS}


def breakdown(t: dict[str, np.ndarray], late_s: float = 8.0) -> dict:
    """The breakdown tables (name -> rows) and the headline figures of one episodes table."""
    collided = t["collided"] > 0.5
    n_values = np.unique(t["n_waypoints"][np.isfinite(t["n_waypoints"])]).astype(int)
    out: dict = {
        "episodes": len(collided),
        "collisions": int(collided.sum()),
        "by_n": rate_by(t["n_waypoints"], collided, [(str(n), t["n_waypoints"] == n) for n in n_values]),
        "by_friction": rate_by(
            t["foot_friction"], collided, failure.bins(t["foot_friction"], FRICTION_BINS, ".1f")
        ),
        "by_com_y": rate_by(
            None, collided, failure.bins(np.abs(t["com_shift_y_m"]), COM_Y_ABS_BINS_M, ".2f")
        ),
        "by_com_z": rate_by(None, collided, failure.bins(t["com_shift_z_m"], COM_Z_BINS_M, ".2f")),
    }
    probed = np.isfinite(t["forced"])
    out["probed"] = int(probed.sum())
    if probed.any():
        tilt = t["platform_tilt_max_rad"]
        out["by_tilt"] = rate_by(tilt, collided, failure.bins(tilt, TILT_BINS_RAD, ".1f"))
        forced = probed & (t["forced"] > 0.5)
        out["by_forced"] = rate_by(None, collided, [("forced", forced), ("not forced", probed & ~forced)])
        out["forced"] = int(forced.sum())
        tail = tilt >= TAIL_TILT_RAD
        out["tilt_tail"] = {"episodes": int(tail.sum()), "collisions": int((collided & tail).sum())}
    causes = [primary_cause(c) for c in t["collision_cause"][collided]]
    kinds = sorted(set(causes), key=lambda k: -causes.count(k))
    out["by_cause"] = [(k, causes.count(k)) for k in kinds]
    times = t["collision_time_s"][collided]
    out["late"] = {"after_s": late_s, "collisions": int((times > late_s).sum())}
    out["at_failure"] = failure.state_tables(t)
    return out


def _share(k: int, n: int, fmt: str = ".3f") -> str:
    return f"{k / n:{fmt}}" if n else "n/a"


def markdown(b: dict) -> str:
    lines = [
        f"{b['episodes']} episodes, {b['collisions']} collisions (rate {_share(b['collisions'], b['episodes'])})."
    ]

    def table(title: str, head: str, rows):
        lines.extend(
            [
                "",
                f"## {title}",
                "",
                f"| {head} | episodes | collisions | collision rate |",
                "|---|---|---|---|",
            ]
        )
        lines.extend(f"| {label} | {n} | {c} | {_share(c, n)} |" for label, n, c in rows if n)

    table("By number of waypoints N", "N", b["by_n"])
    if "by_tilt" in b:
        table("By the platform's maximum tilt (rad)", "max tilt", b["by_tilt"])
    else:
        lines += [
            "",
            "No platform-probe columns (evaluated with --no-platform-probe): no tilt or forced tables.",
        ]
    table("By foot friction", "friction", b["by_friction"])
    table("By the CoM shift across the trunk, |y| (m)", "|CoM y|", b["by_com_y"])
    table("By the CoM shift up, z (m)", "CoM z", b["by_com_z"])
    if "by_forced" in b:
        table(
            "Forced by the world (the Coulomb block slides off or loses contact) or not",
            "world",
            b["by_forced"],
        )
        tail = b["tilt_tail"]
        lines += [
            "",
            f"Tilt tail (max tilt >= {TAIL_TILT_RAD} rad): {tail['episodes']} episodes "
            f"({_share(tail['episodes'], b['episodes'])} of all), {tail['collisions']} collisions "
            f"({_share(tail['collisions'], b['collisions'])} of all collisions).",
        ]
    lines += [
        "",
        "## Failures by cause (the first body that touched, or the fall)",
        "",
        "| cause | collisions | share |",
        "|---|---|---|",
    ]
    lines += [f"| {k} | {c} | {_share(c, b['collisions'])} |" for k, c in b["by_cause"]]
    late = b["late"]
    lines += [
        "",
        f"Failures after {late['after_s']:g} s: {late['collisions']} of {b['collisions']} "
        f"({_share(late['collisions'], b['collisions'])}).",
    ]
    lines += failure.markdown(b["at_failure"], b.get("against_baseline"), b.get("baseline_name", ""))
    return "\n".join(lines)


def summary_row(b: dict, label: str) -> str:
    """One Markdown row of docs/evaluation.md's table of runs, from a breakdown with the probe's
    columns: | label | collisions | in the forced | in the tilt tail (share) | rate below / in the
    tail | late (share) | the three commonest causes (share) |."""
    if "tilt_tail" not in b:
        raise ValueError(
            "the row needs the platform probe's columns: evaluate with the probe or give --probe-from"
        )
    n, c = b["episodes"], b["collisions"]
    tail = b["tilt_tail"]
    forced = dict((k, hit) for k, _, hit in b["by_forced"])["forced"]
    below = _share(c - tail["collisions"], n - tail["episodes"])
    late = b["late"]["collisions"]
    causes = ", ".join(
        f"{k.replace('off_footprint', 'off the footprint')} {_share(m, c, '.2f')}"
        for k, m in b["by_cause"][:3]
    )
    return (
        f"| {label} | {c} | {forced} | {tail['collisions']} ({_share(tail['collisions'], c, '.2f')}) | "
        f"{below} / {_share(tail['collisions'], tail['episodes'])} | {late} ({_share(late, c, '.2f')}) | {causes} |"
    )


def plot(t: dict[str, np.ndarray], b: dict, path: Path) -> bool:
    """Four panels: collision rate by N, by max tilt, by friction; failure times. False without matplotlib."""
    try:
        import matplotlib
    except ImportError:
        return False
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from lasmp.io.atomic import atomic_write_with

    panels = [
        ("N (waypoints)", b["by_n"]),
        ("platform max tilt (rad)", b.get("by_tilt", [])),
        ("foot friction", b["by_friction"]),
    ]
    fig, axes = plt.subplots(1, 4, figsize=(17, 3.6))
    for ax, (title, rows) in zip(axes, panels, strict=False):
        rows = [r for r in rows if r[1]]
        ax.bar(range(len(rows)), [c / n for _, n, c in rows], color="tab:red")
        ax.set_xticks(range(len(rows)), [r[0] for r in rows], rotation=45, fontsize=7)
        ax.set_ylim(0, 1)
        ax.set_title(f"collision rate by {title}", fontsize=9)
    times = t["collision_time_s"][t["collided"] > 0.5]
    axes[3].hist(times[np.isfinite(times)], bins=np.arange(0, 10.5, 0.5), color="tab:gray")
    axes[3].axvline(b["late"]["after_s"], color="k", ls="--", lw=1)
    axes[3].set_title("time of the collision (s)", fontsize=9)
    fig.tight_layout()
    atomic_write_with(path, lambda tmp: fig.savefig(tmp, dpi=100, format="png"))
    plt.close(fig)
    return True


def _against_baseline(t: dict[str, np.ndarray], baseline: dict[str, np.ndarray]) -> dict:
    """`failure.against_baseline`, its refusal an EpisodesFileError (which `_naming` names the file of)."""
    try:
        return failure.against_baseline(t, baseline)
    except ValueError as err:
        raise EpisodesFileError(str(err)) from None


def _naming(path: Path, fn, *args):
    """fn(*args), its EpisodesFileError prefixed with the file it is about."""
    try:
        return fn(*args)
    except EpisodesFileError as err:
        raise EpisodesFileError(f"{path}: {err}") from None


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m lasmp.eval.breakdown",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "dir", type=Path, help="an evaluation directory (evaluate.py --out), with episodes.csv.gz or .csv"
    )
    p.add_argument("--plot", type=Path, help="also draw the breakdown to this PNG")
    p.add_argument("--force", action="store_true", help="with --plot: overwrite an existing file")
    p.add_argument(
        "--late-s", type=float_arg(0.0), default=8.0, help="failures after this time count as late (s, >= 0)"
    )
    p.add_argument(
        "--episodes", type=int_arg(1), metavar="K", help="only Xi_eval's first K episodes (episode < K)"
    )
    p.add_argument("--probe-from", type=Path, metavar="DIR2", help="the probe's columns from DIR2's episodes")
    p.add_argument(
        "--baseline", type=Path, metavar="DIR3", help="count the failures in the episodes DIR3's run survives"
    )
    p.add_argument(
        "--row", metavar="LABEL", help="print only docs/evaluation.md's row of this run, named LABEL"
    )
    args = p.parse_args(argv)
    with contextlib.ExitStack() as claims:
        return _main(args, claims)


def _main(args, claims: contextlib.ExitStack) -> int:
    """main's work; `claims` holds the claim of --plot (removed when no plot is drawn)."""
    try:
        if args.plot is not None:  # before the reading: a refused plot costs nothing
            check_out_file(args.plot, suffixes=(".png",), force=True, option="--plot")
            # claimed (create-exclusive), not checked: an existing file, or one another run claimed
            # meanwhile, is refused without --force, with no window between a check and the write
            claims.enter_context(claim_output(args.plot, force=args.force, option="--plot"))
        path = episodes_path(args.dir)
        table = read_csv(path)
        if args.episodes is not None:
            table = _naming(path, first_episodes, table, args.episodes)
        if args.probe_from is not None:
            other = episodes_path(args.probe_from)
            table = _naming(other, with_probe_from, table, read_csv(other))
        paired = None
        if args.baseline is not None:
            base = episodes_path(args.baseline)
            paired = _naming(base, _against_baseline, table, read_csv(base))
    except (EpisodesFileError, InputError, OSError) as err:  # OSError: the plot already there, ...
        print(f"error: {err}", file=sys.stderr)
        return 2
    b = breakdown(table, args.late_s)
    if paired is not None:
        b |= {"against_baseline": paired, "baseline_name": str(args.baseline)}
    if args.row is not None:
        try:
            print(summary_row(b, args.row))
        except ValueError as err:
            print(f"error: {episodes_path(args.dir)}: {err}", file=sys.stderr)
            return 2
    else:
        print(markdown(b))
    try:
        if args.plot is not None and not plot(table, b, args.plot):
            print("\n(no plot: matplotlib is not installed)", file=sys.stderr)
    except AtomicWriteError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
