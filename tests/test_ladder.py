"""scripts/ladder.py: the rungs at equal samples, the table's figures from the curves it names, the figure,
and a command line that refuses what it cannot use."""

from __future__ import annotations

import dataclasses
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from testkit import load_script

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def ladder():
    return load_script("scripts/ladder.py")


def _curve(path: Path, collisions: list[float], steps_per_point: int = 1_000_000) -> None:
    history = [
        {
            "iteration": i,
            "collision_rate": c,
            "height_violation_rate": 0.1,
            "world_tilt_rad": 0.1,
            "seconds": 1.0,
            "env_steps": (i + 1) * steps_per_point,
            "wall_s": 60.0 * (i + 1),
        }
        for i, c in enumerate(collisions)
    ]
    path.mkdir(parents=True)
    (path / "validation.json").write_text(
        json.dumps({"best": min(history, key=lambda r: r["collision_rate"]), "history": history})
    )


def test_the_batch_and_rollout_rungs_train_on_equal_samples_validated_about_as_often_and_at_their_end(ladder):
    for name, rung in ladder.RUNGS.items():
        if rung.continues or rung.seeds != ladder.SEEDS:  # a length rung; the new rows
            continue
        samples = rung.iterations * rung.num_envs * rung.steps_per_env
        assert samples == ladder.SAMPLES, name  # 22.1 M env-steps each
        assert rung.iterations % rung.validation_interval == 0, name  # the last iteration is scored
        assert 15 <= rung.iterations // rung.validation_interval <= 18, name
    assert (ladder.RUNGS["base"].iterations, ladder.RUNGS["envs8192"].iterations) == (1_800, 225)
    cmd = ladder.RUNGS["steps24"].command(10, Path("runs/x"), 900, resume=False)
    assert "runner.num_steps_per_env=24" in cmd and "runner.max_iterations=900" in cmd and "seed=10" in cmd
    big = ladder.RUNGS["envs8192"].command(10, Path("runs/x"), 225, resume=False)
    assert "runner.validation_interval=15" in big and "runner.save_interval=15" in big
    assert "runner.save_interval=50" in ladder.RUNGS["base"].command(10, Path("r"), 5, False)
    assert (
        cmd[-1] != "resume=runs/x" and ladder.RUNGS["base"].command(10, Path("r"), 5, True)[-1] == "resume=r"
    )
    assert min(ladder.SEEDS) >= 10  # fresh seeds: no run before the ladder used 10 and up


def test_the_table_gives_each_seeds_final_score_their_mean_spread_and_the_differences_from_the_baseline(
    ladder, tmp_path
):
    _curve(tmp_path / "base" / "seed10", [0.5, 0.2, 0.10])
    _curve(tmp_path / "base" / "seed11", [0.5, 0.3, 0.06])
    _curve(tmp_path / "envs4096" / "seed10", [0.4, 0.05, 0.07])
    _curve(tmp_path / "envs4096" / "seed11", [0.4, 0.10, 0.05])
    rows = {r["rung"]: r for r in ladder.table_rows(ladder.curves(tmp_path))}
    base, big = rows["base"], rows["envs4096"]
    assert base["per_seed"] == {"10": 0.10, "11": 0.06} and base["mean"] == pytest.approx(0.08)
    assert base["spread"] == pytest.approx(0.04) and base["diff_from_base"] == {}
    assert big["diff_from_base"] == pytest.approx({"10": -0.03, "11": -0.01})
    assert big["mean_diff_from_base"] == pytest.approx(-0.02) and big["spread"] == pytest.approx(0.02)
    assert big["best_mean"] == pytest.approx(0.05)  # each seed's lowest point on its curve, averaged
    assert (big["env_steps"], big["minutes"]) == (3_000_000, 3.0)
    text = ladder.markdown(list(rows.values()))
    assert (
        "| (a) batch | 4,096 envs | 10, 11 | 0.070 / 0.050 | 0.060 | 0.020 | -0.030 / -0.010 (-0.020) |"
        in text
    )


def test_the_table_times_each_seed_to_its_first_validation_at_each_target(ladder, tmp_path):
    _curve(tmp_path / "base" / "seed10", [0.5, 0.04, 0.06, 0.02])  # 0.05 at its 2nd point, 0.029 at its 4th
    _curve(tmp_path / "base" / "seed11", [0.5, 0.3, 0.06, 0.05])  # 0.05 exactly at its 4th; 0.029 never
    (row,) = ladder.table_rows(ladder.curves(tmp_path))
    assert row["first_reaching"]["0.05"] == {"10": (2_000_000, 2.0), "11": (4_000_000, 4.0)}
    assert row["first_reaching"]["0.029"] == {"10": (4_000_000, 4.0), "11": None}
    assert "| 2.0 (2) / 4.0 (4) | 4.0 (4) / never |" in ladder.markdown([row])


def test_the_figure_draws_every_collected_rung(ladder, tmp_path):
    _curve(tmp_path / "base" / "seed10", [0.5, 0.2, 0.1])
    _curve(tmp_path / "steps48" / "seed10", [0.4, 0.2, 0.1])
    out = ladder.figure(ladder.curves(tmp_path), tmp_path / "fig" / "scaling.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_truncated_curve_is_one_line_naming_its_file(ladder, tmp_path):
    path = tmp_path / "base" / "seed10"
    path.mkdir(parents=True)
    (path / "validation.json").write_text('{"history": [{"iteration"')
    with pytest.raises(SystemExit, match=r"seed10/validation.json: not a validation curve"):
        ladder.curves(tmp_path)


@pytest.mark.parametrize(
    "args, message",
    [
        (["plan", "--bogus"], "unrecognized arguments: --bogus"),
        (["train", "base", "3"], "the ladder's seeds are 10, 11, 20, 21, 22, got 3"),
        (["train", "nope", "10"], "invalid choice: 'nope'"),
    ],
)
def test_the_command_line_refuses_what_it_cannot_use(args, message):
    out = subprocess.run(
        [sys.executable, "scripts/ladder.py", *args], cwd=ROOT, capture_output=True, text=True
    )
    assert out.returncode == 2 and message in out.stderr


def test_help_says_what_the_ladder_is():
    out = subprocess.run(
        [sys.executable, "scripts/ladder.py", "--help"], cwd=ROOT, capture_output=True, text=True
    )
    assert out.returncode == 0 and "validation benchmark" in out.stdout and "table" in out.stdout


def test_a_running_run_leaves_its_newest_policy_light_with_its_commands_and_an_unfinished_one_is_not_collected(
    tmp_path, monkeypatch
):
    from testkit import tiny

    from lasmp.cli.train import train

    ladder = load_script("scripts/ladder.py")
    ladder.ROOT, ladder.RESULTS = tmp_path, tmp_path / "results" / "ladder"
    run = tmp_path / "runs" / "ladder" / "base" / "seed10"
    train(
        tiny(
            run,
            runner={
                "max_iterations": 2,
                "save_interval": 1,
                "validation_interval": 1,
                "validation_episodes": 2,
            },
        )
    )
    (run.parent / "seed10.commands").write_text("# a time\ntrain.py seed=10\n")
    dest = ladder.snapshot("base", 10)
    policy = torch.load(dest / "policy_1.pt", weights_only=True)
    # the policy checkpoint, critic kept: a warm start from it starts only the optimizers anew
    assert policy["kind"] == "policy" and policy["iter"] == 1 and policy["critic_state_dict"]
    assert "optimizer_state_dict" not in policy and (dest / "policy_1.pt").stat().st_size < 2.5e6
    assert (dest / "commands").read_text().endswith("train.py seed=10\n")
    with pytest.raises(SystemExit, match="has not finished its 1800 iterations"):
        ladder.collect("base", 10)
    # a rung of two iterations at 4 envs: the run has finished it
    monkeypatch.setitem(
        ladder.RUNGS, "base", ladder.Rung("4 envs", "baseline", num_envs=4, samples=4 * 12 * 2)
    )
    out = ladder.collect("base", 10)
    assert sorted(p.name for p in out.iterdir()) == [  # the snapshot gone: the finished run replaces it
        "commands",
        "config.yaml",
        "policy_best.pt",
        "validation.json",
    ]
    best = torch.load(out / "policy_best.pt", weights_only=True)
    assert best["kind"] == "actor" and sum(f.stat().st_size for f in out.iterdir()) < 1e6  # a run adds < 1 MB
    assert [r["iteration"] for r in ladder.read_curve(out / "validation.json")["history"]] == [0, 1]
    with pytest.raises(SystemExit, match="holds a collected run; give --force"):
        ladder.collect("base", 10)


def _tiny_ladder(tmp_path):
    """scripts/ladder.py with its runs and results under tmp_path, and a rung of two iterations at the
    test sizes (4 envs, 2 validation episodes)."""
    from testkit import TINY_CLI

    ladder = load_script("scripts/ladder.py")
    ladder.RUNS, ladder.RESULTS = tmp_path / "runs", tmp_path / "results"
    tiny = (*TINY_CLI, "runner.validation_episodes=2")
    return ladder, ladder.Rung("4 envs", "baseline", num_envs=4, overrides=tiny, samples=4 * 12 * 2)


def test_train_runs_a_rung_and_records_its_command_with_the_machine_once_it_has_saved(tmp_path, monkeypatch):
    ladder, tiny_rung = _tiny_ladder(tmp_path)
    monkeypatch.setitem(ladder.RUNGS, "base", tiny_rung)
    assert ladder.train("base", 10) == 0
    lines = (tmp_path / "runs" / "base" / "seed10.commands").read_text().splitlines()
    assert len(lines) == 2 and lines[0].startswith("# ") and "cores" in lines[0]
    assert "seed=10" in lines[1] and "runner.max_iterations=2" in lines[1]
    assert ladder.train("base", 10) == 0  # done: nothing runs, nothing is recorded again
    assert len((tmp_path / "runs" / "base" / "seed10.commands").read_text().splitlines()) == 2
    curve = ladder.read_curve(tmp_path / "runs" / "base" / "seed10" / "validation.json")
    assert [r["iteration"] for r in curve["history"]] == [0, 1]
    # the machine is lost after a snapshot: the run goes on from the snapshot's policy, a warm start
    ladder.snapshot("base", 10)
    shutil.rmtree(tmp_path / "runs")
    monkeypatch.setitem(ladder.RUNGS, "base", dataclasses.replace(tiny_rung, samples=4 * 12 * 4))
    assert ladder.train("base", 10) == 0
    lines = (tmp_path / "runs" / "base" / "seed10.commands").read_text().splitlines()
    assert len(lines) == 4 and "runner.max_iterations=2" in lines[3]
    assert "warm_start=" in lines[3] and lines[3].endswith("in_progress/policy_1.pt")
    run = tmp_path / "runs" / "base" / "seed10"
    assert sorted(p.name for p in run.glob("model_*.pt")) == ["model_2.pt", "model_3.pt"]
    # the validation curve goes on from the snapshot's
    assert [r["iteration"] for r in ladder.read_curve(run / "validation.json")["history"]] == [0, 1, 2, 3]
    # a rung whose training fails before its first save records nothing
    bad = ladder.Rung("bad", "(b) rollout", num_envs=4, overrides=("env.bogus_key=1",))
    monkeypatch.setitem(ladder.RUNGS, "steps24", bad)
    assert ladder.train("steps24", 10) != 0
    assert not (tmp_path / "runs" / "steps24" / "seed10.commands").exists()


def test_a_length_rung_goes_on_from_its_finished_run_in_its_own_directory_after_that_runs_commands(
    tmp_path, monkeypatch
):
    ladder, short = _tiny_ladder(tmp_path)
    longer = dataclasses.replace(short, samples=4 * 12 * 4, continues="envs8192")
    monkeypatch.setitem(ladder.RUNGS, "envs8192", short)
    monkeypatch.setitem(ladder.RUNGS, "long8192", longer)
    with pytest.raises(SystemExit, match="has not finished its 2 iterations here"):
        ladder.train("long8192", 10)
    assert ladder.train("envs8192", 10) == 0
    assert ladder.train("long8192", 10) == 0
    run = tmp_path / "runs" / "long8192" / "seed10"
    assert sorted(p.name for p in run.glob("model_*.pt")) == ["model_2.pt", "model_3.pt"]
    # the curve goes on from the first run's: one curve over the 4 iterations
    assert [r["iteration"] for r in ladder.read_curve(run / "validation.json")["history"]] == [0, 1, 2, 3]
    lines = (run.parent / "seed10.commands").read_text().splitlines()
    assert len(lines) == 4 and "runner.max_iterations=2" in lines[3]
    assert lines[3].endswith(f"resume={tmp_path / 'runs' / 'envs8192' / 'seed10' / 'model_1.pt'}")
    assert ladder.train("long8192", 10) == 0  # done
    # the first run is left as it was
    assert sorted(p.name for p in (tmp_path / "runs" / "envs8192" / "seed10").glob("model_*.pt")) == [
        "model_0.pt",
        "model_1.pt",
    ]


def test_the_new_rows_train_the_chosen_rung_and_the_papers_recipe_on_their_own_seeds_only(ladder):
    plus, paper = ladder.RUNGS["rows_plus"], ladder.RUNGS["rows_paper"]
    assert plus.seeds == paper.seeds == ladder.ROW_SEEDS and not set(ladder.ROW_SEEDS) & set(ladder.SEEDS)
    assert plus.overrides == (*ladder.RUNGS[ladder.CHOSEN].overrides, "runner.validation_episodes=1024")
    assert plus.iterations == paper.iterations
    assert {"recipe=paper", "runner.validation_episodes=1024"} <= set(paper.command(20, Path("r"), 5, False))
    with pytest.raises(SystemExit, match="rung rows_plus trains seeds 20, 21, 22, not 10"):
        ladder.train("rows_plus", 10)
    with pytest.raises(SystemExit, match="rung base trains seeds 10, 11, not 20"):
        ladder.collect("base", 20)


def test_a_queue_trains_and_collects_each_run_in_turn_and_stops_at_one_that_fails(tmp_path, monkeypatch):
    ladder, tiny_rung = _tiny_ladder(tmp_path)
    monkeypatch.setitem(ladder.RUNGS, "base", tiny_rung)
    bad = ladder.Rung("bad", "(b) rollout", num_envs=4, overrides=("env.bogus_key=1",))
    monkeypatch.setitem(ladder.RUNGS, "steps24", bad)
    assert ladder.queue([("base", 10), ("steps24", 10), ("base", 11)]) != 0
    assert (tmp_path / "results" / "base" / "seed10" / "validation.json").exists()  # trained and collected
    assert not (tmp_path / "runs" / "base" / "seed11").exists()  # after the failed run: not started
    assert ladder.queue([("base", 10), ("base", 11)]) == 0  # a collected run is left as it is
    assert (tmp_path / "results" / "base" / "seed11" / "policy_best.pt").exists()


@pytest.mark.parametrize("job", ["base", "base:3", "nope:10", "rows_plus:10", "base:x"])
def test_a_queue_refuses_a_job_that_is_not_a_rung_and_one_of_its_seeds_before_any_run(job):
    out = subprocess.run(
        [sys.executable, "scripts/ladder.py", "queue", "base:10", job],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    assert out.returncode == 2 and "is not RUNG:SEED of the ladder" in out.stderr
