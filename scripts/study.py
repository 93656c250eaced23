"""The three-seed study (docs/results.md): train, resume and evaluate every run, idempotently.

    python scripts/study.py plan                      # what is done, what is left
    python scripts/study.py train METHOD SEED [--until N]   # train (or resume) to N iterations (default: its budget)
    python scripts/study.py evaluate METHOD SEED [--at N]    # all of Xi_eval on model_<N-1>.pt (or policy_<N-1>.pt)
    python scripts/study.py next                      # the first unfinished step, trained or evaluated
    python scripts/study.py summary [--paper-columns] # results/study/summary.json from what is evaluated
    python scripts/study.py compare                   # the fast learner against float32 (docs/performance.md)
    python scripts/study.py table [--wide] [--paper]  # the study's table (--wide: docs/results.md's), from summary.json;
                                                      # --paper: the paper's Table II rows below ours
    python scripts/study.py table --headline          # the README's: ours with the paper's row beside it
    python scripts/study.py ordering                  # each ablation against its full method, by the intervals
    python scripts/study.py tables                    # rewrite both tables (with --paper) in README.md, docs/results.md

Runs live in runs/study/<method>/seed<k>/ (not committed: checkpoints); each command line is
appended to runs/study/<method>/seed<k>.commands before it runs, so a run can be continued in a
later sitting, and to its committed copy results/study/<method>/seed<k>.commands once it has
succeeded. A command that fails, or is stopped by Ctrl-C (train.py saves a checkpoint first), ends
the study with its own exit status and message. Evaluations go to results/study/<method>[@<N>]/seed<k>/
(committed), with the run's config, its policy checkpoint (`policy_<N-1>.pt`) and learning curve
(`curves_<N>.json`). Every run has the same budget: 450 iterations x 1,024 envs (the cpu preset), in
the default configuration.

LAS-MP's seeds 0, 1 and 2 come first, then seed 0's continuation to 1,000 iterations (the policy
shipped before LAS-MP+), then the other methods seed by seed, then LAS-MP seeds 1 and 2 to 1,000 iterations: all
under the paper's recipe (`recipe=paper`). Then LAS-MP+ (`recipe=lasmp_plus`, the default recipe)
and its four ablations under its recipe, at one budget chosen from LAS-MP+'s learning curve
(docs/screening.md); each of these runs is also played with the mirror twins of Xi_eval's first
1,024 episodes (results/study/<method>/seed<k>/mirror/). Last, LAS-MP+ once more on seeds 3, 4 and 5,
which no screening run saw (its seeds 0 and 1 are the runs that chose it): a row of its own, free of
that choice.

Every run trains with the bfloat16 learner (`algo.precision=bfloat16`: bfloat16 autocast, fused Adam,
compiled MLPs) (ours): `auto` chooses by the CPU, and the study's machines differ, so one learner for
every row keeps the learner out of the comparison (docs/results.md#one-learner-for-every-row).
LAS-MP's float32 runs are kept in results/study/float32_learner/ as rows of their own. A CPU without
native bfloat16 (AVX2 only: autocast there is emulated, far slower) is refused.

Two earlier passes, each under another entropy bonus (docs/results.md#the-entropy-bonus), are kept
beside the study. The first, under rsl_rl's 0.01, in results/study/entropy_0.01/ (its runs in
runs/study_entropy_0.01/), with the check that the fast learner (bfloat16 autocast) learns as float32
does: LAS-MP with `algo.precision=float32`, seeds 0 and 1, against that pass's LAS-MP seeds 0 and 1 on
Xi_eval's first 2,000 episodes, which `compare` tabulates
(docs/performance.md#does-the-fast-learner-learn-the-same). The second, without a bonus, in
results/study/entropy_0/ (its runs in runs/study_entropy_0/). The study itself runs under the default
0.003.
"""

from __future__ import annotations

import argparse
import json
import re
import shlex
import signal
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path

from lasmp.inputs import InputError, int_arg, read_json

ROOT = Path(__file__).resolve().parents[1]
RUNS = ROOT / "runs" / "study"
RESULTS = ROOT / "results" / "study"
FIRST_PASS = RESULTS / "entropy_0.01"  # the first pass, under the entropy bonus 0.01 (the docstring)
SEEDS = (0, 1, 2)
BUDGET = 450
HEADLINE = 1000  # LAS-MP's three seeds continue to the cpu preset's length
# LAS-MP+'s and its ablations' one budget, chosen from LAS-MP+ seed 0's learning curve by the rule of
# docs/screening.md ("LAS-MP+'s budget") before the ablations train
PLUS_BUDGET = 450
# LAS-MP+'s seeds 0 and 1 are the screening runs that chose it (a winner's curse); these three no
# screening run saw, trained last, make a row of their own (FRESH_ROW)
FRESH_SEEDS = (3, 4, 5)
FRESH_ROW = f"LAS-MP+, seeds {FRESH_SEEDS[0]}-{FRESH_SEEDS[-1]}"
# method -> train.py overrides (the ablations of docs/method.md are policy groups; R-S its own task).
# LAS-MP and its ablations under the paper's recipe (recipe=paper), as the study first ran them;
# LAS-MP+ (the default recipe, ours) and the same four ablations under it
PAPER, PLUS = "recipe=paper", "recipe=lasmp_plus"
ABLATIONS = (
    "no_alignment_command",
    "no_platform_velocity_estimates",
    "no_explicit_estimator",
    "no_explicit_estimator_history",
)
PAPER_METHODS = {
    "lasmp": [PAPER],
    "lasmp_centre": [PAPER, "env.rewards.h_des_from=centre"],
    **{a: [PAPER, f"policy={a}"] for a in ABLATIONS},
    "rs": ["task=rough_static"],  # the rough-terrain task takes no recipe
}
PLUS_METHODS = {"lasmp_plus": [PLUS], **{f"plus_{a}": [PLUS, f"policy={a}"] for a in ABLATIONS}}
METHODS = PAPER_METHODS | PLUS_METHODS
MIRROR_EPISODES = 1024  # LAS-MP+'s runs are also played with their mirror twins on this many
LEARNER = "algo.precision=bfloat16"  # the study's one learner (the docstring)
FLOAT32_LEARNER = "float32_learner"  # under RESULTS: LAS-MP's runs under float32, before the pin
# their rows: name -> (method, iterations, seeds); seed 2 ran float32 to 244 and bfloat16 after: no row
FLOAT32_ROWS = {
    "LAS-MP, float32 learner": ("lasmp", BUDGET, (0, 1)),
    "LAS-MP (1,000 it.), float32 learner": ("lasmp", HEADLINE, (0,)),
}
FLOAT32 = "lasmp_float32"  # the fast-learner comparison, in the first pass: not a row of the table
FLOAT32_SEEDS = (0, 1)
FLOAT32_EPISODES = 2000
ABLATION_NAMES = {
    "no_alignment_command": "w/o alignment command",
    "no_platform_velocity_estimates": "w/o platform velocity estimates",
    "no_explicit_estimator": "w/o explicit estimator",
    "no_explicit_estimator_history": "w/o explicit estimator, with the history",
}
# the results table's rows: name -> (method, iterations, controller); Stand Still has no seeds
ROWS = {
    "LAS-MP": ("lasmp", BUDGET, None),
    "LAS-MP (1,000 it.)": ("lasmp", HEADLINE, None),
    "LAS-MP, centre reward": ("lasmp_centre", BUDGET, None),
    **{ABLATION_NAMES[a]: (a, BUDGET, None) for a in ABLATIONS},
    "R-S": ("rs", BUDGET, "rs"),
    "R-S (oracle)": ("rs", BUDGET, "rs_oracle"),
    "LAS-MP+": ("lasmp_plus", PLUS_BUDGET, None),
    **{f"LAS-MP+ {ABLATION_NAMES[a]}": (f"plus_{a}", PLUS_BUDGET, None) for a in ABLATIONS},
}
STAND_STILL = RESULTS / "stand_still" / "seed0"
# the README's table: label -> the summary rows it shows, side by side ("; " between them)
TABLE_ROWS = {
    "Stand Still (a = 0)": ("Stand Still",),
    "LAS-MP, 450 iterations": ("LAS-MP",),
    "LAS-MP, 1,000 iterations (shipped before LAS-MP+)": ("LAS-MP (1,000 it.)",),
    "LAS-MP, centre reward reading": ("LAS-MP, centre reward",),
    **{name: (name,) for name in ABLATION_NAMES.values()},
    "R-S (its estimates; the true x_exp)": ("R-S", "R-S (oracle)"),
    "LAS-MP, float32 learner (450; 1,000 it.)": tuple(FLOAT32_ROWS),
    f"LAS-MP+ (ours), {PLUS_BUDGET:,} iterations (seed 0 is the shipped policy)": ("LAS-MP+",),
    f"LAS-MP+, seeds {', '.join(map(str, FRESH_SEEDS))} (no screening run saw them)": (FRESH_ROW,),
    **{f"LAS-MP+ {name}": (f"LAS-MP+ {name}",) for name in ABLATION_NAMES.values()},
}
# the README's headline: label -> (summary row, the seed directory of a single run or None for the row
# over its seeds, the paper's Table II row beside it (lasmp.eval.paper)); at most 8 rows
SHIPPED_SEED = "results/study/lasmp_plus/seed0"  # resources/policies/lasmp_a1.pt (its README)
HEADLINE_ROWS = {
    f"the shipped policy: LAS-MP+ seed 0, {PLUS_BUDGET} iterations": ("LAS-MP+", SHIPPED_SEED, "lasmp"),
    f"LAS-MP+ (ours), {PLUS_BUDGET} iterations, fresh seeds {FRESH_SEEDS[0]}-{FRESH_SEEDS[-1]}": (
        FRESH_ROW,
        None,
        "lasmp",
    ),
    f"LAS-MP, the paper's recipe, {BUDGET} iterations, seeds 0-2": ("LAS-MP", None, "lasmp"),
    "Stand Still (zero action)": ("Stand Still", None, "stand_still"),
    f"R-S (rough-terrain policy, zero command), {BUDGET} iterations, seeds 0-2": ("R-S", None, "rs"),
}
TABLE_COLUMNS = {  # metric -> (header, format)
    "collision_rate": ("collision rate", ".3f"),
    "height_violation_rate": ("height-violation rate", ".3f"),
    "position_deviation_m": ("position dev. (m)", ".3f"),
    "rotation_deviation_rad": ("rotation dev. (rad)", ".3f"),
    "power_w": ("power (W)", ".2f"),
}
WIDE_COLUMNS = {  # docs/results.md's table: every metric, each summary row on its own
    "collision_rate": ("collision", ".3f"),
    "height_violation_rate": ("height viol.", ".3f"),
    "position_deviation_m": ("position dev. (m, platform)", ".3f"),
    "rotation_deviation_rad": ("rotation dev. (rad, world tilt)", ".3f"),
    "power_w": ("power (W)", ".2f"),
    "position_deviation_translating_m": ("position dev. (m, translating)", ".3f"),
    "rotation_deviation_platform_rad": ("rotation (rad, rel. to platform)", ".3f"),
}


def run_dir(method: str, seed: int) -> Path:
    return RUNS / method / f"seed{seed}"


def last_iteration(d: Path) -> int:
    """The last completed iteration saved in run directory d (-1 if none)."""
    its = [int(m.group(1)) for p in d.glob("model_*.pt") if (m := re.fullmatch(r"model_(\d+)\.pt", p.name))]
    return max(its, default=-1)


def saved_at(d: Path, it: int) -> Path:
    """The checkpoint of iteration `it` in run directory d: its full model_<it>.pt, or the policy_<it>.pt
    that `runner.keep_full` turns an older save into once the run goes on (a missing one: the full name)."""
    full, policy = d / f"model_{it}.pt", d / f"policy_{it}.pt"
    return policy if not full.exists() and policy.exists() else full


def execute(cmd: list[str], log: Path) -> None:
    """Run cmd niced, after appending it to log with the time and the commit. A log in runs/study/ is
    mirrored in results/study/ (committed, so the commands outlive the machine) once cmd has succeeded:
    a failed command made nothing to commit. A failure (or a Ctrl-C) ends the study with cmd's exit
    status: cmd has said why, and a traceback of this script would only bury it."""
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    when = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    entry = f"# {when}, at {commit.stdout.strip() or 'no commit'}, nice -n 10\n{shlex.join(cmd)}\n"
    append(log, entry)
    print("+", shlex.join(cmd), flush=True)
    status = run_to_its_end(["nice", "-n", "10", *cmd])
    if status != 0:
        raise SystemExit(status)
    if log.is_relative_to(RUNS):
        append(RESULTS / log.relative_to(RUNS), entry)


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
        status = subprocess.run(cmd, cwd=ROOT).returncode
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


def budget(method: str) -> int:
    """The iterations a method's runs train for: LAS-MP+'s (and its ablations') own, the rest BUDGET."""
    return PLUS_BUDGET if method in PLUS_METHODS else BUDGET


def train(method: str, seed: int, until: int | None = None) -> None:
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
        f"runner.log_dir={d.relative_to(ROOT)}",
    ]
    if done > 0:
        cmd += [f"resume={d.relative_to(ROOT)}", f"runner.max_iterations={until - done}"]
    else:
        cmd += [f"runner.max_iterations={until}"]
    execute(cmd, d.with_suffix(".commands"))
    record_run(method, seed, until)


def record_run(method: str, seed: int, at: int) -> None:
    """Beside the run's evaluation: its config, its policy at 'at' iterations in the light form (the
    actor and its normalizers, 0.96 MB, lasmp.light_checkpoint; the full checkpoint, with the critic,
    the optimizers and the envs' running state, stays in runs/) and its learning curve to 'at'
    (lasmp.eval.curves' windows of 10 iterations): a run adds about 1 MB to the repository."""
    from lasmp.algo.checkpoint import policy_checkpoint
    from lasmp.eval.curves import read_scalars, truncated, windows
    from lasmp.eval.report import atomic_write_text
    from lasmp.light_checkpoint import convert_in_place

    d, out = run_dir(method, seed), result_dir(method, seed, at)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "config.yaml", (d / "config.yaml").read_text())
    policy = out / f"policy_{at - 1}.pt"
    if not policy.exists():
        policy_checkpoint(saved_at(d, at - 1), policy)
    convert_in_place(policy)  # a light one is left as it is
    rows = windows(truncated(read_scalars(d), at - 1), 10)
    curves = {"run_dir": str(d.relative_to(ROOT)), "windows": rows}
    atomic_write_text(out / f"curves_{at}.json", json.dumps(curves))
    print(f"wrote {out.relative_to(ROOT)}/{{config.yaml,{policy.name},curves_{at}.json}}")


def result_dir(
    method: str, seed: int, at: int, controller: str | None = None, root: Path | None = None
) -> Path:
    name = controller or method
    return (root or RESULTS) / (name if at == BUDGET else f"{name}@{at}") / f"seed{seed}"


def controllers(method: str) -> list[str | None]:
    return ["rs", "rs_oracle"] if method == "rs" else [None]


def evaluations(method: str, seed: int, at: int) -> list[tuple[Path, list[str]]]:
    """A run's evaluations, (out, evaluate.py's options): all of Xi_eval per controller, and for
    LAS-MP+'s runs the first MIRROR_EPISODES with their mirror twins (in the run's result, mirror/)."""
    runs = [(result_dir(method, seed, at, c), ["--controller", c] if c else []) for c in controllers(method)]
    if method in PLUS_METHODS:
        n = str(MIRROR_EPISODES)
        runs.append((result_dir(method, seed, at) / "mirror", ["--num-trajectories", n, "--mirror", n]))
    return runs


def committed_policy(method: str, seed: int, at: int) -> Path:
    """The policy checkpoint `record_run` committed beside the run's evaluation once it had trained to
    'at' iterations: it outlives the machine, runs/ does not."""
    return result_dir(method, seed, at) / f"policy_{at - 1}.pt"


def evaluate(method: str, seed: int, at: int | None = None) -> None:
    at = at or budget(method)
    ckpt = saved_at(run_dir(method, seed), at - 1)
    if not ckpt.exists() and committed_policy(method, seed, at).exists():
        ckpt = committed_policy(method, seed, at)  # a fresh machine: the run's checkpoints are gone
    if not ckpt.exists():
        raise SystemExit(f"{ckpt} does not exist: train {method} seed {seed} to {at} iterations first")
    for out, options in evaluations(method, seed, at):
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
            *options,
        ]
        execute(cmd, run_dir(method, seed).with_suffix(".commands"))


def steps():
    """Every step of the study in order: (kind, method, seed, iterations)."""
    # LAS-MP's three seeds first (the row the others are compared with), then seed 0's continuation
    # to 1,000 iterations: the new shipped policy
    order = [("lasmp", s, BUDGET) for s in SEEDS] + [("lasmp", 0, HEADLINE)]
    order += [(m, s, BUDGET) for s in SEEDS for m in PAPER_METHODS if m != "lasmp"]
    order += [("lasmp", s, HEADLINE) for s in SEEDS[1:]]
    # then LAS-MP+'s three seeds, and its ablations seed by seed
    order += [("lasmp_plus", s, PLUS_BUDGET) for s in SEEDS]
    order += [(m, s, PLUS_BUDGET) for s in SEEDS for m in PLUS_METHODS if m != "lasmp_plus"]
    # then LAS-MP+ on the seeds no screening run saw
    order += [("lasmp_plus", s, PLUS_BUDGET) for s in FRESH_SEEDS]
    for method, seed, at in order:
        yield "train", method, seed, at
        yield "evaluate", method, seed, at


def is_done(kind: str, method: str, seed: int, at: int) -> bool:
    """A step is done when its result is committed. A training is also done once its policy checkpoint
    is committed (its evaluation then plays that one): on a fresh machine runs/ is gone, and a later
    step that needs the full checkpoint (a continuation to 1,000 iterations) retrains from the start."""
    evaluated = all((out / "metrics.json").exists() for out, _ in evaluations(method, seed, at))
    if kind == "train":
        trained = (
            last_iteration(run_dir(method, seed)) + 1 >= at or committed_policy(method, seed, at).exists()
        )
        return evaluated or trained
    return evaluated


def summary_args() -> list[str]:
    """results_table's --method groups: every row with at least one evaluated seed (the study's,
    LAS-MP+ on its fresh seeds, then the float32 learner's), and Stand Still."""
    rows = {name: [result_dir(m, s, at, c) for s in SEEDS] for name, (m, at, c) in ROWS.items()}
    rows[FRESH_ROW] = [result_dir("lasmp_plus", s, PLUS_BUDGET) for s in FRESH_SEEDS]
    for name, (m, at, seeds) in FLOAT32_ROWS.items():
        rows[name] = [result_dir(m, s, at, root=RESULTS / FLOAT32_LEARNER) for s in seeds]
    args = []
    for name, dirs in rows.items():
        done = [str(d.relative_to(ROOT)) for d in dirs if (d / "metrics.json").exists()]
        if done:
            args += ["--method", name, *done]
    return args + ["--method", "Stand Still", str(STAND_STILL.relative_to(ROOT))]


def first_collision_rate(method: str, seed: int) -> float | None:
    """The collision rate over Xi_eval's first FLOAT32_EPISODES episodes of a first-pass run's
    evaluation (None when it is not evaluated): the breakdown's count, whether the evaluation covered
    those episodes alone or all 10,000. An evaluated run whose records are not regenerated yet raises
    EpisodesFileError saying how to regenerate them."""
    from lasmp.eval.breakdown import breakdown, first_episodes
    from lasmp.eval.episodes import episodes_path, read_csv

    d = result_dir(method, seed, BUDGET, root=FIRST_PASS)
    if not (d / "metrics.json").exists():
        return None
    b = breakdown(
        first_episodes(read_csv(episodes_path(d)), FLOAT32_EPISODES)
    )  # missing: says how to regenerate
    return b["collisions"] / b["episodes"]


def compare() -> str:
    """The fast learner against float32 in the first pass (Markdown): per seed, training success
    (mean over 50 iterations) with the highest curriculum level, the first iteration above level 5,
    and the collision rate on Xi_eval's first 2,000 episodes."""
    sides = [(m, s) for m in ("lasmp", FLOAT32) for s in FLOAT32_SEEDS]
    label = {"lasmp": "fast", FLOAT32: "float32"}
    curves = {}
    for m, s in sides:
        path = result_dir(m, s, BUDGET, root=FIRST_PASS) / f"curves_{BUDGET}.json"
        if not path.exists():
            raise SystemExit(f"{path} does not exist: the first pass's {m} seed {s} is not in this checkout")
        curves[m, s] = read_json(path)["windows"]
    head = " | ".join(f"{label[m]}, seed {s}" for m, s in sides)
    lines = [f"| iterations | {head} |", "|---" * (len(sides) + 1) + "|"]
    for lo in range(0, BUDGET, 50):
        cells = []
        for key in sides:
            w = [r for r in curves[key] if lo <= r["iterations"][0] < lo + 50]
            success = sum(r["Episode/success_rate"] for r in w) / len(w)
            cells.append(f"{success:.2f} (level {max(r['Curriculum/level'] for r in w):.0f})")
        lines.append(f"| {lo}-{min(lo + 50, BUDGET) - 1} | " + " | ".join(cells) + " |")
    above = []
    for key in sides:
        first = [r["iterations"][0] for r in curves[key] if r["Curriculum/level"] > 5]
        above.append(str(first[0]) if first else "never")
    lines.append("| first window above level 5 | " + " | ".join(above) + " |")
    rates = [first_collision_rate(m, s) for m, s in sides]
    rates = ["not evaluated" if r is None else f"{r:.3f}" for r in rates]
    lines.append(f"| collision, Xi_eval's first {FLOAT32_EPISODES:,} | " + " | ".join(rates) + " |")
    return "\n".join(lines)


def _seed_of(result_dir: str) -> str:
    return result_dir.rstrip("/").rsplit("seed", 1)[-1]


def _cell(entry: dict, metric: str, fmt: str) -> str:
    """Three seeds: the mean ± the 95 % t-interval; fewer: each seed's value ("a / b", seed order:
    two seeds give no useful interval); Stand Still (no seeds): its one value."""
    m = entry["metrics"][metric]
    if len(entry["seeds"]) == len(SEEDS):
        return f"{m['mean']:{fmt}} ± {m['ci95']:{fmt}}"
    return " / ".join(f"{v:{fmt}}" for v in m["per_seed"])


def summary_methods(summary_path: Path | None = None) -> dict:
    """summary.json's rows by name (RESULTS/summary.json when None); InputError naming the file when it
    is missing, cut short or not a summary."""
    path = summary_path or RESULTS / "summary.json"
    if not path.exists():
        raise InputError(f"{path}: no such file; write it with `python scripts/study.py summary`")
    summary = read_json(path)
    if not isinstance(summary.get("methods"), dict):
        raise InputError(
            f'{path}: no "methods" object: not the summary `python scripts/study.py summary` writes'
        )
    return summary["methods"]


def table(summary_path: Path | None = None, wide: bool = False, paper: bool = False) -> str:
    """A results table (Markdown) from summary.json. The README's (default): its rows (TABLE_ROWS;
    R-S beside its oracle), the paper's five metrics, the number of seeds. `wide`: docs/results.md's,
    every summary row on its own, every metric, the seeds by name and each seed's learner. A row not
    yet evaluated is left out. `paper`: the paper's rows follow ours (`paper_rows`)."""
    from lasmp.eval.results_table import SHORT_LEARNER

    methods = summary_methods(summary_path)
    columns = WIDE_COLUMNS if wide else TABLE_COLUMNS
    heads = [h for h, _ in columns.values()] + (["learner per seed"] if wide else [])
    lines = ["| method | seeds | " + " | ".join(heads) + " |", "|---" * (len(heads) + 2) + "|"]
    rows = {n: (n,) for n in methods} if wide else TABLE_ROWS
    for label, names in rows.items():
        entries = [methods[n] for n in names if n in methods]
        if not entries:
            continue
        seeds = [
            ", ".join(map(_seed_of, e["seeds"])) if wide or len(e["seeds"]) < len(SEEDS) else str(len(SEEDS))
            for e in entries
        ]
        seeds = "–" if names == ("Stand Still",) else "; ".join(dict.fromkeys(seeds))  # the same once
        cells = ["; ".join(_cell(e, metric, fmt) for e in entries) for metric, (_, fmt) in columns.items()]
        if wide:
            learners = entries[0].get("learner_per_seed") or []
            cells.append(", ".join(SHORT_LEARNER.get(x, "–") for x in learners) or "–")
        lines.append(f"| {label} | {seeds} | " + " | ".join(cells) + " |")
    return "\n".join(lines + (paper_rows(columns, wide) if paper else []))


def headline(summary_path: Path | None = None) -> str:
    """The README's table (HEADLINE_ROWS): each of our rows with the paper's Table II row beside it, the
    same metric in adjacent columns (ours, then the paper's), so that the two read at a glance. Ours:
    the mean ± a 95 % t-interval over three seeds, or one run's value (the shipped policy, Stand
    Still); the paper's: its mean ± its std. A row not yet evaluated is left out."""
    from lasmp.eval.paper import paper_row

    methods = summary_methods(summary_path)
    heads = [f"{h}: ours | paper" for h, _ in TABLE_COLUMNS.values()]
    lines = [
        "| ours, vs the paper's row | " + " | ".join(heads) + " |",
        "|---" * (2 * len(heads) + 1) + "|",
    ]
    for label, (name, seed_dir, paper_key) in HEADLINE_ROWS.items():
        entry = methods.get(name)
        if entry is None or (seed_dir is not None and seed_dir not in entry["seeds"]):
            continue
        paper = paper_row(paper_key)
        cells = []
        for metric, (_, fmt) in TABLE_COLUMNS.items():
            m = entry["metrics"][metric]
            if seed_dir is not None:
                ours = f"{m['per_seed'][entry['seeds'].index(seed_dir)]:{fmt}}"
            else:
                ours = _cell(entry, metric, fmt)
            theirs = paper["metrics"][metric]
            cells += [ours, f"{theirs['mean']} ± {theirs['std']}"]
        lines.append(f"| {label}, vs the paper's {paper['method']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def ordering(summary_path: Path | None = None) -> str:
    """Whether each ablation is ordered against its full method (LAS-MP's four under the paper's
    recipe, LAS-MP+'s under its own) by the study's rule: two rows are ordered on a metric only
    when their 95 % intervals over three seeds do not overlap. Each cell: `above`, `below` (the
    ablation's interval against the full method's) or `overlap`; a row with fewer than three seeds
    orders nothing yet. LAS-MP+'s ablations are also set against FRESH_ROW, LAS-MP+ on the seeds no
    screening run saw, once it has three. The paper's Table II has every ablation above LAS-MP in
    every one of these metrics."""
    methods = summary_methods(summary_path)
    lines = [
        "| full method | ablation | seeds | " + " | ".join(h for h, _ in TABLE_COLUMNS.values()) + " |",
        "|---" * (len(TABLE_COLUMNS) + 3) + "|",
    ]
    for base in ("LAS-MP", "LAS-MP+", FRESH_ROW):
        prefix = "" if base == "LAS-MP" else "LAS-MP+ "
        for name in ABLATION_NAMES.values():
            row, full = methods.get(prefix + name), methods.get(base)
            if row is None or full is None:
                continue
            ready = len(row["seeds"]) == len(full["seeds"]) == len(SEEDS)
            cells = [_order(full["metrics"][m], row["metrics"][m]) if ready else "–" for m in TABLE_COLUMNS]
            lines.append(f"| {base} | {name} | {len(row['seeds'])} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _order(full: dict, ablation: dict) -> str:
    lo, hi = ablation["mean"] - ablation["ci95"], ablation["mean"] + ablation["ci95"]
    if lo > full["mean"] + full["ci95"]:
        return "above"
    if hi < full["mean"] - full["ci95"]:
        return "below"
    return "overlap"


# the documents whose results table `tables` rewrites: path -> the table (the README's headline, the
# full study in docs/results.md)
TABLE_DOCS = {
    "README.md": lambda summary: headline(summary),
    "docs/results.md": lambda summary: table(summary, wide=True, paper=True),
}


def replace_table(text: str, new: str) -> str:
    """text with its Markdown table that has new's header line (from that line to the next blank line
    or the end) replaced by new; a text without that header is an error, not a silent no-op."""
    lines, header = text.split("\n"), new.split("\n", 1)[0]
    if header not in lines:
        raise ValueError(f"no table with the header {header!r}")
    start = lines.index(header)
    end = next((i for i in range(start, len(lines)) if not lines[i].strip()), len(lines))
    return "\n".join(lines[:start] + new.split("\n") + lines[end:])


def write_tables(summary_path: Path | None = None) -> None:
    """Rewrite each TABLE_DOCS document's results table from summary.json."""
    from lasmp.eval.report import atomic_write_text

    for name, make in TABLE_DOCS.items():
        path = ROOT / name
        atomic_write_text(path, replace_table(path.read_text(), make(summary_path)))
        print(f"wrote {name}'s table")


def paper_rows(columns: dict, wide: bool) -> list[str]:
    """The paper's Table II (lasmp.eval.paper) as rows of our table, each marked as the
    paper's, `mean ± the paper's std` (over what, it does not say); a column it does not report stays
    empty. Its budget differs from ours: 8,192 envs x 4,000 iterations."""
    from lasmp.eval.paper import PAPER_ROWS, paper_row

    lines = []
    for key in PAPER_ROWS:
        row = paper_row(key)
        cells = [
            f"{m['mean']} ± {m['std']}" if (m := row["metrics"].get(metric)) else "" for metric in columns
        ]
        lines.append(f"| paper: {row['method']} | – | " + " | ".join(cells + ([""] if wide else [])) + " |")
    return lines


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("plan")
    sub.add_parser("next")
    sub.add_parser("compare")
    tab = sub.add_parser("table")
    tab.add_argument(
        "--wide", action="store_true", help="docs/results.md's table: every row and metric on its own"
    )
    tab.add_argument(
        "--paper", action="store_true", help="the paper's Table II rows below ours, marked as its"
    )
    tab.add_argument(
        "--headline", action="store_true", help="the README's table: ours with the paper's beside it"
    )
    sub.add_parser("ordering", help="each ablation against its full method, by the intervals")
    sub.add_parser("tables", help="rewrite README.md's and docs/results.md's tables from summary.json")
    sub.add_parser("summary").add_argument(
        "--paper-columns", action="store_true", help="print only the paper's five metrics"
    )
    for name in ("train", "evaluate"):
        s = sub.add_parser(name)
        s.add_argument("method", choices=sorted(METHODS))
        s.add_argument("seed", type=int, choices=SEEDS + FRESH_SEEDS)
        s.add_argument(
            "--until" if name == "train" else "--at",
            dest="n",
            type=int_arg(1),
            help="iterations (default: the method's budget, 450; LAS-MP+'s PLUS_BUDGET)",
        )
    args = p.parse_args(argv)
    try:
        run_step(args)
    except InputError as err:  # a file the step reads (summary.json, a learning curve), named in one line
        raise SystemExit(f"error: {err}") from None


def run_step(args: argparse.Namespace) -> None:
    """The step the command line names."""
    if args.cmd == "plan":
        for step in steps():
            print(("done " if is_done(*step) else "todo ") + " ".join(map(str, step)))
    elif args.cmd == "next":
        for kind, method, seed, n in steps():
            if not is_done(kind, method, seed, n):
                (train if kind == "train" else evaluate)(method, seed, n)
                return
        print("the study is complete")
    elif args.cmd == "compare":
        from lasmp.eval.episodes import EpisodesFileError

        try:
            print(compare())
        except EpisodesFileError as err:
            raise SystemExit(f"error: {err}") from None
    elif args.cmd == "table":
        print(headline() if args.headline else table(wide=args.wide, paper=args.paper))
    elif args.cmd == "ordering":
        print(ordering())
    elif args.cmd == "tables":
        write_tables()
    elif args.cmd == "summary":
        from lasmp.eval import results_table

        columns = ["--paper-columns"] if args.paper_columns else []
        raise SystemExit(
            # the study's own summary.json, rewritten from its results each time: --force
            results_table.main(
                [*summary_args(), "--json", str(RESULTS / "summary.json"), "--force", *columns]
            )
        )
    elif args.cmd == "train":
        train(args.method, args.seed, args.n)
    else:
        evaluate(args.method, args.seed, args.n)


if __name__ == "__main__":
    main()
