"""scripts/study.py's steps on a constructed runs/ and results/ tree: their order, what counts as
done, and the train.py and evaluate.py commands each step runs."""

from __future__ import annotations

import pytest
from testkit import mark_evaluated as evaluated


def trained(study, method, seed, iterations):
    d = study.run_dir(method, seed)
    d.mkdir(parents=True, exist_ok=True)
    (d / f"model_{iterations - 1}.pt").write_bytes(b"")


def test_the_study_runs_las_mp_s_three_seeds_then_the_shipped_policy_then_the_rest(study):
    order = [(m, s, n) for kind, m, s, n in study.steps() if kind == "train"]
    assert order[:5] == [
        ("lasmp", 0, 450),
        ("lasmp", 1, 450),
        ("lasmp", 2, 450),
        ("lasmp", 0, 1000),
        ("lasmp_centre", 0, 450),
    ]
    paper = order[: 3 * 7 + 3]
    assert paper[-2:] == [("lasmp", 1, 1000), ("lasmp", 2, 1000)]
    assert "lasmp_float32" not in {m for m, _, _ in order}  # the first pass's check, not rerun
    # then LAS-MP+'s three seeds and its four ablations, seed by seed, at the one budget
    plus = order[3 * 7 + 3 :]
    assert plus[:4] == [("lasmp_plus", 0, 450), ("lasmp_plus", 1, 450), ("lasmp_plus", 2, 450)] + [
        ("plus_no_alignment_command", 0, 450)
    ]
    assert len(plus) == 3 * 5 + 3 and {m for m, _, _ in plus} == set(study.PLUS_METHODS)
    # last, LAS-MP+ on the three seeds no screening run saw
    assert plus[-3:] == [("lasmp_plus", 3, 450), ("lasmp_plus", 4, 450), ("lasmp_plus", 5, 450)]


def test_the_papers_runs_train_under_its_recipe_and_las_mp_plus_s_under_the_default_one_explicitly(study):
    study.train("no_alignment_command", 0)
    study.train("plus_no_alignment_command", 0)
    study.train("rs", 0)
    paper, plus, rs = study.ran
    assert "recipe=paper" in paper and "policy=no_alignment_command" in paper
    assert "recipe=lasmp_plus" in plus and "policy=no_alignment_command" in plus
    assert not any(a.startswith("recipe=") for a in rs)  # the rough-terrain task takes none


def test_las_mp_plus_runs_are_also_played_with_their_mirror_twins_and_done_only_then(study):
    trained(study, "lasmp_plus", 0, 450)
    study.evaluate("lasmp_plus", 0)
    full, mirror = study.ran
    assert "--mirror" not in full and full[full.index("--out") + 1] == "results/study/lasmp_plus/seed0"
    assert mirror[mirror.index("--mirror") + 1] == mirror[mirror.index("--num-trajectories") + 1] == "1024"
    assert mirror[mirror.index("--out") + 1] == "results/study/lasmp_plus/seed0/mirror"
    evaluated(study.result_dir("lasmp_plus", 0, 450))
    assert not study.is_done("evaluate", "lasmp_plus", 0, 450)
    evaluated(study.result_dir("lasmp_plus", 0, 450) / "mirror")
    assert study.is_done("evaluate", "lasmp_plus", 0, 450) and study.is_done("train", "lasmp_plus", 0, 450)


def test_next_trains_the_first_unfinished_run_and_resumes_it_where_it_stopped(study):
    trained(study, "lasmp", 0, 450)
    evaluated(study.result_dir("lasmp", 0, 450))
    trained(study, "lasmp", 0, 700)  # on its way to 1,000 iterations
    for seed in (1, 2):
        trained(study, "lasmp", seed, 450)
        evaluated(study.result_dir("lasmp", seed, 450))
    study.main(["next"])
    cmd = study.ran[-1]
    assert cmd[0] == "train.py" and "seed=0" in cmd
    assert "resume=runs/study/lasmp/seed0" in cmd and "runner.max_iterations=300" in cmd


def test_on_a_fresh_machine_evaluated_runs_are_skipped_and_a_continuation_retrains_from_the_start(study):
    for s in (0, 1):  # committed results, no runs/: a new machine
        evaluated(study.result_dir("lasmp", s, 450))
    evaluated(study.result_dir("lasmp", 0, 1000))
    assert study.is_done("train", "lasmp", 1, 450) and not study.is_done("train", "lasmp", 1, 1000)
    study.main(["next"])
    assert "seed=2" in study.ran[-1] and "runner.max_iterations=450" in study.ran[-1]
    study.train("lasmp", 1, 1000)
    assert "runner.max_iterations=1000" in study.ran[-1]
    assert not any(a.startswith("resume=") for a in study.ran[-1])


def test_on_a_fresh_machine_a_run_with_a_committed_policy_is_evaluated_from_it_not_retrained(study):
    for _, method, seed, at in study.steps():  # every run before LAS-MP+ seed 2 is evaluated
        if (method, seed) == ("lasmp_plus", 2):
            break
        for out, _ in study.evaluations(method, seed, at):
            evaluated(out)
    policy = study.result_dir("lasmp_plus", 2, 450) / "policy_449.pt"  # trained, then the machine went
    policy.parent.mkdir(parents=True)
    policy.write_bytes(b"")
    assert study.is_done("train", "lasmp_plus", 2, 450) and not study.is_done(
        "evaluate", "lasmp_plus", 2, 450
    )
    study.main(["next"])
    cmd = study.ran[-1]
    assert (
        cmd[0] == "evaluate.py"
        and cmd[cmd.index("--checkpoint") + 1] == "results/study/lasmp_plus/seed2/policy_449.pt"
    )
    trained(study, "lasmp_plus", 2, 450)  # the run's own checkpoint, where the machine kept it, comes first
    study.evaluate("lasmp_plus", 2)
    assert (
        study.ran[-1][study.ran[-1].index("--checkpoint") + 1] == "runs/study/lasmp_plus/seed2/model_449.pt"
    )


def test_las_mp_plus_and_its_ablations_train_to_their_own_budget_resuming_a_shorter_run(study, monkeypatch):
    monkeypatch.setattr(study.plan, "PLUS_BUDGET", 1000)
    plus = [(m, s, n) for kind, m, s, n in study.steps() if kind == "train" and m in study.PLUS_METHODS]
    assert len(plus) == 15 + 3 and {n for _, _, n in plus} == {1000}
    assert ("lasmp", 0, 450) in [(m, s, n) for _, m, s, n in study.steps()]  # the paper's runs keep theirs
    trained(study, "lasmp_plus", 0, 450)
    study.main(["train", "lasmp_plus", "0"])
    assert (
        "resume=runs/study/lasmp_plus/seed0" in study.ran[-1] and "runner.max_iterations=550" in study.ran[-1]
    )
    study.main(["train", "plus_no_explicit_estimator", "1"])
    assert "runner.max_iterations=1000" in study.ran[-1]
    trained(study, "lasmp_plus", 0, 1000)
    study.main(["evaluate", "lasmp_plus", "0"])
    cmd = study.ran[-1]
    assert cmd[cmd.index("--checkpoint") + 1] == "runs/study/lasmp_plus/seed0/model_999.pt"
    assert cmd[cmd.index("--out") + 1].startswith("results/study/lasmp_plus@1000/seed0")


def test_a_method_trains_with_its_overrides_and_is_evaluated_on_all_of_xi_eval(study):
    study.train("no_alignment_command", 1)
    assert "policy=no_alignment_command" in study.ran[-1] and "runner.max_iterations=450" in study.ran[-1]
    trained(study, "no_alignment_command", 1, 450)
    study.evaluate("no_alignment_command", 1)
    cmd = study.ran[-1]
    assert "--num-trajectories" not in cmd
    assert cmd[cmd.index("--out") + 1] == "results/study/no_alignment_command/seed1"
    with pytest.raises(SystemExit, match="model_449.pt does not exist"):
        study.evaluate("lasmp", 2)
    with pytest.raises(SystemExit):
        study.main(["train", "lasmp_float32", "0"])


def test_every_run_trains_with_the_bfloat16_learner_and_a_cpu_without_it_is_refused(study, monkeypatch):
    study.train("no_explicit_estimator", 2)
    assert "algo.precision=bfloat16" in study.ran[-1]
    study.real_check_learner("flags\t\t: fpu sse avx2 avx512f avx512_bf16\n")  # AVX-512 BF16: no error
    with pytest.raises(SystemExit, match="lacks AVX-512 BF16/AMX"):
        study.real_check_learner("flags\t\t: fpu sse avx2 fma\n")
    from lasmp.algo import precision

    monkeypatch.setattr(precision, "cpu_has_fast_bf16", lambda cpuinfo=None: False)
    monkeypatch.setattr(study.runs, "check_learner", study.real_check_learner)
    with pytest.raises(SystemExit, match="20 times slower"):
        study.train("rs", 1)
    assert len(study.ran) == 1  # refused before it ran


def test_rs_is_evaluated_twice_and_counts_as_done_only_with_both_controllers(study):
    trained(study, "rs", 0, 450)
    study.evaluate("rs", 0)
    controllers = [c[c.index("--controller") + 1] for c in study.ran]
    assert controllers == ["rs", "rs_oracle"]
    evaluated(study.result_dir("rs", 0, 450, "rs"))
    assert not study.is_done("evaluate", "rs", 0, 450)
    evaluated(study.result_dir("rs", 0, 450, "rs_oracle"))
    assert study.is_done("evaluate", "rs", 0, 450)


def test_las_mp_plus_on_the_seeds_no_screening_run_saw_is_a_row_of_its_own_trained_and_mirrored_alike(
    study,
):
    for s in (0, 1, 2, 3, 4):
        evaluated(study.result_dir("lasmp_plus", s, 450))
    args = study.summary_args()
    assert args[: args.index("--method", 1)] == [
        "--method", "LAS-MP+", *(f"results/study/lasmp_plus/seed{s}" for s in (0, 1, 2)),
    ]  # fmt: skip
    fresh = args.index(study.FRESH_ROW)
    assert args[fresh + 1 : fresh + 3] == ["results/study/lasmp_plus/seed3", "results/study/lasmp_plus/seed4"]
    assert args[fresh + 3] == "--method"  # seed 5 is not evaluated yet
    study.main(["train", "lasmp_plus", "5"])
    assert "recipe=lasmp_plus" in study.ran[-1] and "seed=5" in study.ran[-1]
    trained(study, "lasmp_plus", 5, 450)
    study.main(["evaluate", "lasmp_plus", "5"])
    assert study.ran[-1][study.ran[-1].index("--out") + 1] == "results/study/lasmp_plus/seed5/mirror"
    with pytest.raises(SystemExit):
        study.main(["train", "lasmp_plus", "6"])  # no such seed in the study


def test_a_saved_iteration_is_its_full_checkpoint_or_the_policy_checkpoint_keep_full_turned_it_into(
    study, tmp_path
):
    run = tmp_path / "run"
    run.mkdir()
    assert study.saved_at(run, 449) == run / "model_449.pt"  # neither: the name a message gives
    (run / "policy_449.pt").write_bytes(b"")
    assert study.saved_at(run, 449) == run / "policy_449.pt"
    (run / "model_449.pt").write_bytes(b"")
    assert study.saved_at(run, 449) == run / "model_449.pt"


def test_the_new_rows_are_the_ladders_runs_played_at_their_best_checkpoint_by_validation_with_mirror_twins(
    study,
):
    assert [(k, m, s) for k, m, s, _ in study.steps()][-6:] == [
        ("evaluate", m, s) for s in (20, 21, 22) for m in ("rows_plus", "rows_paper")
    ]
    assert study.ROW_METHODS["rows_paper"] == ["recipe=paper", "runner.validation_episodes=1024"]
    with pytest.raises(
        SystemExit, match="the ladder trains the new rows: python scripts/ladder.py train rows_plus 20"
    ):
        study.train("rows_plus", 20)
    with pytest.raises(SystemExit, match="scripts/ladder.py train rows_paper 21, then collect it"):
        study.evaluate("rows_paper", 21)
    best = study.plan.LADDER / "rows_paper" / "seed21" / "policy_best.pt"  # what the ladder collects
    best.parent.mkdir(parents=True)
    best.write_bytes(b"")
    study.evaluate("rows_paper", 21)
    full, mirror = study.ran
    assert full[full.index("--checkpoint") + 1] == "results/ladder/rows_paper/seed21/policy_best.pt"
    assert full[full.index("--out") + 1] == "results/study/rows_paper/seed21" and "--mirror" not in full
    assert mirror[mirror.index("--out") + 1] == "results/study/rows_paper/seed21/mirror"
    evaluated(study.result_dir("rows_paper", 21, study.ROW_BUDGET))
    evaluated(study.result_dir("rows_paper", 21, study.ROW_BUDGET) / "mirror")
    assert study.is_done("evaluate", "rows_paper", 21, 1800)
    args = study.summary_args()
    assert args[args.index("LAS-MP (paper's recipe), 1,800 it., seeds 20-22") + 1] == (
        "results/study/rows_paper/seed21"
    )
