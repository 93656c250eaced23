"""scripts/study.py: the order of the study's steps, what counts as done, the commands it runs, and
the rows it hands to the results table, on a constructed runs/ and results/ tree."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def study(tmp_path, monkeypatch):
    spec = importlib.util.spec_from_file_location("study_script", ROOT / "scripts" / "study.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    monkeypatch.setattr(mod, "ROOT", tmp_path)
    monkeypatch.setattr(mod, "RUNS", tmp_path / "runs" / "study")
    monkeypatch.setattr(mod, "RESULTS", tmp_path / "results" / "study")
    monkeypatch.setattr(mod, "STAND_STILL", tmp_path / "results" / "study" / "stand_still" / "seed0")
    ran = []
    monkeypatch.setattr(mod, "execute", lambda cmd, log: ran.append(cmd[1:]))
    monkeypatch.setattr(mod, "record_run", lambda *a: None)
    mod.ran = ran
    return mod


def trained(study, method, seed, iterations):
    d = study.run_dir(method, seed)
    d.mkdir(parents=True, exist_ok=True)
    (d / f"model_{iterations - 1}.pt").write_bytes(b"")


def evaluated(d: Path):
    d.mkdir(parents=True, exist_ok=True)
    (d / "metrics.json").write_text("{}")


def test_the_study_runs_las_mp_seeds_then_the_float32_comparison_then_the_rest_then_the_headline(study):
    order = [(m, s, n) for kind, m, s, n in study.steps() if kind == "train"]
    assert order[:5] == [
        ("lasmp", 0, 450),
        ("lasmp", 1, 450),
        ("lasmp", 2, 450),
        ("lasmp_float32", 0, 450),
        ("lasmp_float32", 1, 450),
    ]
    assert order[-3:] == [("lasmp", 0, 1000), ("lasmp", 1, 1000), ("lasmp", 2, 1000)]
    assert len(order) == 3 * 7 + 2 + 3


def test_next_trains_the_first_unfinished_run_and_resumes_it_where_it_stopped(study):
    trained(study, "lasmp", 0, 450)
    evaluated(study.result_dir("lasmp", 0, 450))
    trained(study, "lasmp", 1, 200)
    study.main(["next"])
    cmd = study.ran[-1]
    assert cmd[0] == "train.py" and "seed=1" in cmd
    assert "resume=runs/study/lasmp/seed1" in cmd and "runner.max_iterations=250" in cmd


def test_the_float32_side_trains_with_float32_and_is_scored_on_the_first_2000_episodes(study):
    study.train("lasmp_float32", 1)
    assert "algo.precision=float32" in study.ran[-1] and "runner.max_iterations=450" in study.ran[-1]
    trained(study, "lasmp_float32", 1, 450)
    study.evaluate("lasmp_float32", 1)
    cmd = study.ran[-1]
    assert cmd[cmd.index("--num-trajectories") + 1] == "2000"
    assert cmd[cmd.index("--out") + 1] == "results/study/lasmp_float32/seed1"
    with pytest.raises(SystemExit, match="model_449.pt does not exist"):
        study.evaluate("lasmp", 2)


def test_rs_is_evaluated_twice_and_counts_as_done_only_with_both_controllers(study):
    trained(study, "rs", 0, 450)
    study.evaluate("rs", 0)
    controllers = [c[c.index("--controller") + 1] for c in study.ran]
    assert controllers == ["rs", "rs_oracle"]
    evaluated(study.result_dir("rs", 0, 450, "rs"))
    assert not study.is_done("evaluate", "rs", 0, 450)
    evaluated(study.result_dir("rs", 0, 450, "rs_oracle"))
    assert study.is_done("evaluate", "rs", 0, 450)


def test_the_summary_lists_each_row_with_its_evaluated_seeds_and_leaves_out_the_float32_side(study):
    for s in (0, 2):
        evaluated(study.result_dir("lasmp", s, 450))
    evaluated(study.result_dir("lasmp", 0, 1000))
    evaluated(study.result_dir("lasmp_float32", 0, 450))
    evaluated(study.result_dir("rs", 1, 450, "rs_oracle"))
    assert study.summary_args() == [
        "--method", "LAS-MP", "results/study/lasmp/seed0", "results/study/lasmp/seed2",
        "--method", "LAS-MP (1,000 it.)", "results/study/lasmp@1000/seed0",
        "--method", "R-S (oracle)", "results/study/rs_oracle/seed1",
        "--method", "Stand Still", "results/study/stand_still/seed0",
    ]  # fmt: skip
