"""The learner's update on a tiny rollout: PPO's and the ROA pass's shares of the actor, what the
ROA pass logs, the divergence guard, time-out bootstrapping, the entropy bonus and its decay, and
the fused-Adam, mixed-precision and compiled-MLP options."""

from __future__ import annotations

import math

import pytest
import torch
from testkit import bare_learner as _learner
from testkit import changed_since as changed
from testkit import learner_rollout as _learner_rollout
from testkit import param_copy as params
from testkit import runner_rollout as rollout
from testkit import tiny

from lasmp.cli.build import make_runner
from lasmp.modules.obs_groups import GROUP_HISTORY


def test_ppo_update_leaves_estimators_alone_and_roa_moves_them(tmp_path):
    runner = make_runner(tiny(tmp_path), None)
    actor = runner.alg.get_policy()
    rollout(runner)
    before = params(actor)
    runner.alg.update_roa = lambda: {}  # PPO's own update only
    runner.alg.update()
    assert not changed(before, actor, "explicit_estimator") and not changed(
        before, actor, "implicit_estimator"
    )
    assert changed(before, actor, "mlp") and changed(before, actor, "encoder")

    runner = make_runner(tiny(tmp_path), None)
    actor = runner.alg.get_policy()
    rollout(runner)
    runner.alg.storage.clear()  # as PPO.update leaves it: the data stay, the cursor rewinds
    before = params(actor)
    losses = type(runner.alg).update_roa(runner.alg)
    assert {"roa_exp", "roa_imp_est", "roa_imp_reg"} <= set(losses)
    assert "Estimator/v_plf_x" in losses and "Estimator/l_imp_l2" in losses
    assert changed(before, actor, "explicit_estimator") and changed(before, actor, "implicit_estimator")
    assert changed(before, actor, "encoder")  # the λ term
    assert not changed(before, actor, "mlp")  # the backbone is PPO's alone


def test_the_roa_pass_logs_the_errors_of_its_own_forward_passes(tmp_path):
    # with the estimators' learning rate and λ at 0 nothing moves in the pass, so the mean of its
    # mini-batches' errors is the error over the whole rollout; float32, so that the pass and the
    # reference compute alike on every CPU (auto takes bfloat16 autocast where the CPU has it)
    runner = make_runner(tiny(tmp_path, precision="float32", algo={"roa_lambda": 0.0}), None)
    alg, actor = runner.alg, runner.alg.get_policy()
    for group in alg.estimator_optimizer.param_groups:
        group["lr"] = 0.0
    rollout(runner)
    with torch.no_grad():
        _, expected = actor.roa_losses(alg.storage.observations.flatten(0, 1), lam=0.0)
    logged = type(alg).update_roa(alg)
    assert {f"Estimator/{k}" for k in expected} <= set(logged)
    for name, value in expected.items():
        assert logged[f"Estimator/{name}"] == pytest.approx(float(value), rel=1e-5, abs=1e-6)


def test_the_divergence_guard_is_the_learners_own_and_stops_a_non_finite_loss(tmp_path):
    alg, env, steps = _learner(tmp_path)
    assert "update" not in vars(alg)  # PPOROA.update itself, nobody's patch
    _learner_rollout(alg, env, steps)
    alg.storage.observations[GROUP_HISTORY][0, 0] = float("nan")  # one sample, read by the ROA pass alone
    with pytest.raises(
        FloatingPointError, match=r"non-finite loss after the update of iteration 0: .*roa_exp"
    ):
        alg.update()
    assert alg.iteration == 0  # the diverged update does not count


def test_the_divergence_guard_stops_a_non_finite_parameter(tmp_path):
    from lasmp.algo.ppo_roa import PPOROA

    class PoisonedROA(PPOROA):
        """Its ROA pass leaves a parameter infinite (its losses stay finite)."""

        def update_roa(self):
            losses = super().update_roa()
            with torch.no_grad():
                next(self.get_policy().parameters()).view(-1)[0] = float("inf")
            return losses

    alg, env, steps = _learner(tmp_path, algorithm=PoisonedROA)
    assert type(alg) is PoisonedROA and "update" not in vars(alg)
    _learner_rollout(alg, env, steps)
    with pytest.raises(FloatingPointError, match="after the update .*non-finite values in actor_state_dict"):
        alg.update()
    assert alg.iteration == 0


@pytest.mark.parametrize("bootstrap", [True, False])
def test_time_outs_are_bootstrapped_unless_switched_off_and_terminations_never_are(tmp_path, bootstrap):
    runner = make_runner(tiny(tmp_path, algo={"bootstrap_time_outs": bootstrap}), None)
    alg = runner.alg
    obs = runner.env.get_observations()
    with torch.inference_mode():
        alg.act(obs)
        values = alg.transition.values.clone().squeeze(-1)
        rewards = torch.zeros(4)
        dones = torch.tensor([1, 1, 0, 0])
        extras = {"time_outs": torch.tensor([1, 0, 0, 0])}
        alg.process_env_step(obs, rewards, dones, extras)
    stored = alg.storage.rewards[0].squeeze(-1)
    # truncation: bootstrapped with V(s); switched off, the time limit ends the return like a fall
    assert torch.allclose(stored[0], alg.gamma * values[0] if bootstrap else torch.tensor(0.0))
    assert stored[1] == 0.0 and stored[2] == 0.0  # termination and running env: reward only
    assert values[0].abs() > 0  # otherwise the check above proves nothing


@pytest.mark.parametrize("entropy_coef", [None, 0.0])
def test_without_a_task_signal_the_default_update_raises_the_action_std_and_no_bonus_leaves_it_alone(
    tmp_path, entropy_coef
):
    """Zero advantages give PPO's surrogate no gradient, so only an entropy bonus moves the std; the
    default has a small one (ours: 0.003, between rsl_rl's 0.01 and none; docs/results.md)."""
    algo = {} if entropy_coef is None else {"entropy_coef": entropy_coef}
    runner = make_runner(tiny(tmp_path, algo=algo), None)
    assert runner.alg.entropy_coef == (0.003 if entropy_coef is None else entropy_coef)
    rollout(runner)
    runner.alg.storage.advantages = torch.zeros_like(runner.alg.storage.advantages)
    std = runner.alg.get_policy().distribution.std_param
    before = std.detach().clone()
    runner.alg.update()
    if entropy_coef is None:
        assert (std > before).all()
    else:
        assert torch.equal(std, before)


def test_a_decaying_entropy_bonus_falls_linearly_to_zero_and_a_resumed_learner_goes_on_where_it_left(
    tmp_path,
):
    algo = {"entropy_coef": 0.01, "entropy_decay_iterations": 4}
    alg, env, steps = _learner(tmp_path, algo=algo)
    std = alg.get_policy().distribution.std_param
    logged, moved = [], []
    for _ in range(6):
        _learner_rollout(alg, env, steps)
        alg.storage.advantages = torch.zeros_like(alg.storage.advantages)  # only the bonus moves the std
        alg.optimizer.state.clear()  # and no momentum of an earlier update
        before = std.detach().clone()
        logged.append(alg.update()["Policy/entropy_coef"])
        moved.append(not torch.equal(std, before))
    assert logged == pytest.approx([0.01, 0.0075, 0.005, 0.0025, 0.0, 0.0])
    assert moved == [True, True, True, True, False, False]  # no bonus left from iteration 4 on
    resumed, _, _ = _learner(tmp_path, algo=algo)
    assert resumed.entropy_coef == pytest.approx(0.01)
    assert resumed.load({**alg.save(), "iter": 1}, None, True)  # goes on at iteration 2
    assert resumed.entropy_coef == pytest.approx(0.005)
    constant, _, _ = _learner(tmp_path, algo={"entropy_coef": 0.01})
    constant.iteration = 10_000
    assert constant.entropy_coef == 0.01  # 0 decay iterations: rsl_rl's constant bonus


def test_fused_adam_option_builds_fused_optimizers_over_the_same_parameters(tmp_path):
    plain = make_runner(tiny(tmp_path), None).alg
    fused = make_runner(tiny(tmp_path, algo={"fused_adam": True}), None)
    alg = fused.alg
    assert alg.optimizer.defaults["fused"] and alg.estimator_optimizer.defaults["fused"]
    shapes = [[tuple(p.shape) for p in g["params"]] for g in alg.optimizer.param_groups]
    assert shapes == [[tuple(p.shape) for p in g["params"]] for g in plain.optimizer.param_groups]
    rollout(fused)
    before = params(alg.get_policy())
    losses = alg.update()
    assert all(math.isfinite(v) for v in losses.values()) and changed(before, alg.get_policy(), "mlp")


def test_mixed_precision_runs_ppo_and_roa_under_bfloat16_autocast(tmp_path):
    runner = make_runner(tiny(tmp_path, algo={"use_mixed_precision": True}), None)
    alg, actor = runner.alg, runner.alg.get_policy()
    seen = []
    real = actor.roa_losses

    def spy(obs, lam):
        seen.append(torch.is_autocast_enabled("cpu") and torch.get_autocast_dtype("cpu") == torch.bfloat16)
        return real(obs, lam)

    actor.roa_losses = spy
    rollout(runner)
    before = params(actor)
    losses = alg.update()
    assert seen and all(seen)
    assert all(math.isfinite(v) for v in losses.values())
    assert changed(before, actor, "mlp") and changed(before, actor, "implicit_estimator")


def test_compiled_mlps_train_and_save_the_same_parameter_names(tmp_path):
    plain = make_runner(tiny(tmp_path), None)
    compiled = make_runner(tiny(tmp_path, algo={"compile_mlps": True}), None)
    alg = compiled.alg
    nets = [alg.actor.mlp, alg.critic.mlp, alg.actor.encoder.mlp, *alg.actor.estimators()]
    assert len(nets) == 5 and all(net._compiled_call_impl is not None for net in nets)
    assert plain.alg.actor.state_dict().keys() == alg.actor.state_dict().keys()
    rollout(compiled)
    before = params(alg.get_policy())
    losses = alg.update()
    assert all(math.isfinite(v) for v in losses.values()) and changed(before, alg.get_policy(), "mlp")
    assert changed(before, alg.get_policy(), "implicit_estimator")  # the compiled estimators learn too
    plain.alg.actor.load_state_dict(alg.actor.state_dict())  # a compiled run's checkpoint loads anywhere
