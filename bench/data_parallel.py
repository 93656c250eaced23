"""Steps/s of a data-parallel job against one process with the same total envs (ratio in one run).

    python bench/data_parallel.py [--envs 1024] [--processes 2] [--iterations 8] [--warmup 3] [--json]
    python bench/data_parallel.py --curves OUT.json [--seeds 0 1] [--iterations 100]
    python bench/data_parallel.py --plot CURVES.json FIGURE.png

Runs `train.py` once with `env.num_envs=ENVS` in one process and once under
`torchrun --nproc_per_node=K` with ENVS/K envs per process (the same env-steps per iteration),
each for ITERATIONS iterations, and reports the median steps/s of the iterations after WARMUP
(its progress lines: all ranks' env-steps over the iteration's wall time). With two cores, one
process per core may use them better than one process with two threads. Nothing else should run.

With --curves, it trains both layouts for every seed in --seeds instead and writes each
iteration's mean episode reward, success rate and curriculum level (rank 0's progress line: the
reward is rank 0's episodes, the success and level the shared curriculum's) to OUT.json. The
curves are not timings: they may share the cores.
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STEPS = re.compile(r"^it (\d+)/\d+ \| ([\d,]+) steps/s")
PROGRESS = re.compile(
    r"^it (\d+)/\d+ \| [\d,]+ steps/s \| reward +(\S+)(?: \| success (\S+))?(?: \| level (\d+))?"
)


def run(cmd: list[str]) -> str:
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, check=False)
    if out.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{(out.stdout + out.stderr)[-3000:]}")
    return out.stdout


def steps_per_s(cmd: list[str], warmup: int) -> float:
    stdout = run(cmd)
    rates = [
        float(m.group(2).replace(",", ""))
        for line in stdout.splitlines()
        if (m := STEPS.match(line)) and int(m.group(1)) > warmup
    ]
    if not rates:
        raise SystemExit(f"no progress lines after the warm-up in:\n{stdout[-2000:]}")
    return statistics.median(rates)


def commands(
    envs: int, processes: int, iterations: int, tmp: str, extra: list[str]
) -> tuple[list[str], list[str]]:
    """One process with ENVS envs, and PROCESSES torchrun ranks with ENVS/PROCESSES each."""
    common = [f"runner.max_iterations={iterations}", "runner.save_interval=100000", *extra]
    one = [sys.executable, "train.py", f"env.num_envs={envs}", f"runner.log_dir={tmp}/one", *common]
    many = [
        sys.executable,
        "-m",
        "torch.distributed.run",
        "--standalone",
        f"--nproc_per_node={processes}",
        "train.py",
        f"env.num_envs={envs // processes}",
        f"runner.log_dir={tmp}/many",
        "env.sim.num_threads=1",
        "torch_threads=1",
        *common,
    ]
    return one, many


def curve(stdout: str) -> dict[str, list]:
    rows = [m.groups() for line in stdout.splitlines() if (m := PROGRESS.match(line))]
    if not rows:
        raise SystemExit(f"no progress lines in:\n{stdout[-2000:]}")
    number = lambda x: None if x is None or x == "nan" else float(x)  # noqa: E731 (no episode ended: null)
    return {
        "iteration": [int(r[0]) for r in rows],
        "reward": [number(r[1]) for r in rows],
        "success": [number(r[2]) for r in rows],
        "level": [int(r[3]) if r[3] else None for r in rows],
    }


def curves(args) -> None:
    out = Path(args.curves)
    result = {"envs_total": args.envs, "processes": args.processes, "iterations": args.iterations, "runs": []}
    for seed in args.seeds:
        with tempfile.TemporaryDirectory() as tmp:
            one, many = commands(args.envs, args.processes, args.iterations, tmp, [f"seed={seed}"])
            for layout, cmd in (
                (f"1x{args.envs}", one),
                (f"{args.processes}x{args.envs // args.processes}", many),
            ):
                print(f"seed {seed}, {layout} ...", flush=True)
                result["runs"].append({"seed": seed, "layout": layout, **curve(run(cmd))})
                tmp_out = out.with_suffix(".tmp")
                tmp_out.write_text(json.dumps(result, allow_nan=False) + "\n")
                tmp_out.replace(out)  # atomic: a partial study is still readable
    print(f"wrote {out}")


def plot(curves_json: str, figure: str) -> None:
    """Mean episode reward and success rate against iteration, one line per layout and seed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs = json.loads(Path(curves_json).read_text())["runs"]
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    layouts = sorted({r["layout"] for r in runs})
    for r in runs:
        color = f"C{layouts.index(r['layout'])}"
        style = "-" if r["seed"] == runs[0]["seed"] else "--"
        label = f"{r['layout']} envs, seed {r['seed']}"
        for ax, key in zip(axes, ("reward", "success"), strict=True):
            ax.plot(
                r["iteration"],
                [float("nan") if v is None else v for v in r[key]],
                style,
                color=color,
                label=label,
            )
    for ax, title in zip(axes, ("mean episode reward", "success rate (curriculum)"), strict=True):
        ax.set_xlabel("iteration")
        ax.set_title(title)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(figure, dpi=110)
    print(f"wrote {figure}")


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--envs", type=int, default=1024)
    p.add_argument("--processes", type=int, default=2)
    p.add_argument("--iterations", type=int, default=8)
    p.add_argument("--warmup", type=int, default=3)
    p.add_argument("--json", action="store_true")
    p.add_argument(
        "--curves", metavar="OUT.json", help="train both layouts per seed and write the learning curves"
    )
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    p.add_argument(
        "--plot", nargs=2, metavar=("CURVES.json", "FIGURE.png"), help="plot the curves of --curves"
    )
    args = p.parse_args(argv)
    if args.plot:
        return plot(*args.plot)
    if args.envs % args.processes:
        p.error("--envs must be a multiple of --processes")
    if args.curves:
        if Path(args.curves).exists():
            p.error(f"{args.curves} exists; remove it first")
        return curves(args)
    with tempfile.TemporaryDirectory() as tmp:
        one, many = commands(args.envs, args.processes, args.iterations, tmp, [])
        single = steps_per_s(one, args.warmup)
        parallel = steps_per_s(many, args.warmup)
    result = {
        "envs_total": args.envs,
        "processes": args.processes,
        "iterations": args.iterations,
        "warmup": args.warmup,
        "one_process_steps_per_s": single,
        "data_parallel_steps_per_s": parallel,
        "ratio": parallel / single,
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(
            f"1 x {args.envs} envs: {single:,.0f} steps/s; {args.processes} x {args.envs // args.processes}: "
            f"{parallel:,.0f} steps/s (ratio {parallel / single:.2f})"
        )


if __name__ == "__main__":
    main()
