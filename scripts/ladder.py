"""The scaling ladder (docs/scaling.md): LAS-MP+ at other batches, rollout lengths and updates, each run
scored during training on the validation benchmark (`runner.validation_*`), on fresh seeds (SEEDS: no
run before the ladder used them), the same seeds on every rung so that rungs compare seed by seed.

    python scripts/ladder.py plan                 # every run: its command and how far it is
    python scripts/ladder.py train RUNG SEED      # train it (a stopped run resumes from its last save;
                                                  # one whose machine was lost, from its snapshot: a warm start)
    python scripts/ladder.py collect RUNG SEED    # its curve, config, commands and light policies -> results/ladder/
    python scripts/ladder.py snapshot RUNG SEED   # a run still training: its newest policy checkpoint, curve, commands
    python scripts/ladder.py queue RUNG:SEED ...  # train and collect each in turn; stops at a run that fails or is stopped
    python scripts/ladder.py table [--json]       # the table, from results/ladder/<rung>/seed<k>/validation.json
    python scripts/ladder.py figure [--out docs/figures/scaling.png]

A rung's score is its validation collision rate at its last validation (the full budget) on the
validation benchmark's first `runner.validation_episodes` episodes; the table gives each seed's, their
mean, their spread (max - min) and each seed's difference from the baseline rung on the same seed.
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

from ladderlib.report import curves, figure, markdown, read_curve, table_rows  # noqa: F401  (tests read them here)
from ladderlib.rungs import BASE, CHOSEN, RESULTS, ROOT, ROW_SEEDS, RUNGS, RUNS, SAMPLES, SEEDS, Rung  # noqa: F401


def _rung(name: str) -> Rung:
    if name not in RUNGS:
        raise SystemExit(f"error: unknown rung {name!r}; the rungs: {', '.join(RUNGS)}")
    return RUNGS[name]


def _seed(text: str) -> int:
    seed = int(text)
    known = sorted({s for rung in RUNGS.values() for s in rung.seeds})
    if seed not in known:
        raise argparse.ArgumentTypeError(f"the ladder's seeds are {', '.join(map(str, known))}, got {seed}")
    return seed


def _rung_seed(name: str, seed: int) -> Rung:
    rung = _rung(name)
    if seed not in rung.seeds:
        raise SystemExit(f"error: rung {name} trains seeds {', '.join(map(str, rung.seeds))}, not {seed}")
    return rung


def _last_saved(run_dir: Path) -> int | None:
    from lasmp.io.rundir import run_checkpoints

    full = run_checkpoints(run_dir, full_only=True) if run_dir.is_dir() else {}
    return max(full) if full else None


def machine() -> str:
    """The CPU this runs on, and whether it multiplies bfloat16 natively (the learner depends on it)."""
    try:
        info = Path("/proc/cpuinfo").read_text()
    except OSError:
        return "an unknown CPU"
    model = next(
        (line.split(":", 1)[1].strip() for line in info.splitlines() if line.startswith("model name")), "?"
    )
    return f"{model}, {os.cpu_count()} cores, {'with' if 'avx512_bf16' in info else 'without'} AVX-512 BF16"


def snapshot_policy(name: str, seed: int) -> tuple[Path, int] | None:
    """The committed snapshot's policy of a run (`snapshot`) and its iteration; None without one."""
    found = sorted(
        (int(p.stem.split("_")[1]), p)
        for p in (RESULTS / name / f"seed{seed}" / "in_progress").glob("policy_*.pt")
        if p.stem.split("_")[1].isdigit()
    )
    return (found[-1][1], found[-1][0]) if found else None


def _continued(rung: Rung, seed: int) -> tuple[Path, int, Path]:
    """The finished run that `rung` goes on from (`Rung.continues`): its last full checkpoint, that
    checkpoint's iteration and the run's commands file; refused while that run has not finished."""
    before = _rung(rung.continues)
    run_dir = RUNS / rung.continues / f"seed{seed}"
    last = _last_saved(ROOT / run_dir)
    if last is None or last + 1 < before.iterations:
        raise SystemExit(
            f"error: this rung goes on from {run_dir}, which has not finished its {before.iterations} "
            f"iterations here (last save: {last}): train {rung.continues} {seed} first"
        )
    return run_dir / f"model_{last}.pt", last, ROOT / run_dir.parent / f"seed{seed}.commands"


def train(name: str, seed: int) -> int:
    """Train (or resume) one run. Its command goes into runs/ladder/<rung>/seed<k>.commands, with the
    time and the machine, once the training has saved a checkpoint (so that a snapshot of a run still
    training carries it), never for a run that failed before its first save. A run with no checkpoint
    here but a committed snapshot (its machine was lost) goes on from the snapshot's policy, a warm
    start (lasmp/cli/warm_start.py), after the snapshot's commands. A rung that continues another
    (`Rung.continues`) starts as a resume of that run's last checkpoint, after that run's commands."""
    rung = _rung_seed(name, seed)
    run_dir = RUNS / name / f"seed{seed}"
    last = _last_saved(ROOT / run_dir)
    snap = snapshot_policy(name, seed) if last is None else None
    branch = _continued(rung, seed) if last is None and not snap and rung.continues else None
    done = last + 1 if last is not None else snap[1] + 1 if snap else branch[1] + 1 if branch else 0
    if done >= rung.iterations:
        print(f"{run_dir}: done ({rung.iterations} iterations)")
        return 0
    warm = Path(os.path.relpath(snap[0], ROOT)) if snap else None
    cmd = rung.command(seed, run_dir, rung.iterations - done, resume=last is not None, warm_start=warm)
    if branch:  # a resume of the other run's checkpoint, into this run's own directory
        cmd.append(f"resume={branch[0]}")
    commands = ROOT / RUNS / name / f"seed{seed}.commands"
    history = snap[0].parent / "commands" if snap else branch[2] if branch else None
    if history and not commands.exists():  # the run's history so far, then this command
        commands.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(history, commands)
    print(" ".join(cmd), flush=True)
    stamp = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    recorded = False

    def record() -> None:
        nonlocal recorded
        if not recorded and _last_saved(ROOT / run_dir) not in (None, last):
            with commands.open("a") as f:
                f.write(f"# {stamp}, {machine()}\n{' '.join(cmd[1:])}\n")
            recorded = True

    proc = subprocess.Popen(cmd, cwd=ROOT)
    try:
        while proc.poll() is None:
            record()
            time.sleep(5)
    finally:
        code = proc.wait()  # a Ctrl-C reaches the training too: it saves, then ends
        record()
    return code


def light_copy(src: Path, dst: Path) -> Path:
    """`dst`: the light form (actor only) of checkpoint `src`, full or policy-only."""
    from lasmp.algo.checkpoint import is_policy_only, policy_checkpoint, read_checkpoint
    from lasmp.algo.checkpoint.light import write_light

    if is_policy_only(read_checkpoint(src)):
        return write_light(src, dst, force=True)
    slim = dst.with_name(dst.stem + ".policy.tmp.pt")
    try:
        policy_checkpoint(src, slim, force=True)
        return write_light(slim, dst, force=True)
    finally:
        slim.unlink(missing_ok=True)


def collect(name: str, seed: int, force: bool = False) -> Path:
    """results/ladder/<rung>/seed<k>/: the run's validation.json, config.yaml, commands and its best
    policy by validation in the light form (under 1 MB: a run adds no more to the tree). The final
    policy's figures are validation.json's last entry; the policy itself stays in the run directory."""
    rung = _rung_seed(name, seed)
    run_dir = ROOT / RUNS / name / f"seed{seed}"
    last = _last_saved(run_dir)
    if last is None or last + 1 < rung.iterations:
        raise SystemExit(
            f"error: {run_dir} has not finished its {rung.iterations} iterations (last save: {last})"
        )
    dest = RESULTS / name / f"seed{seed}"
    if (dest / "validation.json").exists() and not force:
        raise SystemExit(f"error: {dest} holds a collected run; give --force to replace it")
    dest.mkdir(parents=True, exist_ok=True)
    read_curve(run_dir / "validation.json")
    for src in ("validation.json", "config.yaml"):
        shutil.copyfile(run_dir / src, dest / src)
    shutil.copyfile(run_dir.parent / f"seed{seed}.commands", dest / "commands")
    light_copy(run_dir / "policy_best.pt", dest / "policy_best.pt")
    shutil.rmtree(dest / "in_progress", ignore_errors=True)  # the finished run's files replace the snapshot
    return dest


def snapshot(name: str, seed: int) -> Path:
    """results/ladder/<rung>/seed<k>/in_progress/: a running run's newest policy checkpoint (the critic
    kept, 1.8 MB), its curve so far and its commands, to commit at the end of a sitting (a lost machine
    then costs the hours since, not the run: `train` goes on from these weights with fresh optimizers,
    a warm start)."""
    _rung_seed(name, seed)
    run_dir = ROOT / RUNS / name / f"seed{seed}"
    last = _last_saved(run_dir)
    if last is None:
        raise SystemExit(f"error: {run_dir} holds no checkpoint yet")
    dest = RESULTS / name / f"seed{seed}" / "in_progress"
    dest.mkdir(parents=True, exist_ok=True)
    for old in dest.glob("policy_*.pt"):
        old.unlink()
    from lasmp.algo.checkpoint import policy_checkpoint

    policy_checkpoint(run_dir / f"model_{last}.pt", dest / f"policy_{last}.pt", force=True)
    shutil.copyfile(run_dir.parent / f"seed{seed}.commands", dest / "commands")
    if (run_dir / "validation.json").exists():
        shutil.copyfile(run_dir / "validation.json", dest / "validation.json")
    return dest


def _job(text: str) -> tuple[str, int]:
    """RUNG:SEED, checked: a queue refuses a wrong job before its first run starts."""
    name, _, seed = text.partition(":")
    if name not in RUNGS or not seed.isdigit() or int(seed) not in RUNGS[name].seeds:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not RUNG:SEED of the ladder (e.g. base:10; `python scripts/ladder.py plan` lists them)"
        )
    return name, int(seed)


def queue(jobs: list[tuple[str, int]]) -> int:
    """Train each job in turn (a stopped run resumes) and collect it once finished (a collected run is
    left as it is); the first that fails or is stopped ends the queue with its exit code."""
    for name, seed in jobs:
        stamp = datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
        print(f"{stamp} queue: {name} {seed}", flush=True)
        code = train(name, seed)
        if code:
            print(
                f"queue: {name} {seed} ended with exit code {code}; the runs after it did not start",
                flush=True,
            )
            return code
        if not (RESULTS / name / f"seed{seed}" / "validation.json").exists():
            print(collect(name, seed), flush=True)
    return 0


def plan() -> None:
    for name, rung in RUNGS.items():
        for seed in rung.seeds:
            last = _last_saved(ROOT / RUNS / name / f"seed{seed}")
            collected = (RESULTS / name / f"seed{seed}" / "validation.json").exists()
            snap = snapshot_policy(name, seed) if last is None else None
            before = rung.continues if last is None and not snap else None
            state = (
                "collected"
                if collected
                else f"snapshot {snap[1] + 1}/{rung.iterations} iterations"
                if snap
                else f"after {before}'s {RUNGS[before].iterations}/{rung.iterations} iterations"
                if before
                else f"{0 if last is None else last + 1}/{rung.iterations} iterations"
            )
            print(f"{name:>13} seed {seed}: {state:>22} | python scripts/ladder.py train {name} {seed}")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("plan", help="every run and how far it is")
    for verb in ("train", "collect", "snapshot"):
        s = sub.add_parser(verb)
        s.add_argument("rung", choices=sorted(RUNGS))
        s.add_argument("seed", type=_seed)
        if verb == "collect":
            s.add_argument("--force", action="store_true", help="replace a collected run")
    q = sub.add_parser("queue", help="train and collect each RUNG:SEED in turn")
    q.add_argument("jobs", nargs="+", type=_job, metavar="RUNG:SEED")
    t = sub.add_parser("table", help="the ladder's table (Markdown, or --json)")
    t.add_argument("--json", action="store_true")
    t.add_argument("--results", type=Path, default=RESULTS, help=argparse.SUPPRESS)
    f = sub.add_parser("figure", help="docs/figures/scaling.png")
    f.add_argument("--out", type=Path, default=ROOT / "docs" / "figures" / "scaling.png")
    f.add_argument("--results", type=Path, default=RESULTS, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.cmd == "plan":
        plan()
    elif args.cmd == "train":
        return train(args.rung, args.seed)
    elif args.cmd == "collect":
        print(collect(args.rung, args.seed, args.force))
    elif args.cmd == "snapshot":
        print(snapshot(args.rung, args.seed))
    elif args.cmd == "queue":
        return queue(args.jobs)
    else:
        found = curves(args.results)
        if not found:
            raise SystemExit(f"error: no collected run under {args.results}")
        if args.cmd == "table":
            rows = table_rows(found)
            print(json.dumps(rows, indent=1) if args.json else markdown(rows))
        else:
            print(figure(found, args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
