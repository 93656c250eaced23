"""``python -m lasmp.eval.real_motion {generate,plot,stats}``: the suite's file, figures and numbers."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from lasmp.envs import trajectories as trj
from lasmp.eval.real_motion import suite as rm
from lasmp.eval.real_motion.plots import plot_all
from lasmp.motions.motion import to_trajectories


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m lasmp.eval.real_motion", description=__doc__)
    sub = p.add_subparsers(dest="cmd", required=True)
    g = sub.add_parser("generate", help="write the suite's motions as one 'samples' trajectory file")
    g.add_argument("--out", type=Path, default=Path("benchmarks") / "real_motion.npz")
    pl = sub.add_parser("plot", help="one PNG per scenario: pose, acceleration, angular rate")
    pl.add_argument("--out", type=Path, default=Path("docs") / "figures" / "real_motion")
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
    try:
        motions = rm.build_motions(args.scenarios)
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if args.cmd == "generate":
        args.out.parent.mkdir(parents=True, exist_ok=True)
        trj.save(args.out, to_trajectories(motions))
        print(f"wrote {len(motions)} scenarios to {args.out}")
    elif args.cmd == "plot":
        for path in plot_all(motions, args.out):
            print(path)
    else:
        stats = {m.name: rm.motion_summary(m) for m in motions}
        if args.json:
            print(json.dumps(stats, indent=2))
        else:
            keys = list(next(iter(stats.values())))
            print("| scenario | " + " | ".join(keys) + " |\n|---|" + "---|" * len(keys))
            for name, s in stats.items():
                print(f"| {name} | " + " | ".join(f"{s[k]:.3f}" for k in keys) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
