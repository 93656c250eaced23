"""scripts/study.py: the order of the study's steps, what counts as done, the commands it runs, and
the rows it hands to the results table, on a constructed runs/ and results/ tree."""

from __future__ import annotations

import json
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from testkit import load_script

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def study(tmp_path, monkeypatch):
    mod = load_script("scripts/study.py")
    monkeypatch.setattr(mod, "ROOT", tmp_path)
    monkeypatch.setattr(mod, "RUNS", tmp_path / "runs" / "study")
    monkeypatch.setattr(mod, "RESULTS", tmp_path / "results" / "study")
    monkeypatch.setattr(mod, "FIRST_PASS", tmp_path / "results" / "study" / "entropy_0.01")
    monkeypatch.setattr(mod, "STAND_STILL", tmp_path / "results" / "study" / "stand_still" / "seed0")
    ran = []
    mod.real_execute = mod.execute
    monkeypatch.setattr(mod, "execute", lambda cmd, log: ran.append(cmd[1:]))
    monkeypatch.setattr(mod, "record_run", lambda *a: None)
    mod.real_check_learner = mod.check_learner
    monkeypatch.setattr(mod, "check_learner", lambda cpuinfo=None: None)  # CI's CPU may lack bfloat16
    mod.ran = ran
    return mod


def trained(study, method, seed, iterations):
    d = study.run_dir(method, seed)
    d.mkdir(parents=True, exist_ok=True)
    (d / f"model_{iterations - 1}.pt").write_bytes(b"")


def evaluated(d: Path):
    d.mkdir(parents=True, exist_ok=True)
    (d / "metrics.json").write_text("{}")


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
    monkeypatch.setattr(study, "PLUS_BUDGET", 1000)
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
    monkeypatch.setattr(study, "check_learner", study.real_check_learner)
    with pytest.raises(SystemExit, match="20 times slower"):
        study.train("rs", 1)
    assert len(study.ran) == 1  # refused before it ran


def test_each_command_is_logged_with_its_time_and_commit_before_it_runs(study, tmp_path):
    log = tmp_path / "runs" / "study" / "lasmp" / "seed0.commands"
    cmd = [sys.executable, "-c", "open('ran', 'w')"]
    study.real_execute(cmd, log)
    header, command = log.read_text().splitlines()
    assert header.startswith("# 20") and header.endswith(", at no commit, nice -n 10")  # tmp_path: no git
    assert shlex.split(command) == cmd
    assert (tmp_path / "ran").exists()  # it ran, in ROOT
    mirror = tmp_path / "results" / "study" / "lasmp" / "seed0.commands"
    assert mirror.read_text() == log.read_text()  # committed beside the results, once it succeeded
    with pytest.raises(SystemExit) as stop:  # the command's own status, not a CalledProcessError
        study.real_execute([sys.executable, "-c", "raise SystemExit(3)"], log)
    assert stop.value.code == 3
    assert len(log.read_text().splitlines()) == 4 and len(mirror.read_text().splitlines()) == 2


def test_a_failed_training_ends_the_study_with_its_status_and_is_not_added_to_the_committed_commands(
    study, monkeypatch, tmp_path
):
    """The committed .commands file says how the committed results were made: a training that failed
    made none. The uncommitted log beside the run keeps it, with every command tried."""
    monkeypatch.setattr(study, "execute", study.real_execute)
    (tmp_path / "train.py").write_text("raise SystemExit(2)  # as train.py refusing its configuration\n")
    committed = tmp_path / "results" / "study" / "lasmp" / "seed0.commands"
    committed.parent.mkdir(parents=True)
    committed.write_text("# an earlier sitting\ntrain.py seed=0\n")
    with pytest.raises(SystemExit) as stop:
        study.main(["train", "lasmp", "0"])
    assert stop.value.code == 2
    assert committed.read_text() == "# an earlier sitting\ntrain.py seed=0\n"
    tried = (tmp_path / "runs" / "study" / "lasmp" / "seed0.commands").read_text().splitlines()
    assert len(tried) == 2 and "train.py" in tried[1] and "seed=0" in tried[1]


# train.py as it meets a Ctrl-C: the terminal signals its whole foreground process group (this, and the
# study waiting for it); the training saves a checkpoint, which takes a moment, and exits 130
INTERRUPTED_TRAINING = """
import os, signal, time
try:
    os.killpg(0, signal.SIGINT)
    time.sleep(10)
except KeyboardInterrupt:
    time.sleep(0.5)
    open("saved", "w").close()
    print("interrupted: saved model_3.pt", flush=True)
    raise SystemExit(130)
"""


def test_a_ctrl_c_during_training_waits_for_its_save_and_ends_the_study_with_its_status_and_no_traceback(
    tmp_path,
):
    """Python's subprocess.run kills the child a quarter of a second after the parent's interrupt and
    then raises it: the save cut short, a traceback after the training's own last line."""
    (tmp_path / "train.py").write_text(INTERRUPTED_TRAINING)
    study = (
        "import importlib.util, sys\n"
        "from pathlib import Path\n"
        f"spec = importlib.util.spec_from_file_location('study', {str(ROOT / 'scripts' / 'study.py')!r})\n"
        "study = importlib.util.module_from_spec(spec)\n"
        "spec.loader.exec_module(study)\n"
        f"study.ROOT = Path({str(tmp_path)!r})\n"
        "study.RUNS, study.RESULTS = study.ROOT / 'runs' / 'study', study.ROOT / 'results' / 'study'\n"
        "study.check_learner = lambda: None  # this CPU may lack bfloat16\n"
        "study.main(['train', 'lasmp', '0'])\n"
    )
    done = subprocess.run(  # a session of its own: the Ctrl-C reaches this one and its child, not pytest
        [sys.executable, "-c", study], capture_output=True, text=True, timeout=60, start_new_session=True
    )
    assert done.returncode == 130, done.stderr
    assert (tmp_path / "saved").exists() and done.stdout.endswith("interrupted: saved model_3.pt\n")
    assert "Traceback" not in done.stderr, done.stderr
    assert not (tmp_path / "results" / "study" / "lasmp" / "seed0.commands").exists()


def test_rs_is_evaluated_twice_and_counts_as_done_only_with_both_controllers(study):
    trained(study, "rs", 0, 450)
    study.evaluate("rs", 0)
    controllers = [c[c.index("--controller") + 1] for c in study.ran]
    assert controllers == ["rs", "rs_oracle"]
    evaluated(study.result_dir("rs", 0, 450, "rs"))
    assert not study.is_done("evaluate", "rs", 0, 450)
    evaluated(study.result_dir("rs", 0, 450, "rs_oracle"))
    assert study.is_done("evaluate", "rs", 0, 450)


def test_the_summary_lists_each_row_with_its_evaluated_seeds_and_leaves_out_the_first_pass(study):
    for s in (0, 2):
        evaluated(study.result_dir("lasmp", s, 450))
    evaluated(study.result_dir("lasmp", 0, 1000))
    evaluated(study.result_dir("lasmp", 1, 450, root=study.FIRST_PASS))
    evaluated(study.result_dir("rs", 1, 450, "rs_oracle"))
    for s in (0, 1, 2):  # seed 2 ran float32 and then bfloat16: in no row
        evaluated(study.result_dir("lasmp", s, 450, root=study.RESULTS / "float32_learner"))
    assert study.summary_args() == [
        "--method", "LAS-MP", "results/study/lasmp/seed0", "results/study/lasmp/seed2",
        "--method", "LAS-MP (1,000 it.)", "results/study/lasmp@1000/seed0",
        "--method", "R-S (oracle)", "results/study/rs_oracle/seed1",
        "--method", "LAS-MP, float32 learner",
        "results/study/float32_learner/lasmp/seed0", "results/study/float32_learner/lasmp/seed1",
        "--method", "Stand Still", "results/study/stand_still/seed0",
    ]  # fmt: skip


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


def _entry(study, seeds: list[str], collision: list[float], ci95: float | None = None) -> dict:
    """A summary row whose every metric holds the same values."""
    metric = {"mean": sum(collision) / len(collision), "ci95": ci95, "per_seed": collision}
    return {"seeds": seeds, "metrics": dict.fromkeys(study.WIDE_COLUMNS, metric)}


def test_the_table_gives_three_seeds_as_mean_and_interval_fewer_per_seed_and_r_s_beside_its_oracle(study):
    methods = {
        "Stand Still": _entry(study, ["results/study/stand_still/seed0"], [0.634]),
        "LAS-MP": _entry(
            study, [f"results/study/lasmp/seed{k}" for k in range(3)], [0.1, 0.2, 0.3], ci95=0.248
        ),
        "R-S": _entry(study, ["results/study/rs/seed0", "results/study/rs/seed2"], [0.16, 0.2]),
        "R-S (oracle)": _entry(
            study, ["results/study/rs_oracle/seed0", "results/study/rs_oracle/seed2"], [0.14, 0.5]
        ),
    }
    path = study.RESULTS / "summary.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"methods": methods}))
    rows = study.table(path).splitlines()
    assert rows[0].startswith("| method | seeds | collision rate |") and len(rows) == 2 + 3
    assert rows[2].startswith("| Stand Still (a = 0) | – | 0.634 |")
    assert rows[3].startswith("| LAS-MP, 450 iterations | 3 | 0.200 ± 0.248 |") and rows[3].endswith(
        "| 0.20 ± 0.25 |"
    )  # power to two places
    assert rows[4].startswith("| R-S (its estimates; the true x_exp) | 0, 2 | 0.160 / 0.200; 0.140 / 0.500 |")
    wide = study.table(path, wide=True).splitlines()  # every summary row on its own, every metric
    assert len(wide) == 2 + 4 and wide[0].endswith("| rotation (rad, rel. to platform) | learner per seed |")
    assert wide[3].startswith("| LAS-MP | 0, 1, 2 | 0.200 ± 0.248 |") and wide[3].endswith(
        "| 0.200 ± 0.248 | – |"
    )
    assert wide[5].startswith("| R-S (oracle) | 0, 2 | 0.140 / 0.500 |")


def curves(study, method, seed, level_up_at):
    """A learning curve whose success climbs to 0.9 and whose level leaves 5 at `level_up_at`."""
    windows = [
        {
            "iterations": [lo, lo + 9],
            "Episode/success_rate": min(0.9, lo / 200),
            "Curriculum/level": 5.0 if lo < level_up_at else 6.0,
        }
        for lo in range(0, 450, 10)
    ]
    d = study.result_dir(method, seed, 450, root=study.FIRST_PASS)
    d.mkdir(parents=True, exist_ok=True)
    (d / "curves_450.json").write_text(json.dumps({"windows": windows}))


def test_compare_tabulates_both_learners_of_the_first_pass_per_seed_from_their_curves_and_first_episodes(
    study, monkeypatch
):
    from lasmp.eval import episodes as ep

    monkeypatch.setattr(study, "FLOAT32_EPISODES", 20)

    def evaluated_episodes(method, seed, collided_first_20):
        t = {c: np.zeros(24) for c in ep.COLUMNS}
        t["episode"] = np.arange(24)
        t["collision_cause"] = np.array([""] * 24, dtype=object)
        t["collided"] = np.r_[np.arange(20) < collided_first_20, np.ones(4)].astype(
            float
        )  # 20-23 not counted
        d = study.result_dir(method, seed, 450, root=study.FIRST_PASS)
        ep.write_csv(d / "episodes.csv", t)
        evaluated(d)

    for seed in (0, 1):
        curves(study, "lasmp", seed, 200 + 10 * seed)
        curves(study, "lasmp_float32", seed, 300)
        evaluated_episodes("lasmp", seed, 5 + 5 * seed)  # an evaluation of more than the first 20
    evaluated_episodes("lasmp_float32", 0, 6)
    table = study.compare().splitlines()
    assert table[0] == "| iterations | fast, seed 0 | fast, seed 1 | float32, seed 0 | float32, seed 1 |"
    assert table[2] == "| 0-49 | 0.10 (level 5) | 0.10 (level 5) | 0.10 (level 5) | 0.10 (level 5) |"
    assert table[6] == "| 200-249 | 0.90 (level 6) | 0.90 (level 6) | 0.90 (level 5) | 0.90 (level 5) |"
    assert table[-2] == "| first window above level 5 | 200 | 210 | 300 | 300 |"
    assert table[-1] == "| collision, Xi_eval's first 20 | 0.250 | 0.500 | 0.300 | not evaluated |"


def test_compare_says_how_to_regenerate_an_evaluated_runs_missing_records(study):
    for seed in (0, 1):
        curves(study, "lasmp", seed, 200)
        curves(study, "lasmp_float32", seed, 300)
    d = study.result_dir("lasmp", 0, 450, root=study.FIRST_PASS)
    evaluated(d)  # its metrics.json, not its per-episode records
    with pytest.raises(SystemExit) as stop:
        study.main(["compare"])
    assert str(stop.value) == (
        f"error: {d / 'episodes.csv.gz'}: no such file; per-episode records are derived data: regenerate "
        f"them with `python -m lasmp.eval.regenerate {d}` (or evaluate.py writes them beside metrics.json)"
    )


def test_compare_names_the_missing_run(study):
    curves(study, "lasmp", 0, 200)
    curves(study, "lasmp", 1, 200)
    evaluated(study.result_dir("lasmp_float32", 0, 450))  # a current-pass directory is not the first pass's
    with pytest.raises(SystemExit, match="entropy_0.01/lasmp_float32/seed0/curves_450.json does not exist"):
        study.compare()


def test_a_truncated_summary_is_named_in_one_line(study, capsys):
    path = study.RESULTS / "summary.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"methods": {"LAS-MP": {"seeds": ["a", "b", "c"]}}})[:-7])  # a copy cut short
    for command in (["table"], ["table", "--headline"], ["ordering"]):
        with pytest.raises(SystemExit) as stop:
            study.main(command)
        assert str(stop.value) == f"error: {path}: truncated: the file ends before its JSON does"
    path.unlink()
    with pytest.raises(
        SystemExit, match="summary.json: no such file; write it with `python scripts/study.py"
    ):
        study.main(["table"])


def test_the_table_with_paper_puts_every_row_of_the_papers_table_ii_below_ours_marked_as_the_papers(study):
    from lasmp.eval.paper import PAPER_ROWS

    methods = {"Stand Still": _entry(study, ["results/study/stand_still/seed0"], [0.634])}
    path = study.RESULTS / "summary.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"methods": methods}))
    assert not any(r.startswith("| paper:") for r in study.table(path).splitlines())
    for wide in (False, True):
        rows = study.table(path, wide=wide, paper=True).splitlines()
        paper = [r for r in rows if r.startswith("| paper:")]
        assert len(paper) == len(PAPER_ROWS) and rows[-len(paper) :] == paper
        assert paper[0] == (
            "| paper: LAS-MP | – | 0.029 ± 0.03 | 0.009 ± 0.01 | 0.366 ± 0.01 | 0.071 ± 0.01 | 2.904 ± 0.45 |"
            + ("  |  |  |" if wide else "")
        )
        assert {r.count("|") for r in rows} == {rows[0].count("|")}  # every row as wide as the header


def test_the_headline_puts_each_of_our_rows_beside_the_papers_row_it_reproduces_metric_by_metric(study):
    plus = [f"results/study/lasmp_plus/seed{k}" for k in range(3)]
    methods = {
        "Stand Still": _entry(study, ["results/study/stand_still/seed0"], [0.634]),
        "LAS-MP+": _entry(study, plus, [0.036, 0.069, 0.054], ci95=0.04),
        study.FRESH_ROW: _entry(
            study, [f"results/study/lasmp_plus/seed{k}" for k in (3, 4, 5)], [0.1] * 3, 0.02
        ),
    }
    path = study.RESULTS / "summary.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"methods": methods}))
    rows = study.headline(path).splitlines()
    assert rows[0].startswith("| ours, vs the paper's row | collision rate: ours | paper | height-violation")
    assert len(rows) == 2 + 3 <= 2 + 8  # the paper's recipe and R-S not evaluated: left out
    shipped, fresh, still = rows[2:]
    # the shipped policy is seed 0's own value, not the mean over seeds; each metric beside the paper's
    assert shipped.startswith("| the shipped policy: LAS-MP+ seed 0, 450 iterations, vs the paper's LAS-MP |")
    assert shipped.split(" | ")[1:3] == ["0.036", "0.029 ± 0.03"]
    assert fresh.split(" | ")[1:3] == ["0.100 ± 0.020", "0.029 ± 0.03"] and "fresh seeds 3-5" in fresh
    assert still.split(" | ")[1:3] == ["0.634", "0.612 ± 0.29"]
    assert {r.count("|") for r in rows} == {rows[0].count("|")}


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


def test_tables_rewrites_each_documents_table_in_place_and_refuses_a_document_without_one(study):
    path = study.RESULTS / "summary.json"
    path.parent.mkdir(parents=True)
    path.write_text(
        json.dumps({"methods": {"Stand Still": _entry(study, ["results/study/stand_still/seed0"], [0.5])}})
    )
    old = study.headline(path).replace("0.500", "0.999")
    old_wide = study.table(path, wide=True, paper=True).replace("0.500", "0.999")
    (study.ROOT / "docs").mkdir()
    (study.ROOT / "README.md").write_text(f"# intro\n\n{old}\n\nafter the table\n")
    (study.ROOT / "docs" / "results.md").write_text(f"text\n{old_wide}")  # a table ending the file
    study.write_tables(path)
    readme = (study.ROOT / "README.md").read_text()
    assert readme == f"# intro\n\n{study.headline(path)}\n\nafter the table\n" and "0.500" in readme
    assert (
        study.ROOT / "docs" / "results.md"
    ).read_text() == f"text\n{study.table(path, wide=True, paper=True)}"
    (study.ROOT / "README.md").write_text("# no table here\n")
    with pytest.raises(ValueError, match="no table with the header"):
        study.write_tables(path)


def test_ordering_calls_two_rows_ordered_only_when_their_three_seed_intervals_are_apart(study):
    three = [f"s/seed{k}" for k in range(3)]
    methods = {
        "LAS-MP+": _entry(study, three, [0.04, 0.05, 0.06], ci95=0.02),  # 0.03-0.07
        "LAS-MP+ w/o alignment command": _entry(study, three, [0.09, 0.10, 0.11], ci95=0.02),  # above
        "LAS-MP+ w/o platform velocity estimates": _entry(study, three, [0.07, 0.08, 0.09], ci95=0.02),
        "LAS-MP+ w/o explicit estimator": _entry(study, three, [0.0, 0.01, 0.02], ci95=0.015),  # below
        "LAS-MP+ w/o explicit estimator, with the history": _entry(study, three[:2], [0.3, 0.4]),
    }
    path = study.RESULTS / "summary.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"methods": methods}))
    rows = study.ordering(path).splitlines()[2:]
    assert [r.split(" | ")[1:4] for r in rows] == [
        ["w/o alignment command", "3", "above"],
        ["w/o platform velocity estimates", "3", "overlap"],  # 0.06-0.10 touches 0.03-0.07
        ["w/o explicit estimator", "3", "below"],
        ["w/o explicit estimator, with the history", "2", "–"],  # two seeds order nothing
    ]
    # against LAS-MP+ on the fresh seeds too, once that row is in the summary
    methods[study.FRESH_ROW] = _entry(study, [f"s/seed{k}" for k in (3, 4, 5)], [0.1, 0.11, 0.12], ci95=0.01)
    path.write_text(json.dumps({"methods": methods}))
    fresh = [r.split(" | ")[1:4] for r in study.ordering(path).splitlines()[2:] if study.FRESH_ROW in r]
    assert fresh[:3] == [
        ["w/o alignment command", "3", "overlap"],  # 0.08-0.12 against 0.10-0.12
        ["w/o platform velocity estimates", "3", "overlap"],  # 0.06-0.10 touches 0.10-0.12
        ["w/o explicit estimator", "3", "below"],
    ]


def test_a_recorded_run_keeps_its_policy_in_the_light_form_beside_its_config_and_learning_curve(
    tmp_path, monkeypatch
):
    from testkit import tiny

    from lasmp.algo.checkpoint import read_checkpoint
    from lasmp.light_checkpoint import LIGHT_KIND
    from lasmp.train import train

    mod = load_script("scripts/study.py")
    monkeypatch.setattr(mod, "ROOT", tmp_path)
    monkeypatch.setattr(mod, "RUNS", tmp_path / "runs" / "study")
    monkeypatch.setattr(mod, "RESULTS", tmp_path / "results" / "study")
    train(tiny(mod.run_dir("lasmp_plus", 0), plain=True))  # 2 iterations: model_1.pt
    mod.record_run("lasmp_plus", 0, 2)
    out = mod.result_dir("lasmp_plus", 0, 2)
    policy = read_checkpoint(out / "policy_1.pt")
    full = read_checkpoint(mod.run_dir("lasmp_plus", 0) / "model_1.pt")
    assert policy["kind"] == LIGHT_KIND and policy["critic_state_dict"] == {}
    assert all(torch.equal(policy["actor_state_dict"][k], v) for k, v in full["actor_state_dict"].items())
    assert {p.name for p in out.iterdir()} == {"config.yaml", "policy_1.pt", "curves_2.json"}
