"""Reliability of the learner: GAE by hand, the divergence guard, saves that cannot be half-written,
random states in checkpoints, and Ctrl-C / SIGTERM during the real train.py."""

from __future__ import annotations

import copy
import os
import shlex
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import torch
from omegaconf import OmegaConf
from testkit import tiny

from lasmp.algo.checkpoint import atomic_torch_save, read_checkpoint
from lasmp.cli.build import make_runner
from lasmp.cli.train import train
from lasmp.io.plainstate import unpack

ROOT = Path(__file__).resolve().parents[2]


def test_gae_matches_a_computation_by_hand_with_terminations_and_time_outs(tmp_path):
    runner = make_runner(tiny(tmp_path, steps=5), None)
    alg, env = runner.alg, runner.env
    gamma, lam = alg.gamma, alg.lam
    steps = runner.cfg["num_steps_per_env"]
    rewards = torch.tensor(
        [
            [0.5, -1.0, 2.0, 0.1],
            [1.0, 0.0, -0.5, 0.3],
            [0.2, 0.7, 0.0, -0.2],
            [-0.3, 0.4, 1.5, 0.9],
            [0.6, -0.8, 0.2, 0.05],
        ]
    )
    # env 0 terminates at step 1, env 1 times out at step 2, env 2 both (different steps), env 3 runs on
    dones = torch.tensor([[0, 0, 0, 0], [1, 0, 1, 0], [0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 1, 0]])
    time_outs = torch.tensor([[0, 0, 0, 0], [0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 1, 0]])
    assert rewards.shape[0] == steps
    obs = env.get_observations()
    values = []
    with torch.inference_mode():
        for t in range(steps):
            alg.act(obs)
            values.append(alg.transition.values.squeeze(-1).clone())
            obs = env.step(torch.zeros(4, 12))[0]  # new states, so V changes along the rollout
            alg.process_env_step(obs, rewards[t], dones[t], {"time_outs": time_outs[t]})
        last_value = alg.critic(obs).squeeze(-1).clone()
        alg.compute_returns(obs)
    v = torch.stack(values).double()
    assert v.std() > 0  # otherwise the check proves little
    # by hand: a time-out is a truncation, bootstrapped with gamma V(s_t) (rsl_rl's reading); both end GAE
    r = rewards.double() + gamma * v * time_outs.double()
    expected_returns = torch.zeros(steps, 4, dtype=torch.float64)
    adv = torch.zeros(4, dtype=torch.float64)
    for t in reversed(range(steps)):
        next_v = last_value.double() if t == steps - 1 else v[t + 1]
        alive = 1.0 - dones[t].double()
        delta = r[t] + gamma * alive * next_v - v[t]
        adv = delta + gamma * lam * alive * adv
        expected_returns[t] = adv + v[t]
    got = alg.storage.returns.squeeze(-1).double()
    torch.testing.assert_close(got, expected_returns, rtol=1e-5, atol=1e-5)
    a = expected_returns - v
    if not alg.normalize_advantage_per_mini_batch:
        a = (a - a.mean()) / (a.std() + 1e-8)
    torch.testing.assert_close(alg.storage.advantages.squeeze(-1).double(), a, rtol=1e-4, atol=1e-4)


def test_non_finite_loss_raises_naming_it_and_saves_nothing(tmp_path, monkeypatch):
    from rsl_rl.algorithms import PPO

    real = PPO.update
    # rsl_rl's PPO update diverges
    monkeypatch.setattr(PPO, "update", lambda self: {**real(self), "value": float("nan")})
    runner = make_runner(tiny(tmp_path, steps=5), str(tmp_path))
    assert "update" not in vars(runner.alg)  # the runner leaves the learner's update alone
    with pytest.raises(FloatingPointError, match=r"non-finite loss .*'value': nan"):
        runner.learn(2)
    assert [p.name for p in tmp_path.glob("model_*.pt")] == []


def test_non_finite_parameter_raises_and_never_overwrites_a_good_checkpoint(tmp_path, monkeypatch):
    runner = make_runner(tiny(tmp_path, steps=5), str(tmp_path))
    good = tmp_path / "model_0.pt"
    runner.save(str(good))
    before = good.read_bytes()
    real = type(runner.alg).update_roa

    def poisoned(alg):
        losses = real(alg)
        with torch.no_grad():
            next(alg.get_policy().parameters()).view(-1)[0] = float("inf")
        return losses

    monkeypatch.setattr(type(runner.alg), "update_roa", poisoned)  # the ROA pass leaves a parameter infinite
    with pytest.raises(FloatingPointError, match="non-finite values in actor_state_dict"):
        runner.learn(2)
    with pytest.raises(FloatingPointError, match="refusing to save"):
        runner.save(str(good))
    assert good.read_bytes() == before
    assert read_checkpoint(good)["iter"] == 0
    assert sorted(p.name for p in tmp_path.iterdir() if p.is_file() and "tfevents" not in p.name) == [
        "model_0.pt"
    ]


def test_a_save_killed_mid_write_leaves_the_previous_checkpoint_intact(tmp_path):
    train(tiny(tmp_path, steps=5, runner={"max_iterations": 1}))
    target = tmp_path / "model_0.pt"
    before = target.read_bytes()
    # a subprocess starts overwriting model_0.pt through the atomic writer and is killed mid-write
    script = textwrap.dedent(f"""
        import sys, time, torch
        from lasmp.algo.checkpoint import atomic_torch_save
        def slow(obj, f):
            f.write(b"PK\\x03\\x04 partial checkpoint bytes" * 1000)
            f.flush()
            print("writing", flush=True)
            time.sleep(60)
        torch.save = slow
        atomic_torch_save({{"x": 1}}, {str(target)!r})
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        assert proc.stdout.readline().strip() == "writing"
        partial = [p for p in tmp_path.iterdir() if p.name.startswith(".model_0.pt.")]
        assert len(partial) == 1 and partial[0].stat().st_size > 0  # the write was really under way
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert target.read_bytes() == before
    assert read_checkpoint(target)["iter"] == 0  # still loadable


def test_checkpoints_carry_random_states_and_a_resume_continues_the_streams(tmp_path):
    runner = make_runner(tiny(tmp_path, steps=5), None)
    runner.env.rng.random(7)  # move the env's numpy stream away from its seed
    torch.rand(3)
    runner.save(str(tmp_path / "model_3.pt"))
    next_torch, next_numpy = torch.rand(4), runner.env.rng.random(4)
    data = read_checkpoint(tmp_path / "model_3.pt")
    assert {"torch", "numpy_env"} <= set(data["rng_state"])

    resumed = make_runner(tiny(tmp_path / "b", steps=5), None)
    torch.rand(10)  # whatever happened before the load does not matter
    resumed.load(str(tmp_path / "model_3.pt"))
    assert torch.equal(torch.rand(4), next_torch)
    np.testing.assert_array_equal(resumed.env.rng.random(4), next_numpy)


def test_a_checkpoint_without_random_states_still_loads(tmp_path):
    runner = make_runner(tiny(tmp_path, steps=5), None)
    runner.save(str(tmp_path / "model_1.pt"))
    data = read_checkpoint(tmp_path / "model_1.pt")
    del data["rng_state"], data["path"]
    atomic_torch_save(data, tmp_path / "model_2.pt")  # as written before random states were saved
    make_runner(tiny(tmp_path / "b", steps=5), None).load(str(tmp_path / "model_2.pt"))


@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_signal_during_train_py_saves_the_current_iteration_and_prints_the_resume_command(
    tmp_path, signum, code
):
    run = tmp_path / "run"
    args = [
        "env.num_envs=4",
        "torch_threads=1",
        "policy.actor_hidden_dims=[32,32,32]",
        "runner.max_iterations=500",
        "runner.save_interval=1000",
        f"runner.log_dir={run}",
    ]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [sys.executable, str(ROOT / "train.py"), *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
        env=env,
    )
    try:
        iterations = 0
        deadline = time.monotonic() + 300
        while iterations < 3 and time.monotonic() < deadline:  # let a few iterations pass
            line = proc.stdout.readline()
            assert line, proc.stderr.read()[-2000:]
            iterations += line.startswith("it ")
        proc.send_signal(signum)
        out, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == code, err[-2000:]
    saved = sorted(run.glob("model_*.pt"), key=lambda p: int(p.stem.split("_")[1]))
    assert len(saved) == 2 and saved[0].name == "model_0.pt"  # model_0 (save interval) + the interrupted one
    stopped_at = int(saved[-1].stem.split("_")[1])
    assert stopped_at >= 2 and read_checkpoint(saved[-1])["iter"] == stopped_at
    command = out.split("resume with:")[1].strip().splitlines()[0]
    assert command.startswith("python train.py ") and f"resume={saved[-1]}" in command
    assert f"runner.log_dir={run}" in command and "env.num_envs=4" in command
    # a resume runs runner.max_iterations more: the command asks for those left of the first one's 500
    assert f"runner.max_iterations={500 - (stopped_at + 1)}" in command.split()

    resume = shlex.split(command)[2:]  # the command is quoted for the shell: pasted, it is split so
    resume = [a if not a.startswith("runner.max_iterations=") else "runner.max_iterations=1" for a in resume]
    again = subprocess.run(
        [sys.executable, str(ROOT / "train.py"), *resume],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=env,
        timeout=300,
    )
    assert again.returncode == 0, again.stderr[-2000:]
    assert f"at iteration {stopped_at + 1}" in again.stdout
    assert read_checkpoint(run)["iter"] == stopped_at + 1


@pytest.mark.parametrize(
    ("task", "backend"),
    [
        ("moving_platform", "cpu"),
        ("rough_static", "cpu"),
        pytest.param("moving_platform", "warp", marks=pytest.mark.warp),
    ],
)
def test_resume_is_exact_the_same_parameters_as_an_uninterrupted_run(tmp_path, task, backend):
    over = {}
    if backend == "warp":  # the physics state a checkpoint carries is the backend's own
        pytest.importorskip("mujoco_warp", reason="the gpu extra is not installed")
        over = {"env": {"backend": "warp"}}
    if task == "rough_static":  # the task's own policy and env schema, as train.py composes them
        from hydra import compose, initialize_config_dir

        from lasmp.config.train import register_configs

        register_configs()
        with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
            base = compose("config", overrides=["task=rough_static", "env.num_envs=4"])
        over = {
            "task": "rough_static",
            "policy": OmegaConf.to_container(base.policy),
            "env": OmegaConf.to_container(base.env),
        }
    # algo: the estimate-rollout schedule switches within the run, so the resume must get it right too;
    # float32 on every CPU, so that the adaptive schedule's first steps do not depend on whether
    # `auto` took bfloat16 autocast; a tiny desired KL, so that the schedule surely moves the
    # learning rate in them (asserted below)
    algo = {
        "estimate_rollout_every": 2,
        "estimate_rollout_start": 1,
        "precision": "float32",
        "desired_kl": 1e-6,
    }
    keep = {"max_iterations": 4, "keep_full": 4}  # model_1.pt, the resume's start, stays full
    straight = train(tiny(tmp_path / "a", steps=5, runner=keep, algo=algo, **over))
    resume = str(tmp_path / "a" / "model_1.pt")
    resumed = train(
        tiny(tmp_path / "b", steps=5, runner={"max_iterations": 2}, algo=algo, resume=resume, **over)
    )
    assert resumed.current_learning_iteration == straight.current_learning_iteration == 3
    a, b = read_checkpoint(tmp_path / "a" / "model_3.pt"), read_checkpoint(tmp_path / "b" / "model_3.pt")
    for key in ("actor_state_dict", "critic_state_dict"):
        for name, value in a[key].items():
            assert torch.equal(value, b[key][name]), f"{key}.{name}"
    physics = [unpack(x["env_state"]["run"]["sim"], name="physics state")["state"] for x in (a, b)]
    np.testing.assert_array_equal(np.asarray(physics[0]), np.asarray(physics[1]))
    assert torch.equal(a["rng_state"]["torch"], b["rng_state"]["torch"])
    # the adaptive schedule's learning rate goes on from the checkpoint's, not from algo.learning_rate
    # (rsl-rl-lib before 5.4.2 reset it on load): at the resume and, so, at the end
    saved_lr = read_checkpoint(resume)["optimizer_state_dict"]["param_groups"][0]["lr"]
    assert saved_lr != pytest.approx(1e-3)  # the schedule moved it in the first 2 iterations
    probe = make_runner(tiny(tmp_path / "p", steps=5, algo=algo, **over), None)
    probe.load(resume)
    assert probe.alg.learning_rate == saved_lr
    assert all(group["lr"] == saved_lr for group in probe.alg.optimizer.param_groups)
    lr_a, lr_b = (x["optimizer_state_dict"]["param_groups"][0]["lr"] for x in (a, b))
    assert lr_a == lr_b
    # the logged episode rewards go on too: sums of the running episodes, windows of the finished ones
    log_a, log_b = a["episode_log_state"], b["episode_log_state"]
    assert torch.equal(log_a["reward_sum"], log_b["reward_sum"]) and log_a["reward_sum"].abs().sum() > 0
    assert torch.equal(log_a["length"], log_b["length"])
    assert log_a["rewards"] == log_b["rewards"] and log_a["lengths"] == log_b["lengths"]
    # control: the same resume with the envs restarting their episodes is *not* the same run
    control = make_runner(tiny(tmp_path / "c", steps=5, algo=algo, **over), None)
    control.load(
        resume,
        load_cfg={
            "actor": True,
            "critic": True,
            "optimizer": True,
            "iteration": True,
            "env_run_state": False,
        },
    )
    control.learn(2)
    weights = control.alg.get_policy().state_dict()
    assert not all(torch.equal(v, weights[k]) for k, v in a["actor_state_dict"].items())


def test_a_running_state_from_another_env_version_or_backend_is_refused_with_a_warning():
    """A running state saved by the numpy env (before the GPU backend: no format mark) or by another
    backend cannot be restored into this env: it is skipped with a warning, the episodes restart."""
    from lasmp.config.base import build_env_cfg
    from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
    from lasmp.envs.moving_platform.env import MovingPlatformEnv

    def make(seed):
        return MovingPlatformEnv(
            build_env_cfg({"num_envs": 2, "seed": seed, "sim": {"num_threads": 1}}, schema=MovingPlatformCfg)
        )

    env = make(0)
    env.reset()
    for _ in range(3):
        env.step(torch.zeros(2, 12))
    saved = env.state_dict()
    fresh = make(1)
    fresh.load_state_dict(copy.deepcopy(saved))  # the same format and backend: restored
    assert torch.equal(fresh.sim.qpos, env.sim.qpos) and torch.equal(
        fresh.episode_length_buf, env.episode_length_buf
    )
    for key, value in (("format", None), ("backend", "warp")):
        other = copy.deepcopy(saved)
        if value is None:
            del other["run"][key]
        else:
            other["run"][key] = value
        target = make(1)
        with pytest.warns(UserWarning, match="saved by another env"):
            target.load_state_dict(other)
        assert not torch.equal(target.sim.qpos, env.sim.qpos)  # not restored
