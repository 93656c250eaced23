"""The study's runs (scripts/study.py): train.py and evaluate.py run niced, each command logged
before it runs and mirrored beside the results once it has succeeded, and a trained run recorded
beside its evaluation."""

from __future__ import annotations

import json
import shlex
import signal
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path

from . import plan
from .plan import (
    LEARNER,
    METHODS,
    ROW_METHODS,
    budget,
    committed_policy,
    evaluations,
    last_iteration,
    result_dir,
    run_dir,
    saved_at,
)


def execute(cmd: list[str], log: Path) -> None:
    """Run cmd niced, after appending it to log with the time and the commit. A log in runs/study/ is
    mirrored in results/study/ (committed, so the commands outlive the machine) once cmd has succeeded:
    a failed command made nothing to commit. A failure (or a Ctrl-C) ends the study with cmd's exit
    status: cmd has said why, and a traceback of this script would only bury it."""
    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], cwd=plan.ROOT, capture_output=True, text=True
    )
    when = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    entry = f"# {when}, at {commit.stdout.strip() or 'no commit'}, nice -n 10\n{shlex.join(cmd)}\n"
    append(log, entry)
    print("+", shlex.join(cmd), flush=True)
    status = run_to_its_end(["nice", "-n", "10", *cmd])
    if status != 0:
        raise SystemExit(status)
    if log.is_relative_to(plan.RUNS):
        append(plan.RESULTS / log.relative_to(plan.RUNS), entry)


def append(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("a") as f:
        f.write(text)


def run_to_its_end(cmd: list[str]) -> int:
    """cmd's exit status (128 + N for a cmd killed by signal N, as a shell says it), run in ROOT.
    Ctrl-C at the terminal reaches cmd too (one process group), and train.py answers it by saving a
    checkpoint and exiting 130. Meanwhile this process ignores it, as a shell waits for its foreground
    job: left to Python, the interrupt would kill cmd a quarter of a second later, during its save.
    A no-op handler rather than SIG_IGN, which cmd would inherit: it must take the Ctrl-C itself."""
    previous = signal.signal(signal.SIGINT, lambda signum, frame: None)
    try:
        status = subprocess.run(cmd, cwd=plan.ROOT).returncode
    finally:
        signal.signal(signal.SIGINT, previous)
    return status if status >= 0 else 128 - status


def check_learner(cpuinfo: str | None = None) -> None:
    """Refuse a CPU where the study's bfloat16 learner would be emulated (cpuinfo: /proc/cpuinfo's
    text, read when None)."""
    from lasmp.algo.precision import cpu_has_fast_bf16

    if not cpu_has_fast_bf16(cpuinfo):
        raise SystemExit(
            f"the study trains every run with {LEARNER}, and this CPU lacks AVX-512 BF16/AMX: bfloat16 "
            "autocast would be emulated, about 20 times slower. Continue the study on a CPU that has it "
            "(grep avx512_bf16 /proc/cpuinfo)."
        )


def train(method: str, seed: int, until: int | None = None) -> None:
    if method in ROW_METHODS:
        raise SystemExit(f"the ladder trains the new rows: python scripts/ladder.py train {method} {seed}")
    until = until or budget(method)
    d = run_dir(method, seed)
    done = last_iteration(d) + 1
    if done >= until:
        print(f"{method} seed {seed}: {done} iterations done (>= {until})")
        record_run(method, seed, until)
        return
    check_learner()
    cmd = [
        sys.executable,
        "train.py",
        *METHODS[method],
        LEARNER,
        f"seed={seed}",
        "runner.save_interval=25",
        f"runner.log_dir={d.relative_to(plan.ROOT)}",
    ]
    if done > 0:
        cmd += [f"resume={d.relative_to(plan.ROOT)}", f"runner.max_iterations={until - done}"]
    else:
        cmd += [f"runner.max_iterations={until}"]
    execute(cmd, d.with_suffix(".commands"))
    record_run(method, seed, until)


def record_run(method: str, seed: int, at: int) -> None:
    """Beside the run's evaluation: its config, its policy at 'at' iterations in the light form (the
    actor and its normalizers, 0.96 MB, lasmp.algo.checkpoint.light; the full checkpoint, with the critic,
    the optimizers and the envs' running state, stays in runs/) and its learning curve to 'at'
    (lasmp.eval.curves' windows of 10 iterations): a run adds about 1 MB to the repository."""
    from lasmp.algo.checkpoint import policy_checkpoint
    from lasmp.algo.checkpoint.light import convert_in_place
    from lasmp.eval.curves import read_scalars, truncated, windows
    from lasmp.eval.report import atomic_write_text

    d, out = run_dir(method, seed), result_dir(method, seed, at)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "config.yaml", (d / "config.yaml").read_text())
    policy = out / f"policy_{at - 1}.pt"
    if not policy.exists():
        policy_checkpoint(saved_at(d, at - 1), policy)
    convert_in_place(policy)  # a light one is left as it is
    rows = windows(truncated(read_scalars(d), at - 1), 10)
    curves = {"run_dir": str(d.relative_to(plan.ROOT)), "windows": rows}
    atomic_write_text(out / f"curves_{at}.json", json.dumps(curves))
    print(f"wrote {out.relative_to(plan.ROOT)}/{{config.yaml,{policy.name},curves_{at}.json}}")


def evaluate(method: str, seed: int, at: int | None = None) -> None:
    at = at or budget(method)
    ckpt = saved_at(run_dir(method, seed), at - 1, method)
    if not ckpt.exists() and committed_policy(method, seed, at).exists():
        ckpt = committed_policy(method, seed, at)  # a fresh machine: the run's checkpoints are gone
    if not ckpt.exists():
        how = (
            f"python scripts/ladder.py train {method} {seed}, then collect it"
            if method in ROW_METHODS
            else ""
        )
        raise SystemExit(
            f"{ckpt} does not exist: train {method} seed {seed} to {at} iterations first{': ' + how if how else ''}"
        )
    for out, options in evaluations(method, seed, at):
        if (out / "metrics.json").exists():
            print(f"{out} done")
            continue
        cmd = [
            sys.executable,
            "evaluate.py",
            "--checkpoint",
            str(ckpt.relative_to(plan.ROOT)),
            "--out",
            str(out.relative_to(plan.ROOT)),
            "--no-platform-probe",  # the probe doubles an evaluation's cost; Stand Still's run has it
            *options,
        ]
        execute(cmd, run_dir(method, seed).with_suffix(".commands"))
