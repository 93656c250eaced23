"""The three-seed study (docs/results.md): train, resume and evaluate every run, idempotently.

    python scripts/study.py plan                      # what is done, what is left
    python scripts/study.py train METHOD SEED [--until N]   # train (or resume) to N iterations (default 450)
    python scripts/study.py evaluate METHOD SEED [--at N]    # all of Xi_eval on model_<N-1>.pt
    python scripts/study.py next                      # the first unfinished step, trained or evaluated

Runs live in runs/study/<method>/seed<k>/ (not committed: checkpoints); each command line is
appended to runs/study/<method>/seed<k>.commands before it runs, so a run can be continued in a
later sitting. Evaluations go to results/study/<method>[@<N>]/seed<k>/ (committed). Every run has
the same budget: 450 iterations x 1,024 envs (the cpu preset), in the default configuration.
"""

from __future__ import annotations

import argparse
import re
import shlex
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RUNS = ROOT / "runs" / "study"
RESULTS = ROOT / "results" / "study"
SEEDS = (0, 1, 2)
BUDGET = 450
HEADLINE = 1000  # LAS-MP's three seeds continue to the cpu preset's length
# method -> train.py overrides (the ablations of docs/method.md are policy groups; R-S its own task)
METHODS = {
    "lasmp": [],
    "lasmp_centre": ["env.rewards.h_des_from=centre"],
    "no_alignment_command": ["policy=no_alignment_command"],
    "no_platform_velocity_estimates": ["policy=no_platform_velocity_estimates"],
    "no_explicit_estimator": ["policy=no_explicit_estimator"],
    "no_explicit_estimator_history": ["policy=no_explicit_estimator_history"],
    "rs": ["task=rough_static"],
}


def run_dir(method: str, seed: int) -> Path:
    return RUNS / method / f"seed{seed}"


def last_iteration(d: Path) -> int:
    """The last completed iteration saved in run directory d (-1 if none)."""
    its = [int(m.group(1)) for p in d.glob("model_*.pt") if (m := re.fullmatch(r"model_(\d+)\.pt", p.name))]
    return max(its, default=-1)


def execute(cmd: list[str], log: Path) -> None:
    log.parent.mkdir(parents=True, exist_ok=True)
    with log.open("a") as f:
        f.write(shlex.join(cmd) + "\n")
    print("+", shlex.join(cmd), flush=True)
    subprocess.run(["nice", "-n", "10", *cmd], cwd=ROOT, check=True)


def train(method: str, seed: int, until: int = BUDGET) -> None:
    d = run_dir(method, seed)
    done = last_iteration(d) + 1
    if done >= until:
        print(f"{method} seed {seed}: {done} iterations done (>= {until})")
        return
    cmd = [
        sys.executable,
        "train.py",
        *METHODS[method],
        f"seed={seed}",
        "runner.save_interval=25",
        f"runner.log_dir={d.relative_to(ROOT)}",
    ]
    if done > 0:
        cmd += [f"resume={d.relative_to(ROOT)}", f"runner.max_iterations={until - done}"]
    else:
        cmd += [f"runner.max_iterations={until}"]
    execute(cmd, d.with_suffix(".commands"))


def result_dir(method: str, seed: int, at: int, controller: str | None = None) -> Path:
    name = controller or method
    return RESULTS / (name if at == BUDGET else f"{name}@{at}") / f"seed{seed}"


def evaluate(method: str, seed: int, at: int = BUDGET) -> None:
    ckpt = run_dir(method, seed) / f"model_{at - 1}.pt"
    if not ckpt.exists():
        raise SystemExit(f"{ckpt} does not exist: train {method} seed {seed} to {at} iterations first")
    controllers = ["rs", "rs_oracle"] if method == "rs" else [None]
    for controller in controllers:
        out = result_dir(method, seed, at, controller)
        if (out / "metrics.json").exists():
            print(f"{out} done")
            continue
        cmd = [
            sys.executable,
            "evaluate.py",
            "--checkpoint",
            str(ckpt.relative_to(ROOT)),
            "--out",
            str(out.relative_to(ROOT)),
            "--no-platform-probe",  # the probe doubles an evaluation's cost; Stand Still's run has it
        ] + (["--controller", controller] if controller else [])
        execute(cmd, run_dir(method, seed).with_suffix(".commands"))


def steps():
    """Every step of the study in order: (kind, method, seed, iterations)."""
    for seed in SEEDS:
        for method in METHODS:
            yield "train", method, seed, BUDGET
            yield "evaluate", method, seed, BUDGET
    for seed in SEEDS:
        yield "train", "lasmp", seed, HEADLINE
        yield "evaluate", "lasmp", seed, HEADLINE


def is_done(kind: str, method: str, seed: int, at: int) -> bool:
    if kind == "train":
        return last_iteration(run_dir(method, seed)) + 1 >= at
    outs = [result_dir(method, seed, at, c) for c in (["rs", "rs_oracle"] if method == "rs" else [None])]
    return all((o / "metrics.json").exists() for o in outs)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("plan")
    sub.add_parser("next")
    for name in ("train", "evaluate"):
        s = sub.add_parser(name)
        s.add_argument("method", choices=sorted(METHODS))
        s.add_argument("seed", type=int, choices=SEEDS)
        s.add_argument("--until" if name == "train" else "--at", type=int, default=BUDGET, dest="n")
    args = p.parse_args(argv)
    if args.cmd == "plan":
        for step in steps():
            print(("done " if is_done(*step) else "todo ") + " ".join(map(str, step)))
    elif args.cmd == "next":
        for kind, method, seed, n in steps():
            if not is_done(kind, method, seed, n):
                (train if kind == "train" else evaluate)(method, seed, n)
                return
        print("the study is complete")
    elif args.cmd == "train":
        train(args.method, args.seed, args.n)
    else:
        evaluate(args.method, args.seed, args.n)


if __name__ == "__main__":
    main()
