"""``python -m lasmp.eval.real_motion {generate,plot,stats,table}``: the suite's file, figures and numbers.

The files ``generate`` and ``plot`` write are checked (extension, directory) and claimed
(`lasmp.io.atomic.claim_output`: an existing file is refused without ``--force``, with no window between a
check and the write) before any motion is built; a claim the run did not write is removed; a write
that fails is one line naming the file (exit 1).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path

from lasmp.envs import trajectories as trj
from lasmp.eval.real_motion import suite as rm
from lasmp.eval.real_motion.plots import plot_all
from lasmp.io.atomic import claim_output
from lasmp.io.inputs import check_out_file
from lasmp.motions.motion import to_trajectories


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m lasmp.eval.real_motion", description=__doc__)
    sub = p.add_subparsers(dest="cmd", required=True)
    g = sub.add_parser("generate", help="write the suite's motions as one 'samples' trajectory file")
    g.add_argument("--out", type=Path, default=Path("benchmarks") / "real_motion.npz", help="an .npz file")
    pl = sub.add_parser("plot", help="one PNG per scenario: pose, acceleration, angular rate")
    pl.add_argument("--out", type=Path, default=Path("docs") / "figures" / "real_motion", help="a directory")
    for q in (g, pl):
        q.add_argument("--force", action="store_true", help="overwrite the files --out already holds")
    st = sub.add_parser("stats", help="per scenario: RMS and peak acceleration and angular rate, excursions")
    st.add_argument("--json", action="store_true")
    for q in (g, pl, st):
        q.add_argument("--scenarios", nargs="+", help=f"default: all of {list(rm.SCENARIOS)}")
    tb = sub.add_parser(
        "table", help="controllers x scenarios (collision rate / position deviation) from results"
    )
    tb.add_argument("results", nargs="+", type=Path, help="evaluate.py --suite real_motion output dirs")
    tb.add_argument("--labels", nargs="+", help="column labels (default: the directory names)")
    args = p.parse_args(argv)
    if args.cmd == "table":
        try:
            print(rm.comparison_table(args.results, args.labels))
        except (OSError, ValueError, KeyError) as err:
            print(f"error: {err}", file=sys.stderr)
            return 2
        return 0
    with contextlib.ExitStack() as claims:
        try:  # the files it writes, checked and claimed before the motions are built (seconds of work)
            if args.cmd == "generate":
                check_out_file(args.out, suffixes=(".npz",), force=True, option="--out")
                claims.enter_context(claim_output(args.out, force=args.force, option="--out"))
            elif args.cmd == "plot":
                for name in args.scenarios or rm.SCENARIOS:  # plot_all's file names
                    path = args.out / f"{name}.png"
                    check_out_file(path, suffixes=(".png",), force=True, option="--out")
                    claims.enter_context(claim_output(path, force=args.force, option="--out"))
            motions = rm.build_motions(args.scenarios)
        except (ValueError, FileExistsError) as err:  # InputError, an unknown scenario, a file there
            print(f"error: {err}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print("interrupted: nothing written", file=sys.stderr)
            return 130
        if args.cmd == "stats":
            print_stats(motions, args.json)
            return 0
        return _write(args, motions)


def _write(args, motions) -> int:
    """generate's file or plot's figures, into the claims `main` holds."""
    try:
        if args.cmd == "generate":
            trj.save(args.out, to_trajectories(motions))  # atomic; it makes the directory
            print(f"wrote {len(motions)} scenarios to {args.out}")
        else:
            for path in plot_all(motions, args.out):
                print(path)
    except OSError as err:  # AtomicWriteError (a full disk, ...), a figure that cannot be saved: named
        print(f"error: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(
            f"interrupted: {args.out} {'not written' if args.cmd == 'generate' else 'incomplete'}",
            file=sys.stderr,
        )
        return 130
    return 0


def print_stats(motions, as_json: bool) -> None:
    stats = {m.name: rm.motion_summary(m) for m in motions}
    if as_json:
        print(json.dumps(stats, indent=2))
    else:
        keys = list(next(iter(stats.values())))
        print("| scenario | " + " | ".join(keys) + " |\n|---|" + "---|" * len(keys))
        for name, s in stats.items():
            print(f"| {name} | " + " | ".join(f"{s[k]:.3f}" for k in keys) + " |")


if __name__ == "__main__":
    sys.exit(main())
