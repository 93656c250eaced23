"""A run's learning curve in the benchmark's terms: the collision rate on Xi_eval's first episodes at
several budgets, each with the training minutes it took (LAS-MP+'s budget is chosen from it:
docs/screening.md#las-mps-budget).

    python scripts/learning_curve.py RUN_DIR --at 150 300 449 [999] --out DIR [--episodes 2000]

`--at` names the run's checkpoints as rsl_rl numbers them: model_<I>.pt (or the policy_<I>.pt that
keep_full left) is saved after iteration I, so it holds I + 1 iterations (a run of 450 saves
model_0, model_150, model_300 every 150 and model_449 at its end). For each, `evaluate.py` plays it
on the first `--episodes` episodes into DIR/it<I>/ (kept: an evaluated checkpoint is not played
again). The minutes are the run's own: the sum of TensorBoard's `Perf/collection_time` and
`Perf/learning_time` over its first I + 1 iterations, the time spent training on the machine that
ran it, without start-up, checkpoint writes or evaluation. DIR/curve.json holds every point; the
Markdown table is printed.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

from lasmp.io.inputs import InputError, int_arg, read_json

ROOT = Path(__file__).resolve().parents[1]


def training_minutes(scalars: dict, n: int, run_dir: Path) -> float:
    """Minutes of collection and learning over iterations 0..n-1, from the run's TensorBoard scalars
    (`lasmp.eval.curves.read_scalars`)."""
    total = 0.0
    for tag in ("Perf/collection_time", "Perf/learning_time"):
        its, values = scalars[tag]
        if (its < n).sum() < n:
            raise SystemExit(f"{run_dir}'s logs hold {tag} for {(its < n).sum()} of the first {n} iterations")
        total += float(values[its < n].sum())
    return total / 60.0


def point(ckpt: Path, it: int, out: Path, episodes: int, minutes: float) -> dict:
    dest = out / f"it{it}"
    if not (dest / "metrics.json").exists():
        cmd = [sys.executable, "evaluate.py", "--checkpoint", str(ckpt), "--out", str(dest)]
        cmd += ["--num-trajectories", str(episodes), "--no-platform-probe"]
        print(" ".join(cmd), flush=True)
        try:
            subprocess.run(cmd, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
        except subprocess.CalledProcessError as err:  # evaluate.py has said why on stderr
            raise SystemExit(err.returncode) from None
    m = read_json(dest / "metrics.json")
    if m["num_episodes"] != episodes:
        raise SystemExit(f"{dest} evaluated {m['num_episodes']} episodes, not {episodes}: give another --out")
    return {
        "iterations": it + 1,
        "checkpoint": str(ckpt),
        "collision_rate": m["metrics"]["collision_rate"]["mean"],
        "height_violation_rate": m["metrics"]["height_violation_rate"]["mean"],
        "four_feet_step_share": m["gait"]["four_feet_step_share"],
        "training_minutes": minutes,
    }


def table(points: list[dict], episodes: int) -> str:
    lines = [
        f"| iterations | collision (first {episodes:,}) | height violation | steps on four feet | training minutes |",
        "|---|---|---|---|---|",
    ]
    for p in points:
        lines.append(
            f"| {p['iterations']} | {p['collision_rate']:.3f} | {p['height_violation_rate']:.3f} | "
            f"{p['four_feet_step_share']:.3f} | {p['training_minutes']:.1f} |"
        )
    return "\n".join(lines)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("run_dir", type=Path)
    p.add_argument(
        "--at", type=int_arg(0), nargs="+", required=True, help="checkpoints, by the iteration they end"
    )
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--episodes", type=int_arg(1), default=2000, help="Xi_eval's first episodes to play")
    args = p.parse_args(argv)
    if not args.run_dir.is_dir():
        p.error(f"{args.run_dir} is not a run directory")
    if args.out.exists() and not args.out.is_dir():
        p.error(f"--out {args.out} is not a directory")
    from lasmp.eval.curves import read_scalars  # torch: after the arguments, so that --help answers at once
    from lasmp.eval.report import atomic_write_text
    from lasmp.io.rundir import run_checkpoints

    its = sorted(set(args.at))
    # every checkpoint exists and the logs cover it before the first evaluation starts
    saved = run_checkpoints(args.run_dir)
    missing = [it for it in its if it not in saved]
    if missing:
        raise SystemExit(
            f"{args.run_dir} holds no checkpoint of iteration {missing[0]} "
            f"(model_{missing[0]}.pt or policy_{missing[0]}.pt); it holds {sorted(saved)}"
        )
    scalars = read_scalars(args.run_dir)
    minutes = {it: training_minutes(scalars, it + 1, args.run_dir) for it in its}
    try:
        points = [point(saved[it], it, args.out, args.episodes, minutes[it]) for it in its]
    except InputError as err:  # a metrics.json cut short or not evaluate.py's: one line naming it
        raise SystemExit(f"error: {err}") from None
    curve = {"run_dir": str(args.run_dir), "episodes": args.episodes, "points": points}
    atomic_write_text(args.out / "curve.json", json.dumps(curve, indent=1))
    print(table(points, args.episodes))


if __name__ == "__main__":
    main()
