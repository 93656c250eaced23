"""Iterations on the estimates: the schedule of iterations whose rollout acts on the estimators'
outputs, the learner's own count of its iterations across a resume (the study's checkpoint
included), and the update of such an iteration on the very estimates its rollout acted on."""

from __future__ import annotations

import torch
from testkit import ROOT, tiny
from testkit import bare_learner as _learner
from testkit import changed_since as changed
from testkit import learner_rollout as _learner_rollout
from testkit import param_copy as params
from testkit import runner_rollout as rollout

from lasmp.algo.checkpoint import read_checkpoint
from lasmp.cli.build import make_runner
from lasmp.modules.obs_groups import GROUP_DETACHED_ESTIMATES


def test_iterations_on_the_estimates_follow_the_schedule_and_keep_ppo_off_the_estimators(tmp_path):
    runner = make_runner(
        tiny(tmp_path, algo={"estimate_rollout_every": 3, "estimate_rollout_start": 10}), None
    )
    alg, actor = runner.alg, runner.alg.get_policy()
    assert [it for it in range(8, 20) if alg.acts_on_estimates(it)] == [10, 13, 16, 19]
    assert alg.iteration == 0 and not actor.act_on_estimates
    alg.iteration = 13
    assert actor.act_on_estimates
    obs = runner.env.get_observations()
    with torch.inference_mode():
        on_estimates = actor.get_latent(obs).clone()
        actor.act_on_estimates, actor.deploy = False, True
        deployed = actor.get_latent(obs).clone()
        actor.deploy = False
        privileged = actor.get_latent(obs).clone()
    assert torch.equal(on_estimates, deployed) and not torch.equal(on_estimates, privileged)
    alg.iteration = 13
    rollout(runner)
    before = params(actor)
    alg.update_roa = lambda: {}  # PPO's own update only, on the estimates
    losses = alg.update()
    assert losses["Policy/acts_on_estimates"] == 1.0
    assert not changed(before, actor, "explicit_estimator") and not changed(
        before, actor, "implicit_estimator"
    )
    assert changed(before, actor, "mlp")


def test_each_iteration_of_a_run_acts_as_the_schedule_says(tmp_path):
    runner = make_runner(
        tiny(tmp_path, algo={"estimate_rollout_every": 2, "estimate_rollout_start": 1}), None
    )
    modes = []
    real = runner.alg.update

    def spy():
        modes.append(runner.alg.get_policy().act_on_estimates)
        return real()

    runner.alg.update = spy
    runner.learn(4)
    assert modes == [False, True, False, True]  # iterations 0..3: on at 1 and 3
    assert runner.alg.iteration == 4


def test_the_learner_counts_its_iterations_and_acts_on_the_estimates_on_schedule_on_its_own(tmp_path):
    algo = {"estimate_rollout_every": 2, "estimate_rollout_start": 1}
    alg, env, steps = _learner(tmp_path, algo=algo)
    actor = alg.get_policy()
    modes, logged = [], []
    for _ in range(4):
        modes.append(actor.act_on_estimates)
        _learner_rollout(alg, env, steps)
        logged.append(alg.update()["Policy/acts_on_estimates"])
    assert alg.iteration == 4
    assert modes == [False, True, False, True] and logged == [0.0, 1.0, 0.0, 1.0]  # on at 1 and 3
    assert not actor.act_on_estimates  # iteration 4 comes next: off
    # a checkpoint of it: `iter` is the last completed iteration (3); a learner that loads it goes on at 4
    saved = {**alg.save(), "iter": 3}
    resumed, _, _ = _learner(tmp_path, algo=algo)
    assert resumed.iteration == 0 and resumed.load(saved, None, True)
    assert resumed.iteration == 4 and not resumed.get_policy().act_on_estimates
    assert resumed.load({**saved, "iter": 4}, None, True)
    assert resumed.iteration == 5 and resumed.get_policy().act_on_estimates
    # without the iteration (rsl_rl's load_cfg) the learner's count stays where it was
    fresh, _, _ = _learner(tmp_path, algo=algo)
    assert not fresh.load(saved, {"actor": True, "critic": True, "optimizer": True}, True)
    assert fresh.iteration == 0


def test_a_learner_resumed_from_the_studys_checkpoint_goes_on_at_its_place_in_the_estimate_schedule():
    """The study's first LAS-MP seed 0 (results/study/diagnosis/init_std1_seed0) stopped after
    iteration 449 of a schedule that acts on the estimates from iteration 100 on, every iteration:
    it goes on at 450, on the estimates."""
    from lasmp.config.checkpoint import checkpoint_cfg

    data = read_checkpoint(ROOT / "results" / "study" / "diagnosis" / "init_std1_seed0" / "policy_449.pt")
    cfg = checkpoint_cfg(data, num_envs=4, seed=0)
    assert (cfg.algo.estimate_rollout_start, cfg.algo.estimate_rollout_every) == (100, 1)
    runner = make_runner(cfg, None)
    runner.load(
        data,
        load_cfg={
            "actor": True,
            "critic": True,
            "optimizer": False,  # its policy checkpoint: the optimizers' states stayed in the run
            "iteration": True,
            "env_run_state": False,
        },
    )
    alg = runner.alg
    assert alg.iteration == runner.current_learning_iteration == 450
    assert alg.get_policy().act_on_estimates
    assert [it for it in range(95, 103) if alg.acts_on_estimates(it)] == [100, 101, 102]


def test_an_iteration_on_the_estimates_updates_on_the_very_estimates_its_rollout_acted_on(
    tmp_path, monkeypatch
):
    runner = make_runner(
        tiny(tmp_path, algo={"estimate_rollout_every": 1, "estimate_rollout_start": 0}), None
    )
    alg, actor = runner.alg, runner.alg.get_policy()
    assert alg.iteration == 0 and actor.act_on_estimates  # the schedule: on from iteration 0
    rollout(runner)
    kept = alg._rollout_estimates
    sample = alg.storage.observations.flatten(0, 1)
    with torch.no_grad():
        per_batch = actor.get_latent(sample)  # computes the estimates itself
        torch.testing.assert_close(kept.flatten(0, 1), actor.detached_estimates(sample), rtol=1e-5, atol=1e-5)
        sample[GROUP_DETACHED_ESTIMATES] = kept.flatten(0, 1)
        cached = actor.get_latent(sample)
    torch.testing.assert_close(cached, per_batch, rtol=1e-5, atol=1e-5)
    calls, handed = [], []
    real = actor.detached_estimates
    actor.detached_estimates = lambda obs: calls.append(obs.batch_size) or real(obs)
    storage_type = type(alg.storage)
    real_batches = storage_type.mini_batch_generator

    def batches(storage, *args):
        handed.append(storage.observations.get(GROUP_DETACHED_ESTIMATES, None))
        return real_batches(storage, *args)

    monkeypatch.setattr(storage_type, "mini_batch_generator", batches)
    alg.update_roa = lambda: {}
    alg.update()
    assert calls == [] and len(handed) == 1 and torch.equal(handed[0], kept)  # bit for bit, none recomputed
    assert (
        GROUP_DETACHED_ESTIMATES not in alg.storage.observations.keys()
    )  # the next rollout writes without it
    # an update on the estimates after a rollout that did not keep them computes them, once
    actor.act_on_estimates = False
    rollout(runner)
    actor.act_on_estimates = True
    alg.update()
    assert calls == [torch.Size([alg.storage.num_transitions_per_env * runner.env.num_envs])]
    actor.act_on_estimates = False
    alg.update()
    assert len(calls) == 1  # a privileged iteration computes none
