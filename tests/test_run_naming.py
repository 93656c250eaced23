"""A training says which recipe it trains (LAS-MP+ or the paper's) in its start line, its run directory
and its evaluation's metrics.md; a finished one names its last checkpoint with the commands that play
and evaluate it; a resume's config.yaml says that runner.max_iterations counts the iterations it added.
On the real CLI at a tiny size, in the default run directory (logs/ under the working directory)."""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from testkit import TINY_CLI, run_script

from lasmp.config.recipe import recipe_of, run_label, run_slug
from lasmp.config.train import register_configs, to_train_cfg
from lasmp.eval import benchmark as bm

ROOT = Path(__file__).resolve().parents[1]
TINY = TINY_CLI


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """Two trainings of 2 iterations in the default run directory, LAS-MP+ (the default) and the
    paper's recipe; the first resumed by 1 iteration."""
    tmp = tmp_path_factory.mktemp("naming")
    plus = run_script("train.py", *TINY, "runner.max_iterations=2", cwd=tmp).stdout
    # the paper's recipe with its own 5 learning epochs (the tiny ones' 1 would make it a custom mix)
    paper = run_script(
        "train.py", *TINY, "runner.max_iterations=2", "recipe=paper", "algo.num_learning_epochs=5", cwd=tmp
    ).stdout
    (plus_dir,) = (tmp / "logs" / "moving_platform" / "lasmp_plus").iterdir()
    resumed = run_script("train.py", *TINY, "runner.max_iterations=1", f"resume={plus_dir}", cwd=tmp).stdout
    return tmp, plus, paper, resumed


def compose_cfg(*overrides: str):
    register_configs()
    with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
        return to_train_cfg(compose("config", overrides=list(overrides)))


def test_the_recipe_is_named_from_the_recipe_files_and_a_hand_mixed_config_is_called_custom():
    assert (recipe_of(compose_cfg()), run_label(compose_cfg()), run_slug(compose_cfg())) == (
        "lasmp_plus",
        "LAS-MP+",
        "lasmp_plus",
    )
    paper = compose_cfg("recipe=paper")
    assert (run_label(paper), run_slug(paper)) == ("LAS-MP (the paper's recipe)", "lasmp_paper")
    ablation = compose_cfg("policy=no_alignment_command")
    assert run_label(ablation) == "LAS-MP+, policy no_alignment_command"
    assert run_slug(ablation) == "lasmp_plus-no_alignment_command"
    mixed = compose_cfg("recipe=paper", "algo.symmetry_cfg.use_data_augmentation=true")
    assert recipe_of(mixed) == "custom" and run_slug(mixed) == "lasmp_custom"
    assert run_label(compose_cfg("task=rough_static")) == "rs"  # a task without the recipe's keys


def test_the_start_line_and_the_run_directory_name_the_recipe(trained):
    tmp, plus, paper, _ = trained
    assert (
        "training moving_platform / LAS-MP+: 4 envs, 2 iterations (0\u20131), logs in logs/moving_platform/lasmp_plus/"
        in plus
    )
    assert (
        "training moving_platform / LAS-MP (the paper's recipe): 4 envs, 2 iterations (0\u20131), "
        "logs in logs/moving_platform/lasmp_paper/"
    ) in paper
    assert {p.name for p in (tmp / "logs" / "moving_platform").iterdir()} == {"lasmp_plus", "lasmp_paper"}


def test_a_finished_training_names_its_last_checkpoint_and_the_commands_that_play_and_evaluate_it(trained):
    tmp, plus, _, resumed = trained
    (run_dir,) = (tmp / "logs" / "moving_platform" / "lasmp_plus").iterdir()
    # the run directory as the command named it: the default one relative, the resumed one as given
    for out, checkpoint, last in ((plus, run_dir.relative_to(tmp), 1), (resumed, run_dir, 2)):
        tail = out.rstrip().splitlines()[-3:]
        checkpoint = checkpoint / f"model_{last}.pt"
        assert tail == [
            f"finished: the last checkpoint is {checkpoint} (iteration {last})",
            f"play it:     python play.py --checkpoint {shlex.quote(str(checkpoint))} --video episode.mp4",
            f"evaluate it: python evaluate.py --checkpoint {shlex.quote(str(checkpoint))}",
        ]
        assert (tmp / checkpoint).is_file()


def test_a_resumes_config_says_max_iterations_counts_the_iterations_it_added_not_the_runs_length(trained):
    tmp, *_ = trained
    (run_dir,) = (tmp / "logs" / "moving_platform" / "lasmp_plus").iterdir()
    text = (run_dir / "config.yaml").read_text()
    assert text.startswith(
        "# written by a resume: this command trained iterations 2\u20132, so the run holds 3 in all;\n"
        "# runner.max_iterations below counts the iterations it added, not the run's length\n"
    )
    assert "  max_iterations: 1\n" in text
    (paper_dir,) = (tmp / "logs" / "moving_platform" / "lasmp_paper").iterdir()
    assert not (paper_dir / "config.yaml").read_text().startswith("#")  # a fresh run: no note


def test_an_evaluations_metrics_md_names_the_recipe_and_its_eta_is_a_dash_until_measured(trained):
    tmp, *_ = trained
    bench = tmp / "bench.npz"
    bm.save(bench, bm.generate(num_trajectories=4, num_robots=2, seed=0))
    (paper_dir,) = (tmp / "logs" / "moving_platform" / "lasmp_paper").iterdir()
    for recipe, run_dir in (
        ("LAS-MP+", next((tmp / "logs/moving_platform/lasmp_plus").iterdir())),
        (
            "LAS-MP (the paper's recipe)",
            paper_dir,
        ),
    ):
        out = run_script(
            "evaluate.py",
            *("--checkpoint", str(run_dir), "--benchmark", str(bench), "--num-trajectories", "2"),
            *("--batch-envs", "2", "--no-platform-probe", "--out", str(tmp / "ev" / run_dir.parent.name)),
            cwd=tmp,
        )
        header = (tmp / "ev" / run_dir.parent.name / "metrics.md").read_text().splitlines()[0]
        assert header.startswith(f"# {recipe} checkpoint ") and header.endswith(" (lasmp)")
        progress = [line for line in out.stderr.replace("\r", "\n").splitlines() if " episodes | " in line]
        assert progress[0].endswith("ETA \u2013") and not any("nan" in line for line in progress)
