"""The learner: PPO + ROA updates, time-out bootstrapping, checkpoints, resume, determinism,
Hydra composition of every ablation, and the real train.py CLI at a tiny size."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf
from testkit import tiny

from lasmp.algo.checkpoint import CheckpointError, latest_checkpoint, read_checkpoint
from lasmp.config import ConfigError
from lasmp.modules.obs_groups import GROUP_DETACHED_ESTIMATES, GROUP_HISTORY
from lasmp.train import make_runner, train
from lasmp.train_cfg import register_configs, to_train_cfg

ROOT = Path(__file__).resolve().parents[1]
register_configs()


def params(module):
    return {k: v.detach().clone() for k, v in module.state_dict().items()}


def changed(before, module, prefix):
    after = module.state_dict()
    return any(not torch.equal(before[k], after[k]) for k in before if k.startswith(prefix))


def rollout(runner):
    obs = runner.env.get_observations()
    with torch.inference_mode():
        for _ in range(runner.cfg["num_steps_per_env"]):
            actions = runner.alg.act(obs)
            obs, rew, dones, extras = runner.env.step(actions)
            runner.alg.process_env_step(obs, rew, dones, extras)
        runner.alg.compute_returns(obs)


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


def _learner(tmp_path, algorithm=None, **over):
    """A PPOROA on a tiny env, built as rsl_rl's runner builds it, without a runner or a logger."""
    from lasmp.algo.ppo_roa import PPOROA
    from lasmp.train import make_env
    from lasmp.train_cfg import rsl_rl_cfg

    cfg = tiny(tmp_path, **over)
    env = make_env(cfg)
    rsl = rsl_rl_cfg(cfg)
    rsl["multi_gpu"] = None
    if algorithm is not None:
        rsl["algorithm"]["class_name"] = algorithm
    alg = (algorithm or PPOROA).construct_algorithm(env.get_observations(), env, rsl, cfg.device)
    return alg, env, rsl["num_steps_per_env"]


def _learner_rollout(alg, env, steps):
    obs = env.get_observations()
    with torch.inference_mode():
        for _ in range(steps):
            obs, rew, dones, extras = env.step(alg.act(obs))
            alg.process_env_step(obs, rew, dones, extras)
        alg.compute_returns(obs)


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
    from lasmp.checkpoint_cfg import checkpoint_cfg

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


def test_checkpoint_round_trip_and_exact_resume(tmp_path):
    cfg = tiny(tmp_path / "a")
    runner = train(cfg)
    ckpt = latest_checkpoint(tmp_path / "a")
    assert ckpt.name == "model_1.pt"
    data = read_checkpoint(ckpt)
    assert data["iter"] == 1 and data["num_actions"] == 12
    assert data["obs_layout"]["history"] == [20, 44]
    assert data["config"]["env"]["num_envs"] == 4
    assert "estimator_optimizer_state_dict" in data and data["env_state"]["curriculum"]["level"] == 5

    runner.env.curriculum._level = 7  # a state only the checkpoint can bring back
    runner.alg.learning_rate = 0.000123
    for group in runner.alg.optimizer.param_groups:
        group["lr"] = 0.000123
    runner.save(str(tmp_path / "a" / "model_5.pt"))

    resumed = make_runner(tiny(tmp_path / "b"), None)
    resumed.load(str(tmp_path / "a"))  # a run directory: its latest checkpoint, model_5
    assert resumed.current_learning_iteration == runner.current_learning_iteration + 1
    assert resumed.env.curriculum.level == 7
    assert resumed.alg.learning_rate == pytest.approx(0.000123)
    for (k, v), (k2, v2) in zip(
        runner.alg.get_policy().state_dict().items(),
        resumed.alg.get_policy().state_dict().items(),
        strict=True,
    ):
        assert k == k2 and torch.equal(v, v2), k


def test_latest_checkpoint_is_numeric(tmp_path):
    for n in (9, 10, 2):
        (tmp_path / f"model_{n}.pt").write_bytes(b"x")
    (tmp_path / "model_best.pt").write_bytes(b"x")
    assert latest_checkpoint(tmp_path).name == "model_10.pt"
    with pytest.raises(CheckpointError, match="no checkpoint"):
        latest_checkpoint(tmp_path / "empty_dir_that_does_not_exist")


def test_bad_checkpoints_fail_with_a_message_that_says_what_is_wrong(tmp_path):
    train(tiny(tmp_path / "a"))
    good = latest_checkpoint(tmp_path / "a")
    with pytest.raises(CheckpointError, match="does not exist"):
        read_checkpoint(tmp_path / "missing.pt")
    truncated = tmp_path / "truncated.pt"
    truncated.write_bytes(good.read_bytes()[:1000])
    with pytest.raises(CheckpointError, match="unreadable"):
        read_checkpoint(truncated)
    other = make_runner(tiny(tmp_path / "b", env={"observations": {"history_length": 15}}), None)
    with pytest.raises(CheckpointError, match=r"'history'.*\[20, 44\].*\[15, 44\]"):
        other.load(str(good))


def test_two_cpu_runs_with_the_same_seed_give_identical_parameters(tmp_path):
    def run(name, seed):
        cfg = tiny(tmp_path / name, seed=seed, runner={"max_iterations": 3})
        return train(cfg).alg.get_policy().state_dict()

    a, b, c = run("a", 1), run("b", 1), run("c", 2)
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert not all(torch.equal(a[k], c[k]) for k in a)


@pytest.mark.parametrize(
    "group, input_dim",
    [
        ("lasmp", 76),
        ("no_alignment_command", 73),
        ("no_platform_velocity_estimates", 67),
        ("no_explicit_estimator", 60),
        ("no_explicit_estimator_history", 60 + 20 * 44),
    ],
)
def test_every_policy_group_composes_with_its_actor_input_size(tmp_path, group, input_dim):
    with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
        cfg = compose("config", overrides=[f"policy={group}", "env.num_envs=2", "torch_threads=1"])
    runner = make_runner(to_train_cfg(cfg), None)
    assert runner.alg.get_policy().backbone_input_dim == input_dim
    assert cfg.policy.name == group


def test_presets_and_overrides_compose():
    with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
        cpu = compose("config")
        paper = compose("config", overrides=["preset=paper"])
        custom = compose(
            "config",
            overrides=["env.num_envs=8", "runner.max_iterations=3", "seed=5", "runner.log_dir=/tmp/x"],
        )
    assert (cpu.env.num_envs, cpu.runner.max_iterations, cpu.device) == (1024, 1000, "cpu")
    assert (paper.env.num_envs, paper.runner.max_iterations, paper.device) == (8192, 4000, "cuda")
    assert (custom.env.num_envs, custom.runner.max_iterations, custom.seed) == (8, 3, 5)
    assert to_train_cfg(custom).env.seed == 5


def test_invalid_training_config_names_the_field():
    with pytest.raises(ConfigError, match="algo.roa_lambda"):
        to_train_cfg(OmegaConf.create({"algo": {"roa_lambda": -1.0}}))
    with pytest.raises(ConfigError, match="algo.entropy_decay_iterations"):
        to_train_cfg(OmegaConf.create({"algo": {"entropy_decay_iterations": -1}}))
    with pytest.raises(ConfigError, match="policy.use_alignment"):
        to_train_cfg(OmegaConf.create({"policy": {"explicit": "none"}}))
    # NaN passes a comparison (`nan <= 0` is false): every number of the config must be finite
    with pytest.raises(ConfigError, match=r"algo.learning_rate must be a finite number, got nan"):
        to_train_cfg(OmegaConf.create({"algo": {"learning_rate": float("nan")}}))
    with pytest.raises(ConfigError, match=r"env.rewards.weights.reg4_air_time must be a finite number"):
        to_train_cfg(OmegaConf.create({"env": {"rewards": {"weights": {"reg4_air_time": float("-inf")}}}}))
    with pytest.raises(ConfigError, match=r"env.init_state.yaw_range_rad\[1\] must be a finite number"):
        to_train_cfg(OmegaConf.create({"env": {"init_state": {"yaw_range_rad": [0.0, float("nan")]}}}))
    with pytest.raises(Exception, match="num_env"):  # a typo: OmegaConf names the unknown key
        to_train_cfg(OmegaConf.create({"env": {"num_env": 8}}))


def run_cli(*args, cwd):
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.run(
        [sys.executable, str(ROOT / "train.py"), *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=env,
        timeout=600,
    )


def test_train_cli_end_to_end_then_resume(tmp_path):
    common = ["env.num_envs=8", "torch_threads=1", "policy.actor_hidden_dims=[32,32,32]"]
    out = run_cli(*common, "runner.max_iterations=2", f"runner.log_dir={tmp_path / 'run'}", cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    lines = [line for line in out.stdout.splitlines() if line.startswith("it ")]
    assert len(lines) == 2 and "steps/s" in lines[0] and "ETA" in lines[0]
    run = tmp_path / "run"
    assert (run / "config.yaml").exists() and (run / "model_1.pt").exists()
    assert any(p.name.startswith("events.out.tfevents") for p in run.iterdir())
    assert OmegaConf.load(run / "config.yaml").env.num_envs == 8

    out = run_cli(
        *common,
        "runner.max_iterations=1",
        f"resume={run}",
        f"runner.log_dir={tmp_path / 'run2'}",
        cwd=tmp_path,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert "at iteration 2" in out.stdout
    assert [line.split("|")[0].strip() for line in out.stdout.splitlines() if line.startswith("it ")] == [
        "it 2/2"
    ]
    assert read_checkpoint(tmp_path / "run2")["iter"] == 2

    out = run_cli(*common, f"resume={tmp_path / 'nope.pt'}", cwd=tmp_path)
    assert out.returncode != 0 and "nope.pt does not exist" in out.stderr


def test_rough_static_task_trains_the_rs_policy(tmp_path):
    with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
        cfg = compose(
            "config",
            overrides=[
                "task=rough_static",
                "env.num_envs=4",
                "runner.max_iterations=1",
                f"runner.log_dir={tmp_path}",
                "torch_threads=1",
                "policy.actor_hidden_dims=[32,32,32]",
            ],
        )
    assert cfg.policy.name == "rs"  # the task picks its policy
    runner = train(cfg)
    actor = runner.alg.get_policy()
    assert actor.command_input and actor.num_explicit == 7 and not actor.use_alignment
    assert actor.backbone_input_dim == 44 + 7 + 3 + 16
    data = read_checkpoint(tmp_path)
    assert data["config"]["task"] == "rough_static" and "command" in data["obs_layout"]


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


@pytest.mark.parametrize(
    ("policy", "on_estimates", "history_read"),
    [({}, False, False), ({}, True, False), ({"history_input": True, "use_alignment": False}, False, True)],
)
def test_ppo_mini_batches_carry_the_history_only_where_the_actor_reads_it(
    tmp_path, policy, on_estimates, history_read
):
    runner = make_runner(tiny(tmp_path, policy=policy), None)
    alg, actor = runner.alg, runner.alg.get_policy()
    rollout(runner)
    actor.act_on_estimates = on_estimates
    seen = []
    real = actor.get_latent

    def spy(obs, *args, **kwargs):
        seen.append(set(obs.keys()))
        return real(obs, *args, **kwargs)

    actor.get_latent = spy
    alg.update_roa = lambda: {}
    alg.update()
    assert seen and all((GROUP_HISTORY in keys) == history_read for keys in seen)
    assert all((GROUP_DETACHED_ESTIMATES in keys) == on_estimates for keys in seen)
    stored = set(alg.storage.observations.keys())
    assert GROUP_HISTORY in stored and GROUP_DETACHED_ESTIMATES not in stored  # restored for the next rollout


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


def _batch_fields(batch) -> list[torch.Tensor]:
    obs = batch.observations
    return [obs[k] for k in sorted(obs.keys())] + [
        batch.actions,
        batch.values,
        batch.advantages,
        batch.returns,
        batch.old_actions_log_prob,
        *batch.old_distribution_params,
    ]


def test_rsl_rl_visits_the_same_mini_batches_in_every_epoch(tmp_path):
    """What `RoaRolloutStorage.ppo_pass` relies on: an rsl_rl that drew a new permutation per
    epoch would fail here rather than have its epochs silently collapse into one."""
    runner = make_runner(tiny(tmp_path), None)
    rollout(runner)
    batches = list(runner.alg.storage.mini_batch_generator(2, 3))
    assert len(batches) == 6
    for first, later in zip(batches[:2] * 2, batches[2:], strict=True):
        assert all(torch.equal(a, b) for a, b in zip(_batch_fields(first), _batch_fields(later), strict=True))
    assert not torch.equal(batches[0].actions, batches[1].actions)


def test_ppo_pass_mini_batches_gathered_once_equal_rsl_rl_s_and_are_fresh_objects(tmp_path):
    runner = make_runner(tiny(tmp_path), None)
    storage = runner.alg.storage
    rollout(runner)
    torch.manual_seed(7)
    expected = list(storage.mini_batch_generator(2, 3))
    torch.manual_seed(7)
    with storage.ppo_pass(storage.observations):
        got = list(storage.mini_batch_generator(2, 3))
    assert len(got) == len(expected) == 6 and len({id(b) for b in got}) == 6
    for a, b in zip(expected, got, strict=True):
        assert all(torch.equal(x, y) for x, y in zip(_batch_fields(a), _batch_fields(b), strict=True))
    got[0].advantages = got[0].advantages * 0.0  # PPO reassigns fields: the next epoch's batch keeps its own
    assert torch.equal(got[2].advantages, expected[2].advantages)
