"""The study's plan (scripts/study.py): where its runs and results live, its methods, seeds and
budgets, the steps in their order and which of them are done.

The paths are module attributes read when a function runs (the tests point them at a tree of their
own): the other modules of the study read them as `plan.ROOT`, `plan.RESULTS`, ...; a constant they
only read is imported by name."""

from __future__ import annotations

import re
from pathlib import Path

from ladderlib.rungs import CHOSEN_IN_A_ROW, ROW_SEEDS, RUNGS
from ladderlib.rungs import RESULTS as LADDER_RESULTS

ROOT = Path(__file__).resolve().parents[2]
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
# the new rows (docs/results.md#the-new-rows-chosen-on-validation-played-on-xi_eval): LAS-MP+ at the recipe and budget chosen on the validation
# benchmark, and the paper's recipe at the same budget, on seeds that no run before them used. The
# ladder trains them (scripts/ladder.py train rows_plus|rows_paper SEED: resumable, snapshots) and keeps
# each run's best checkpoint by in-training validation; the study plays that one
ROW_BUDGET = RUNGS["rows_plus"].iterations  # 1,024 envs x 12 steps x 1,800 = 22.1 M env-steps
ROW_METHODS = {m: list(RUNGS[m].overrides) for m in ("rows_plus", "rows_paper")}  # the ladder's rungs
ROW_NAMES = {  # summary row -> its method
    f"LAS-MP+ ({CHOSEN_IN_A_ROW}), {ROW_BUDGET:,} it., seeds {ROW_SEEDS[0]}-{ROW_SEEDS[-1]}": "rows_plus",
    f"LAS-MP (paper's recipe), {ROW_BUDGET:,} it., seeds {ROW_SEEDS[0]}-{ROW_SEEDS[-1]}": "rows_paper",
}
LADDER = LADDER_RESULTS  # where the ladder collects a row's run
METHODS = PAPER_METHODS | PLUS_METHODS | ROW_METHODS
MIRROR_EPISODES = 1024  # LAS-MP+'s runs are also played with their mirror twins on this many
LEARNER = "algo.precision=bfloat16"  # the study's one learner (the docstring)
FLOAT32_LEARNER = "float32_learner"  # under RESULTS: LAS-MP's runs under float32, before the pin
# their rows: name -> (method, iterations, seeds); seed 2 ran float32 to 244 and bfloat16 after: no row
FLOAT32_ROWS = {
    "LAS-MP, float32 learner": ("lasmp", BUDGET, (0, 1)),
    "LAS-MP (1,000 it.), float32 learner": ("lasmp", HEADLINE, (0,)),
}
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


def run_dir(method: str, seed: int) -> Path:
    return RUNS / method / f"seed{seed}"


def last_iteration(d: Path) -> int:
    """The last completed iteration saved in run directory d (-1 if none)."""
    its = [int(m.group(1)) for p in d.glob("model_*.pt") if (m := re.fullmatch(r"model_(\d+)\.pt", p.name))]
    return max(its, default=-1)


def saved_at(d: Path, it: int, method: str | None = None) -> Path:
    """The checkpoint of iteration `it` in run directory d: its full model_<it>.pt, or the policy_<it>.pt
    that `runner.keep_full` turns an older save into once the run goes on (a missing one: the full name);
    a row's (ROW_METHODS), the best policy by validation that the ladder collected."""
    if method in ROW_METHODS:
        return LADDER / method / d.name / "policy_best.pt"
    full, policy = d / f"model_{it}.pt", d / f"policy_{it}.pt"
    return policy if not full.exists() and policy.exists() else full


def budget(method: str) -> int:
    """The iterations a method's runs train for: LAS-MP+'s (and its ablations') own, the new rows'
    ROW_BUDGET, the rest BUDGET."""
    return ROW_BUDGET if method in ROW_METHODS else PLUS_BUDGET if method in PLUS_METHODS else BUDGET


def result_dir(
    method: str, seed: int, at: int, controller: str | None = None, root: Path | None = None
) -> Path:
    name = controller or method
    plain = ROW_BUDGET if method in ROW_METHODS else BUDGET  # the budget a directory's name leaves unsaid
    return (root or RESULTS) / (name if at == plain else f"{name}@{at}") / f"seed{seed}"


def controllers(method: str) -> list[str | None]:
    return ["rs", "rs_oracle"] if method == "rs" else [None]


def evaluations(method: str, seed: int, at: int) -> list[tuple[Path, list[str]]]:
    """A run's evaluations, (out, evaluate.py's options): all of Xi_eval per controller, and for
    LAS-MP+'s runs the first MIRROR_EPISODES with their mirror twins (in the run's result, mirror/)."""
    runs = [(result_dir(method, seed, at, c), ["--controller", c] if c else []) for c in controllers(method)]
    if method in PLUS_METHODS or method in ROW_METHODS:
        n = str(MIRROR_EPISODES)
        runs.append((result_dir(method, seed, at) / "mirror", ["--num-trajectories", n, "--mirror", n]))
    return runs


def committed_policy(method: str, seed: int, at: int) -> Path:
    """The policy checkpoint `record_run` committed beside the run's evaluation once it had trained to
    'at' iterations: it outlives the machine, runs/ does not."""
    if method in ROW_METHODS:
        return saved_at(run_dir(method, seed), at - 1, method)
    return result_dir(method, seed, at) / f"policy_{at - 1}.pt"


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
    # last, the new rows, seed by seed (the ladder trains them)
    for seed in ROW_SEEDS:
        for method in ROW_METHODS:
            yield "evaluate", method, seed, ROW_BUDGET


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
    rows |= {name: [result_dir(m, s, ROW_BUDGET) for s in ROW_SEEDS] for name, m in ROW_NAMES.items()}
    for name, (m, at, seeds) in FLOAT32_ROWS.items():
        rows[name] = [result_dir(m, s, at, root=RESULTS / FLOAT32_LEARNER) for s in seeds]
    args = []
    for name, dirs in rows.items():
        done = [str(d.relative_to(ROOT)) for d in dirs if (d / "metrics.json").exists()]
        if done:
            args += ["--method", name, *done]
    return args + ["--method", "Stand Still", str(STAND_STILL.relative_to(ROOT))]
