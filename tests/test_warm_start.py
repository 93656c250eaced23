"""Warm start (`warm_start=`, lasmp/cli/warm_start.py): a new run from a policy or light checkpoint takes its
actor (and critic where it has one), curriculum, validation curve and iteration, starts the optimizers
anew, and is refused where it cannot go as asked, before anything is written."""

from __future__ import annotations

import pytest
import torch
from testkit import tiny

from lasmp.algo.checkpoint import CheckpointError, policy_checkpoint, read_checkpoint
from lasmp.algo.checkpoint.light import write_light
from lasmp.cli.build import make_runner
from lasmp.cli.train import train
from lasmp.cli.warm_start import WarmStart
from lasmp.config.checks import ConfigError
from lasmp.io.rundir import RunDirError


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A tiny run of 3 iterations (saved at each) and its last checkpoint's policy and light forms; a
    tiny KL target, so that the adaptive schedule surely moves the learning rate."""
    root = tmp_path_factory.mktemp("warm")
    train(tiny(root / "run", runner={"max_iterations": 3}, algo={"desired_kl": 1e-6}))
    policy = policy_checkpoint(root / "run" / "model_2.pt", root / "policy_2.pt")
    light = write_light(policy, root / "light_2.pt")
    return root, policy, light


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


@pytest.mark.parametrize("form", ["policy", "light"])
def test_a_warm_start_takes_the_weights_curriculum_and_iteration_and_starts_the_optimizers_anew(
    trained, tmp_path, form
):
    root, policy, light = trained
    source = policy if form == "policy" else light
    data = read_checkpoint(source)
    cfg = tiny(tmp_path / "new", warm_start=str(source))
    start = WarmStart.check(cfg, explicit=None)
    runner = make_runner(start.cfg, str(tmp_path / "new"))
    untrained_critic = {k: v.clone() for k, v in runner.alg.critic.state_dict().items()}
    said = []
    start.restore(runner, lambda *a, **k: said.append(a[0]))

    assert runner.current_learning_iteration == 3 and runner.alg.iteration == 3
    assert _same(runner.alg.actor.state_dict(), data["actor_state_dict"])
    if form == "policy":
        assert _same(runner.alg.critic.state_dict(), data["critic_state_dict"])
    else:  # the light file holds no critic: the new run's own, untouched
        assert _same(runner.alg.critic.state_dict(), untrained_critic)
        assert "the critic (the file holds none: a new critic" in said[0]
    assert not runner.alg.optimizer.state_dict()["state"]  # Adam's moments start anew
    # the learning rate goes on at the schedule's, which the file kept (the full checkpoint's own)
    full = read_checkpoint(root / "run" / "model_2.pt")
    saved_lr = full["optimizer_state_dict"]["param_groups"][0]["lr"]
    assert saved_lr != pytest.approx(cfg.algo.learning_rate)  # the schedule moved it
    assert data["learning_rates"]["optimizer"]["lr"] == saved_lr
    assert runner.alg.learning_rate == saved_lr
    assert all(g["lr"] == saved_lr for g in runner.alg.optimizer.param_groups)
    assert f"goes on at the file's {saved_lr:.4g}" in said[0]
    assert runner.env.state_dict(run=False) == data["env_state"]  # the curriculum: the checkpoint's
    assert "warm start from" in said[0] and "at iteration 3" in said[0]


def test_a_warm_started_run_trains_on_from_the_checkpoints_iteration_and_records_where_it_started(
    trained, tmp_path
):
    _, _, light = trained
    new = tmp_path / "new"
    runner = train(tiny(new, runner={"max_iterations": 2}, warm_start=str(light)))
    assert runner.current_learning_iteration == 4  # the last iteration trained
    assert sorted(p.name for p in new.glob("model_*.pt")) == ["model_3.pt", "model_4.pt"]
    text = (new / "config.yaml").read_text()
    assert text.startswith("# written by a warm start: this command trained iterations 3\u20134")
    assert f"warm_start: {light}" in text
    # the new run resumes as any run, exactly: the warm start is not taken again
    resumed = train(tiny(new, runner={"max_iterations": 1}, resume=str(new)))
    assert resumed.current_learning_iteration == 5


def test_a_warm_start_is_refused_before_anything_is_written_where_it_cannot_go_as_asked(trained, tmp_path):
    root, policy, _ = trained
    with pytest.raises(ConfigError, match="resume=.* and warm_start=.* both given"):
        train(tiny(tmp_path / "a", warm_start=str(policy), resume=str(root / "run")))
    with pytest.raises(CheckpointError, match="no_such.pt"):
        train(tiny(tmp_path / "b", warm_start=str(tmp_path / "no_such.pt")))
    with pytest.raises(CheckpointError, match="seed=5 differs from the run's seed=0"):
        WarmStart.check(tiny(tmp_path / "c", warm_start=str(policy), seed=5), explicit={"seed"})
    with pytest.raises(RunDirError, match="already holds a run"):
        train(tiny(root / "run", warm_start=str(policy)))
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_a_file_written_before_learning_rates_were_kept_restarts_at_the_configs_and_says_so(
    trained, tmp_path
):
    _, policy, _ = trained
    data = torch.load(policy, weights_only=True)
    del data["learning_rates"]
    old = tmp_path / "policy_2.pt"
    torch.save(data, old)
    start = WarmStart.check(tiny(tmp_path / "new", warm_start=str(old)), explicit=None)
    runner = make_runner(start.cfg, str(tmp_path / "new"))
    said = []
    start.restore(runner, lambda *a, **k: said.append(a[0]))
    assert runner.alg.optimizer.param_groups[0]["lr"] == start.cfg.algo.learning_rate
    assert "keeps no learning rate" in said[0]


def test_a_warm_start_from_a_checkpoint_with_a_non_finite_weight_is_refused_naming_the_entry(
    trained, tmp_path
):
    _, policy, _ = trained
    data = torch.load(policy, weights_only=True)
    key = next(iter(data["actor_state_dict"]))
    data["actor_state_dict"][key] = torch.full_like(data["actor_state_dict"][key], float("nan"))
    bad = tmp_path / "policy_2.pt"
    torch.save(data, bad)
    with pytest.raises(CheckpointError, match="no run can start from it"):
        WarmStart.check(tiny(tmp_path / "new", warm_start=str(bad)), explicit=None)


def test_the_resume_command_after_a_stop_of_a_warm_started_run_drops_the_warm_start(monkeypatch):
    import lasmp.cli.command_line as cli

    given = ["seed=3", "warm_start=results/policy_364.pt", "runner.log_dir=runs/x", "runner.max_iterations=9"]
    monkeypatch.setattr(cli, "hydra_overrides", lambda: given)
    command = cli.resume_command("runs/x/model_7.pt", "runs/x", 3)
    assert command == (
        "python train.py seed=3 runner.max_iterations=3 resume=runs/x/model_7.pt runner.log_dir=runs/x"
    )
