"""What train.py prints, on the real CLI at a tiny size: a line per network, progress lines numbered
as the checkpoint files are, no `nan` reward, no ETA before an iteration after the first is timed,
the checkpoints kept and converted, and a resume that says how many iterations it adds; and that
loading its policy to play or evaluate prints none of rsl_rl's build output."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from lasmp.algo.console import NONE_YET, OneLineLogger
from lasmp.deploy import load_policy

ROOT = Path(__file__).resolve().parents[2]
TINY = [
    "env.num_envs=4",
    "env.trajectory.duration_s=0.3",  # 15 steps: the first episodes end in iteration 1
    "torch_threads=1",
    "algo.precision=float32",  # no compilation
    "algo.num_mini_batches=2",
    "algo.num_learning_epochs=1",
    "policy.actor_hidden_dims=[32,32,32]",
    "policy.critic_hidden_dims=[32,32]",
    "runner.save_interval=1",
    "runner.keep_full=1",
]


def train_py(*args: str, cwd: Path) -> str:
    out = subprocess.run(
        [sys.executable, str(ROOT / "train.py"), *TINY, *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
        timeout=600,
    )
    assert out.returncode == 0, out.stderr[-3000:]
    return out.stdout


def progress(stdout: str) -> list[str]:
    return [line for line in stdout.splitlines() if line.startswith("it ")]


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> tuple[Path, str, str]:
    """A run of 3 iterations, then its resume by 2: the run directory and both outputs."""
    tmp = tmp_path_factory.mktemp("console")
    run = tmp / "run"
    first = train_py("runner.max_iterations=3", f"runner.log_dir={run}", cwd=tmp)
    resumed = train_py("runner.max_iterations=2", f"resume={run}", cwd=tmp)
    return run, first, resumed


def test_each_network_is_one_short_line_instead_of_its_layers(runs):
    _, first, resumed = runs
    for out in (first, resumed):
        head = out[: out.index("\nit 0/" if out is first else "\nit 3/")]
        assert "Linear(" not in out and "Actor Model" not in out and "Resolved observation sets" not in out
        assert len(head.splitlines()) <= 8, head
        actor = [line for line in head.splitlines() if line.startswith("actor: ")]
        critic = [line for line in head.splitlines() if line.startswith("critic: ")]
        assert len(actor) == len(critic) == 1 and all(len(line) < 160 for line in actor + critic)
        assert actor[0].startswith("actor: LasmpActor(policy 44, history 20x44, priv_explicit 13,")
        assert re.fullmatch(r"critic: MLPModel\(critic \d+\), MLP \d+ -> 1, [\d,]+ parameters", critic[0])


def test_progress_lines_number_iterations_as_the_files_show_no_nan_and_no_eta_before_a_timed_iteration(runs):
    run, first, _ = runs
    lines = progress(first)
    assert [line.split(" | ")[0] for line in lines] == ["it 0/2", "it 1/2", "it 2/2"]
    assert "training moving_platform / LAS-MP+: 4 envs, 3 iterations (0\u20132)" in first
    # every line has the same columns, a field with no value yet included (the success rate before an
    # episode has ended)
    assert len({len(line.split(" | ")) for line in lines}) == 1
    labels = [[re.sub(r"[-\d.,:/\u2013 ]+", " ", f).strip() for f in line.split(" | ")] for line in lines]
    assert labels[0] == labels[-1] and "success" in labels[0]
    assert not any("nan" in line for line in lines)
    assert re.search(rf"reward +{NONE_YET} ", lines[0])  # no episode has ended yet
    assert re.search(r"reward +-?\d+\.\d\d ", lines[-1])
    assert lines[0].endswith(f"ETA {NONE_YET}")
    assert all(re.search(r"ETA \d+:\d\d:\d\d$", line) for line in lines[1:])
    said = [line for line in first.splitlines() if line.startswith("checkpoints ")]
    assert (
        said[-1] == "checkpoints (runner.keep_full=1): kept as policy checkpoints: model_1.pt -> policy_1.pt"
    )


def test_a_resume_says_it_adds_max_iterations_and_goes_on_in_the_same_numbering(runs):
    run, _, resumed = runs
    assert (
        f"resumed from {run / 'model_2.pt'} at iteration 3 (0\u20132 done); runner.max_iterations counts "
        "the iterations to add: 2 more, to 4"
    ) in resumed
    lines = progress(resumed)
    assert [line.split(" | ")[0] for line in lines] == ["it 3/4", "it 4/4"]
    assert lines[0].endswith(f"ETA {NONE_YET}") and not any("nan" in line for line in lines)
    assert {p.name for p in run.glob("*.pt")} == {"model_4.pt", *(f"policy_{n}.pt" for n in range(4))}


def test_the_eta_leaves_out_the_first_iteration_of_each_command():
    logger = OneLineLogger.__new__(OneLineLogger)  # _eta reads nothing else
    assert logger._eta(10, 10, 20, 100.0) == NONE_YET  # the first, compiling, is not timed
    assert logger._eta(11, 10, 20, 2.0) == "0:00:16"  # 8 left at 2 s
    assert logger._eta(12, 10, 20, 4.0) == "0:00:21"  # 7 left at 3 s
    assert logger._eta(0, 0, 5, 50.0) == NONE_YET  # a new command starts over


def test_loading_a_run_s_policy_prints_nothing_of_rsl_rl_s(runs, capsys):
    run, _, _ = runs
    capsys.readouterr()
    load_policy(run)
    assert capsys.readouterr().out == ""  # no "Resolved observation sets", no model printout
