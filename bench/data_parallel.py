"""Steps/s of a data-parallel job against one process with the same total envs (ratio in one run).

    python bench/data_parallel.py [--envs 1024] [--processes 2] [--iterations 8] [--warmup 3] [--json]

Runs `train.py` once with `env.num_envs=ENVS` in one process and once under
`torchrun --nproc_per_node=K` with ENVS/K envs per process (the same env-steps per iteration),
each for ITERATIONS iterations, and reports the median steps/s of the iterations after WARMUP
(its progress lines: all ranks' env-steps over the iteration's wall time). With two cores, one
process per core may use them better than one process with two threads. Nothing else should run.
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


def steps_per_s(cmd: list[str], warmup: int) -> float:
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, check=False)
    if out.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{(out.stdout + out.stderr)[-3000:]}")
    rates = [float(m.group(2).replace(",", "")) for line in out.stdout.splitlines()
             if (m := STEPS.match(line)) and int(m.group(1)) > warmup]  # fmt: skip
    if not rates:
        raise SystemExit(f"no progress lines after the warm-up in:\n{out.stdout[-2000:]}")
    return statistics.median(rates)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--envs", type=int, default=1024)
    p.add_argument("--processes", type=int, default=2)
    p.add_argument("--iterations", type=int, default=8)
    p.add_argument("--warmup", type=int, default=3)
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    if args.envs % args.processes:
        p.error("--envs must be a multiple of --processes")
    with tempfile.TemporaryDirectory() as tmp:
        common = [f"runner.max_iterations={args.iterations}", "runner.save_interval=100000"]
        one = [sys.executable, "train.py", f"env.num_envs={args.envs}", f"runner.log_dir={tmp}/one", *common]
        many = [sys.executable, "-m", "torch.distributed.run", "--standalone", f"--nproc_per_node={args.processes}",
                "train.py", f"env.num_envs={args.envs // args.processes}", f"runner.log_dir={tmp}/many",
                "env.sim.num_threads=1", "torch_threads=1", *common]  # fmt: skip
        single = steps_per_s(one, args.warmup)
        parallel = steps_per_s(many, args.warmup)
    result = {"envs_total": args.envs, "processes": args.processes, "iterations": args.iterations,
              "warmup": args.warmup, "one_process_steps_per_s": single,
              "data_parallel_steps_per_s": parallel, "ratio": parallel / single}  # fmt: skip
    if args.json:
        print(json.dumps(result))
    else:
        print(f"1 x {args.envs} envs: {single:,.0f} steps/s; {args.processes} x {args.envs // args.processes}: "
              f"{parallel:,.0f} steps/s (ratio {parallel / single:.2f})")  # fmt: skip


if __name__ == "__main__":
    main()
