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
    python scripts/study.py paired                    # the new rows seed by seed: LAS-MP+ minus the paper's recipe
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
that choice. Then the new rows: LAS-MP+ at the recipe and budget chosen on the validation benchmark,
and the paper's recipe at the same budget, on seeds 20-22, which the ladder trains
(`scripts/ladder.py train rows_plus|rows_paper SEED`, then `collect`); the study plays each run's best
checkpoint by validation on all of Xi_eval and with the mirror twins (results/study/rows_*/seed<k>/).

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

from studylib import plan
from studylib.plan import FRESH_SEEDS, METHODS, ROW_SEEDS, SEEDS, is_done, steps, summary_args
from studylib.runs import evaluate, train
from studylib.tables import compare, headline, ordering, paired, table, write_tables

from lasmp.io.inputs import InputError, int_arg


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
    sub.add_parser("paired", help="the new rows seed by seed: LAS-MP+ minus the paper's recipe")
    sub.add_parser("tables", help="rewrite README.md's and docs/results.md's tables from summary.json")
    sub.add_parser("summary").add_argument(
        "--paper-columns", action="store_true", help="print only the paper's five metrics"
    )
    for name in ("train", "evaluate"):
        s = sub.add_parser(name)
        s.add_argument("method", choices=sorted(METHODS))
        s.add_argument("seed", type=int, choices=SEEDS + FRESH_SEEDS + ROW_SEEDS)
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
    elif args.cmd == "paired":
        print(paired())
    elif args.cmd == "tables":
        write_tables()
    elif args.cmd == "summary":
        from lasmp.eval import results_table

        columns = ["--paper-columns"] if args.paper_columns else []
        raise SystemExit(
            # the study's own summary.json, rewritten from its results each time: --force
            results_table.main(
                [*summary_args(), "--json", str(plan.RESULTS / "summary.json"), "--force", *columns]
            )
        )
    elif args.cmd == "train":
        train(args.method, args.seed, args.n)
    else:
        evaluate(args.method, args.seed, args.n)


if __name__ == "__main__":
    main()
