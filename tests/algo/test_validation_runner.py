"""The runner's validation step: when it runs, what it logs and keeps (policy_best.pt changes only on an
improvement), what a resume keeps, and that validating leaves the training curve as it was."""

from __future__ import annotations

import dataclasses
import json

import pytest
import torch
from testkit import tiny

from lasmp.algo.runner import LasmpRunner
from lasmp.algo.validating import BEST_POLICY, VALIDATION_FILE
from lasmp.cli.build import make_env, make_runner, make_validator
from lasmp.config.train import rsl_rl_cfg, to_plain
from lasmp.eval import benchmark as bm
from lasmp.eval.validation import Score, Validator


class Scripted:
    """A validator whose scores are given: (collision, height violation) per call, in order. It notes
    which iteration's policy the run's policy_best.pt held when each call came (None: no file yet)."""

    def __init__(self, scores, run_dir=None):
        self.scores = list(scores)
        self.seen: list[int] = []
        self.best_before: list[int | None] = []
        self.run_dir = run_dir

    def __call__(self, iteration, actor_state_dict, obs_layout, num_actions) -> Score:
        self.seen.append(iteration)
        if self.run_dir is not None:
            path = self.run_dir / BEST_POLICY
            self.best_before.append(torch.load(path, weights_only=True)["iter"] if path.exists() else None)
        collision, height = self.scores.pop(0)
        return Score(iteration, collision, height, world_tilt_rad=0.1, seconds=0.0)


def _runner(cfg, validator, interval: int) -> LasmpRunner:
    torch.manual_seed(cfg.seed)
    return LasmpRunner(
        make_env(cfg),
        rsl_rl_cfg(cfg),
        log_dir=cfg.runner.log_dir,
        full_config=to_plain(cfg),
        validator=validator,
        validation_interval=interval,
    )


def _best(run_dir) -> dict:
    return torch.load(run_dir / BEST_POLICY, weights_only=True)


def test_validation_runs_after_every_kth_iteration_and_the_best_file_changes_only_on_an_improvement(tmp_path):
    run = tmp_path / "run"
    cfg = tiny(run, runner={"max_iterations": 10, "save_interval": 100})
    # iterations 1, 3, 5, 7, 9: a first score, a better one, a worse one, a tie in collisions with a
    # worse height violation, the same tie with a better one (the tie-break)
    scores = [(0.5, 0.2), (0.3, 0.2), (0.4, 0.0), (0.3, 0.25), (0.3, 0.1)]
    validator = Scripted(scores, run)
    runner = _runner(cfg, validator, interval=2)
    runner.learn(10)
    assert validator.seen == [1, 3, 5, 7, 9]
    assert validator.best_before + [_best(run)["iter"]] == [None, 1, 3, 3, 3, 9]
    curve = json.loads((run / VALIDATION_FILE).read_text())
    assert [(r["collision_rate"], r["height_violation_rate"]) for r in curve["history"]] == scores
    assert curve["best"]["iteration"] == 9 and runner.validation_best["iteration"] == 9
    walls = [r["wall_s"] for r in curve["history"]]
    assert walls == sorted(walls) and walls[0] > 0


def test_the_best_file_holds_the_policy_of_its_iteration(tmp_path):
    run = tmp_path / "run"
    cfg = tiny(run, runner={"max_iterations": 4, "save_interval": 1})
    runner = _runner(cfg, Scripted([(0.2, 0.0), (0.9, 0.0)]), interval=2)
    runner.learn(4)
    best, model_1 = _best(run), torch.load(run / "policy_1.pt", weights_only=True)  # kept as a policy one
    assert best["kind"] == "policy" and "iteration 1" in best["source"]
    for key, value in model_1["actor_state_dict"].items():
        assert torch.equal(best["actor_state_dict"][key], value), key
    last = torch.load(run / "model_3.pt", weights_only=True)["actor_state_dict"]
    assert not all(torch.equal(best["actor_state_dict"][k], v) for k, v in last.items())


def test_a_resume_keeps_the_best_so_far_and_the_curve(tmp_path):
    run = tmp_path / "run"
    cfg = tiny(run, runner={"max_iterations": 4, "save_interval": 1})
    first = _runner(cfg, Scripted([(0.2, 0.0), (0.4, 0.0)]), interval=2)
    first.learn(4)
    best_bytes = (run / BEST_POLICY).read_bytes()
    wall_at_save = torch.load(run / "model_3.pt", weights_only=True)["validation"]["wall_s"]

    again = _runner(cfg, Scripted([(0.3, 0.0)]), interval=2)
    again.load(str(run / "model_3.pt"))
    assert again.validation_best == first.validation_best
    assert again.validation_history == first.validation_history
    again.learn(2)  # iterations 4 and 5: one more score, worse than the best so far
    assert (run / BEST_POLICY).read_bytes() == best_bytes
    curve = json.loads((run / VALIDATION_FILE).read_text())
    assert [r["iteration"] for r in curve["history"]] == [1, 3, 5]
    assert curve["best"]["iteration"] == 1
    assert curve["history"][-1]["wall_s"] > wall_at_save  # the run's clock goes on from its checkpoint


def test_validating_leaves_the_training_curve_as_it_was(tmp_path):
    def trained(name, interval):
        cfg = tiny(tmp_path / name, seed=3, runner={"max_iterations": 3, "validation_interval": 0})
        validator = Validator(to_plain(cfg), 2, bench=bm.generate_set(bm.VALIDATION)) if interval else None
        runner = _runner(cfg, validator, interval)
        runner.learn(3)
        return runner

    plain, validated = trained("plain", 0), trained("validated", 1)
    assert [r["iteration"] for r in validated.validation_history] == [0, 1, 2]
    a, b = plain.alg.get_policy().state_dict(), validated.alg.get_policy().state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert plain.validation_history == []


def test_the_default_training_validates_on_the_moving_platform_only(tmp_path):
    on = make_runner(tiny(tmp_path / "a", runner={"validation_interval": 50, "validation_episodes": 8}), None)
    assert isinstance(on.validator, Validator) and on.validation_interval == 50
    off = make_runner(tiny(tmp_path / "b", runner={"validation_interval": 0}), None)
    assert off.validator is None and off.validation_interval == 0
    rough = dataclasses.replace(tiny(tmp_path / "c", runner={"validation_interval": 50}), task="rough_static")
    assert make_validator(to_plain(rough)) is None  # the validation benchmark is the moving platform's


@pytest.mark.parametrize("interval", [0, 3])
def test_no_validation_runs_when_none_is_due(tmp_path, interval):
    validator = Scripted([])
    runner = _runner(tiny(tmp_path / "run"), validator, interval)
    runner.learn(2)
    assert validator.seen == [] and not (tmp_path / "run" / BEST_POLICY).exists()
