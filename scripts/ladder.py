"""The scaling ladder (docs/scaling.md): LAS-MP+ at other batches, rollout lengths and updates, each run
scored during training on the validation benchmark (`runner.validation_*`), on fresh seeds (SEEDS: no
run before the ladder used them), the same seeds on every rung so that rungs compare seed by seed.

    python scripts/ladder.py plan                 # every run: its command and how far it is
    python scripts/ladder.py train RUNG SEED      # train it (a stopped run resumes from its last save;
                                                  # one whose machine was lost, from its snapshot: a warm start)
    python scripts/ladder.py collect RUNG SEED    # its curve, config, commands and light policies -> results/ladder/
    python scripts/ladder.py snapshot RUNG SEED   # a run still training: its newest policy checkpoint, curve, commands
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
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RUNS = Path("runs") / "ladder"  # the training directories (not committed)
RESULTS = ROOT / "results" / "ladder"  # what each finished run leaves in the tree
SEEDS = (10, 11)
BASE = "base"
STEPS_PER_ENV = 12  # the default rollout, runner.num_steps_per_env
SAMPLES = 1_024 * STEPS_PER_ENV * 1_800  # 22.1 M env-steps: every rung of (a) and (b) at equal samples
POINTS = 18  # validations per run: one every SAMPLES / POINTS env-steps (1.2 M), whatever the rung


@dataclass(frozen=True)
class Rung:
    """One configuration of the ladder: what it changes against the default, at how many envs, steps."""

    label: str
    lever: str
    num_envs: int = 1_024
    steps_per_env: int = STEPS_PER_ENV
    overrides: tuple[str, ...] = field(default=())

    @property
    def iterations(self) -> int:
        return SAMPLES // (self.num_envs * self.steps_per_env)

    @property
    def validation_interval(self) -> int:
        """About POINTS validations, the last at the run's last iteration: the divisor of the
        iterations nearest iterations / POINTS (8,192 envs: 225 iterations, every 15th, not every 12th,
        which left the last 9 iterations unscored)."""
        target = self.iterations / POINTS
        divisors = [k for k in range(1, self.iterations + 1) if self.iterations % k == 0]
        return min(divisors, key=lambda k: (abs(k - target), k))

    def command(
        self, seed: int, run_dir: Path, iterations: int, resume: bool, warm_start: Path | None = None
    ) -> list[str]:
        cmd = [sys.executable, "train.py", f"seed={seed}", f"env.num_envs={self.num_envs}"]
        cmd += [f"runner.num_steps_per_env={self.steps_per_env}", *self.overrides]
        # a save at least every 50 iterations and every validation: a stop (or a lost machine) costs at
        # most that much, also at 8,192 envs where an iteration takes a minute on 2 cores
        save = min(50, self.validation_interval)
        cmd += [f"runner.validation_interval={self.validation_interval}", f"runner.save_interval={save}"]
        cmd += [f"runner.log_dir={run_dir}", f"runner.max_iterations={iterations}"]
        cmd += [f"resume={run_dir}"] if resume else []
        return cmd + ([f"warm_start={warm_start}"] if warm_start else [])


RUNGS = {
    BASE: Rung("1,024 envs x 12 steps (the default)", "baseline"),
    "envs4096": Rung("4,096 envs", "(a) batch", num_envs=4_096),
    "envs8192": Rung("8,192 envs", "(a) batch", num_envs=8_192),
    "steps24": Rung("24 steps per env", "(b) rollout", steps_per_env=24),
    "steps48": Rung("48 steps per env", "(b) rollout", steps_per_env=48),
    "epochs5": Rung("5 learning epochs (rsl_rl's)", "(c) update", overrides=("algo.num_learning_epochs=5",)),
    "minibatches8": Rung("8 mini-batches", "(c) update", overrides=("algo.num_mini_batches=8",)),
    "kl0.02": Rung("KL target 0.02", "(c) update", overrides=("algo.desired_kl=0.02",)),
    # the baseline's plateau is a drift to a wide support at the trunk's level (docs/scaling.md): the
    # support-margin bonus (ours) taken out, the rest of LAS-MP+ kept
    "no_margin": Rung(
        "no support-margin bonus", "(e) reward", overrides=("env.rewards.weights.ours_support_margin=0",)
    ),
}


def _rung(name: str) -> Rung:
    if name not in RUNGS:
        raise SystemExit(f"error: unknown rung {name!r}; the rungs: {', '.join(RUNGS)}")
    return RUNGS[name]


def _seed(text: str) -> int:
    seed = int(text)
    if seed not in SEEDS:
        raise argparse.ArgumentTypeError(f"the ladder's seeds are {', '.join(map(str, SEEDS))}, got {seed}")
    return seed


def read_curve(path: Path) -> dict:
    """A run's validation.json; one line naming the file if it is missing or not JSON."""
    try:
        curve = json.loads(path.read_text())
        history = curve["history"]
    except FileNotFoundError:
        raise SystemExit(f"error: {path}: no such file (collect the run first)") from None
    except (json.JSONDecodeError, KeyError, TypeError) as err:
        raise SystemExit(f"error: {path}: not a validation curve ({err})") from None
    if not history:
        raise SystemExit(f"error: {path}: holds no validation")
    return curve


def curves(results: Path = RESULTS) -> dict[str, dict[int, dict]]:
    """{rung: {seed: curve}} of every collected run."""
    out: dict[str, dict[int, dict]] = {}
    for name in RUNGS:
        for seed in SEEDS:
            path = results / name / f"seed{seed}" / "validation.json"
            if path.exists():
                out.setdefault(name, {})[seed] = read_curve(path)
    return out


def table_rows(found: dict[str, dict[int, dict]]) -> list[dict]:
    """One row per rung with runs: each seed's final validation collision rate (its last score), their
    mean and spread, the seeds' differences from the baseline rung's same seed, and the env-steps and
    training minutes of the last score."""
    base = {seed: c["history"][-1]["collision_rate"] for seed, c in found.get(BASE, {}).items()}
    rows = []
    for name, runs in found.items():
        final = {seed: c["history"][-1] for seed, c in sorted(runs.items())}
        values = [r["collision_rate"] for r in final.values()]
        diffs = {s: r["collision_rate"] - base[s] for s, r in final.items() if s in base and name != BASE}
        rows.append(
            {
                "rung": name,
                "lever": RUNGS[name].lever,
                "label": RUNGS[name].label,
                "per_seed": {str(s): r["collision_rate"] for s, r in final.items()},
                "mean": sum(values) / len(values),
                "spread": max(values) - min(values),
                "diff_from_base": {str(s): d for s, d in diffs.items()},
                "mean_diff_from_base": sum(diffs.values()) / len(diffs) if diffs else None,
                "best_mean": sum(min(r["collision_rate"] for r in c["history"]) for c in runs.values())
                / len(runs),
                "env_steps": max(r["env_steps"] for r in final.values()),
                "minutes": max(r["wall_s"] for r in final.values()) / 60.0,
            }
        )
    return rows


def markdown(rows: list[dict]) -> str:
    out = [
        "| lever | rung | seeds | validation collision per seed | mean | spread | vs baseline, per seed "
        "(mean) | best on the curve, mean | env-steps | minutes |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        seeds = ", ".join(r["per_seed"])
        per_seed = " / ".join(f"{v:.3f}" for v in r["per_seed"].values())
        diffs = " / ".join(f"{v:+.3f}" for v in r["diff_from_base"].values())
        diff = f"{diffs} ({r['mean_diff_from_base']:+.3f})" if r["diff_from_base"] else "–"
        out.append(
            f"| {r['lever']} | {r['label']} | {seeds} | {per_seed} | {r['mean']:.3f} | {r['spread']:.3f} | "
            f"{diff} | {r['best_mean']:.3f} | {r['env_steps'] / 1e6:.1f} M | {r['minutes']:.0f} |"
        )
    return "\n".join(out)


def figure(found: dict[str, dict[int, dict]], out: Path) -> Path:
    """Validation collision against env-steps: one line per rung (the seeds' mean), seeds as thin lines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.2))
    for i, (name, runs) in enumerate(found.items()):
        color = f"C{i}"
        series = []
        for curve in runs.values():
            steps = [r["env_steps"] / 1e6 for r in curve["history"]]
            values = [r["collision_rate"] for r in curve["history"]]
            ax.plot(steps, values, color=color, lw=0.7, alpha=0.5)
            series.append(dict(zip(steps, values, strict=True)))
        shared = sorted(set.intersection(*(set(s) for s in series)))
        ax.plot(
            shared,
            [sum(s[x] for s in series) / len(series) for x in shared],
            color=color,
            lw=2,
            label=f"{RUNGS[name].label} ({len(runs)} seeds)",
        )
    ax.axhline(0.029, color="k", ls="--", lw=1, label="the paper's LAS-MP (Xi_eval)")
    ax.set_xlabel("env-steps (millions)")
    ax.set_ylabel("validation collision rate")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.stem + ".tmp.png")
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    tmp.replace(out)
    return out


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


def train(name: str, seed: int) -> int:
    """Train (or resume) one run. Its command goes into runs/ladder/<rung>/seed<k>.commands, with the
    time and the machine, once the training has saved a checkpoint (so that a snapshot of a run still
    training carries it), never for a run that failed before its first save. A run with no checkpoint
    here but a committed snapshot (its machine was lost) goes on from the snapshot's policy, a warm
    start (lasmp/cli/warm_start.py), after the snapshot's commands."""
    rung = _rung(name)
    run_dir = RUNS / name / f"seed{seed}"
    last = _last_saved(ROOT / run_dir)
    snap = snapshot_policy(name, seed) if last is None else None
    done = last + 1 if last is not None else snap[1] + 1 if snap else 0
    if done >= rung.iterations:
        print(f"{run_dir}: done ({rung.iterations} iterations)")
        return 0
    warm = Path(os.path.relpath(snap[0], ROOT)) if snap else None
    cmd = rung.command(seed, run_dir, rung.iterations - done, resume=last is not None, warm_start=warm)
    commands = ROOT / RUNS / name / f"seed{seed}.commands"
    if snap and not commands.exists():  # the run's history so far, then the warm start's command
        commands.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(snap[0].parent / "commands", commands)
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
    rung = _rung(name)
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
    _rung(name)
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


def plan() -> None:
    for name, rung in RUNGS.items():
        for seed in SEEDS:
            last = _last_saved(ROOT / RUNS / name / f"seed{seed}")
            collected = (RESULTS / name / f"seed{seed}" / "validation.json").exists()
            snap = snapshot_policy(name, seed) if last is None else None
            state = (
                "collected"
                if collected
                else f"snapshot {snap[1] + 1}/{rung.iterations} iterations"
                if snap
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
