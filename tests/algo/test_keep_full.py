"""runner.keep_full: a run keeps its newest full checkpoints and turns older saves into policy
checkpoints, never losing the only copy; resume, play and evaluate each find the checkpoint they need."""

from __future__ import annotations

import contextlib
import io
import json
import shutil
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf
from testkit import ROOT, tiny

from lasmp.algo import checkpoint as ckpt
from lasmp.algo.checkpoint import CheckpointError, is_policy_only, latest_checkpoint, read_checkpoint
from lasmp.cli.train import train
from lasmp.config.checks import ConfigError
from lasmp.config.train import register_configs, to_train_cfg
from lasmp.io.atomic import AtomicWriteError

register_configs()
KEEP_ONE = {"max_iterations": 3, "keep_full": 1}  # saves after iterations 0, 1 and 2


def names(d: Path) -> set[str]:
    return {p.name for p in d.glob("*.pt")}


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> tuple[Path, str]:
    """A tiny run saved after every iteration, keeping one full checkpoint; and what it printed."""
    d = tmp_path_factory.mktemp("keep") / "run"
    with contextlib.redirect_stdout(io.StringIO()) as out:
        train(tiny(d, precision="float32", runner=KEEP_ONE))
    return d, out.getvalue()


@pytest.fixture
def run_copy(run, tmp_path) -> Path:
    return Path(shutil.copytree(run[0], tmp_path / "run"))


def test_a_run_keeps_one_full_checkpoint_and_its_older_saves_as_policy_checkpoints(run):
    d, out = run
    assert names(d) == {"model_2.pt", "policy_0.pt", "policy_1.pt"}
    for n in (0, 1):
        data = read_checkpoint(d / f"policy_{n}.pt")
        assert (
            is_policy_only(data) and data["iter"] == n and data["source"] == f"model_{n}.pt (iteration {n})"
        )
    assert not is_policy_only(read_checkpoint(d / "model_2.pt"))
    assert (d / "policy_0.pt").stat().st_size < 0.6 * (d / "model_2.pt").stat().st_size
    said = [line for line in out.splitlines() if line.startswith("checkpoints ")]
    assert said == [
        "checkpoints (runner.keep_full=1): kept as policy checkpoints: model_0.pt -> policy_0.pt",
        "checkpoints (runner.keep_full=1): kept as policy checkpoints: model_1.pt -> policy_1.pt",
    ]


def test_a_resume_from_the_directory_continues_from_its_newest_full_checkpoint(run_copy, capsys):
    runner = train(
        tiny(run_copy, precision="float32", resume=str(run_copy), runner={**KEEP_ONE, "max_iterations": 1})
    )
    assert runner.current_learning_iteration == 3
    assert f"resumed from {run_copy / 'model_2.pt'} at iteration 3" in capsys.readouterr().out
    assert names(run_copy) == {"model_3.pt", "policy_0.pt", "policy_1.pt", "policy_2.pt"}


def test_a_policy_checkpoint_given_to_resume_is_refused_naming_the_newest_full_one(run_copy, tmp_path):
    def resume(path):
        train(tiny(tmp_path / "branch", precision="float32", resume=str(path)))

    with pytest.raises(
        CheckpointError,
        match=r"policy_1\.pt is a policy checkpoint \(it holds no training state.*model_2\.pt",
    ):
        resume(run_copy / "policy_1.pt")
    with pytest.raises(
        CheckpointError, match=r"model_0\.pt does not exist \(runner.keep_full kept it as .*policy_0\.pt"
    ):
        resume(run_copy / "model_0.pt")
    (run_copy / "model_2.pt").unlink()
    with pytest.raises(CheckpointError, match=r"policy_1\.pt is a policy checkpoint.*holds none"):
        resume(run_copy / "policy_1.pt")
    with pytest.raises(
        CheckpointError, match=r"no full checkpoint model_<N>\.pt in .*only policy checkpoints"
    ):
        resume(run_copy)
    assert not (tmp_path / "branch").exists()  # refused before anything was written


def test_play_and_evaluate_take_a_converted_policy_checkpoint_and_a_run_directory_its_newest(
    run_copy, tmp_path, capsys
):
    from lasmp.cli.play import main as play
    from lasmp.eval.cli import main as evaluate

    assert latest_checkpoint(run_copy).name == "model_2.pt"  # the newest, of either kind
    assert play(["--checkpoint", str(run_copy / "policy_0.pt"), "--steps", "5"]) == 0
    out = tmp_path / "ev"
    args = ["--checkpoint", str(run_copy / "policy_1.pt"), "--num-trajectories", "1", "--batch-envs", "1"]
    assert evaluate([*args, "--no-platform-probe", "--out", str(out)]) == 0
    assert json.loads((out / "metrics.json").read_text())["num_episodes"] == 1
    (run_copy / "model_2.pt").unlink()
    assert latest_checkpoint(run_copy).name == "policy_1.pt"
    assert play(["--checkpoint", str(run_copy), "--steps", "5"]) == 0
    assert "played 5 steps" in capsys.readouterr().out


@pytest.mark.parametrize("value", [0, -1])
def test_keep_full_below_one_is_refused_naming_the_key(tmp_path, value):
    with pytest.raises(
        ConfigError, match=rf"runner\.keep_full must be an integer in \[1, 1000\] .*, got {value}"
    ):
        tiny(tmp_path, runner={"keep_full": value})


@pytest.mark.parametrize("value", ["two", "1.5"])
def test_keep_full_that_is_no_integer_is_refused_naming_the_key(value):
    with pytest.raises(Exception, match=r"runner\.keep_full"):
        with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
            to_train_cfg(compose("config", overrides=[f"runner.keep_full={value}"]))
    assert to_train_cfg(OmegaConf.create({})).runner.keep_full == 2  # the default


def _three_full(run, d: Path) -> Path:
    """A directory with the run's full checkpoint as model_3, model_4 and model_5."""
    d.mkdir()
    for n in (3, 4, 5):
        shutil.copy(run[0] / "model_2.pt", d / f"model_{n}.pt")
    return d


def test_a_conversion_that_cannot_write_leaves_the_full_checkpoint_and_says_why(run, tmp_path, monkeypatch):
    d = _three_full(run, tmp_path / "d")

    def full_disk(obj, path):
        raise AtomicWriteError(path, OSError(28, "No space left on device"))

    monkeypatch.setattr(ckpt.forms, "atomic_torch_save", full_disk)  # what the conversion writes with
    done, left = ckpt.keep_newest_full(d, 1)
    assert done == [] and names(d) == {"model_3.pt", "model_4.pt", "model_5.pt"}
    assert len(left) == 2 and "model_3.pt (cannot write" in left[0] and "No space left" in left[0]


def test_a_full_checkpoint_in_the_way_of_a_conversion_is_left_and_an_earlier_half_done_one_completes(
    run, tmp_path
):
    d = _three_full(run, tmp_path / "d")
    shutil.copy(d / "model_3.pt", d / "policy_3.pt")  # a full checkpoint under a policy name: not overwritten
    ckpt.policy_checkpoint(d / "model_4.pt", d / "policy_4.pt")  # a conversion cut short before the removal
    done, left = ckpt.keep_newest_full(d, 1)
    assert done == ["model_4.pt -> policy_4.pt"]
    assert left == ["model_3.pt (policy_3.pt exists and is a full checkpoint)"]
    assert names(d) == {"model_3.pt", "policy_3.pt", "policy_4.pt", "model_5.pt"}
    assert not is_policy_only(read_checkpoint(d / "policy_3.pt"))
