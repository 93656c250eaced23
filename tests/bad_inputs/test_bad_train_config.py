"""train.py at start-up: a config typo or an out-of-range value, a device the machine lacks, a
trajectory file it cannot read; and the real train.py printing a typo (Hydra's error printing)."""

from __future__ import annotations

import pytest
import torch
from badkit import files, refused, tiny, train, train_py

# -- config --------------------------------------------------------------------------------------
CONFIG_CASES = {
    "typo in an env key": (["env.num_env=8"], "num_env"),
    "typo in a runner key": (["runner.max_iteration=3"], "max_iteration"),
    "typo in an algo key": (["algo.learning_rat=0.001"], "learning_rat"),
    "typo in a policy key": (["policy.actor_hidden_dim=[32]"], "actor_hidden_dim"),
    "an appended unknown key": (["+foo=1"], "foo"),
    "an appended unknown env key": (["+env.bogus=1"], "bogus"),
    "a string for an integer": (["env.num_envs=abc"], "num_envs"),
    "a string for a float": (["algo.gamma=high"], "gamma"),
    "a string for the seed": (["seed=abc"], "seed"),
    "no envs": (["env.num_envs=0"], "env.num_envs"),
    "negative envs": (["env.num_envs=-4"], "env.num_envs"),
    "zero learning rate": (["algo.learning_rate=0"], "algo.learning_rate"),
    "negative learning rate": (["algo.learning_rate=-1"], "algo.learning_rate"),
    "zero estimator learning rate": (["algo.estimator_learning_rate=0"], "algo.estimator_learning_rate"),
    "gamma above 1": (["algo.gamma=1.5"], "algo.gamma"),
    "negative lambda": (["algo.lam=-0.1"], "algo.lam"),
    "zero clip": (["algo.clip_param=0"], "algo.clip_param"),
    "zero grad norm": (["algo.max_grad_norm=0"], "algo.max_grad_norm"),
    "negative ROA lambda": (["algo.roa_lambda=-1"], "algo.roa_lambda"),
    "no mini-batches": (["algo.num_mini_batches=0"], "algo.num_mini_batches"),
    "no epochs": (["algo.num_learning_epochs=0"], "algo.num_learning_epochs"),
    "no estimator epochs": (["algo.estimator_epochs=0"], "algo.estimator_epochs"),
    "negative estimate schedule": (["algo.estimate_rollout_every=-1"], "algo.estimate_rollout_every"),
    "unknown precision": (["algo.precision=fp16"], "algo.precision"),
    "no steps per env": (["runner.num_steps_per_env=0"], "runner.num_steps_per_env"),
    "no save interval": (["runner.save_interval=0"], "runner.save_interval"),
    "unknown logger": (["runner.logger=mlflow"], "runner.logger"),
    "negative iterations": (["runner.max_iterations=-1"], "max_iterations"),
    "fault fraction above 1": (["runner.max_fault_fraction=1.5"], "runner.max_fault_fraction"),
    "negative fault fraction": (["runner.max_fault_fraction=-0.1"], "runner.max_fault_fraction"),
    "fewer samples than mini-batches": (
        ["env.num_envs=1", "runner.num_steps_per_env=1", "algo.num_mini_batches=4"],
        "algo.num_mini_batches",
    ),
    "unknown explicit estimates": (["policy.explicit=some"], "policy.explicit"),
    "alignment without the platform estimates": (["policy.explicit=none"], "policy.use_alignment"),
    "no latent": (["policy.latent_dim=0"], "policy.latent_dim"),
    "zero action noise": (["policy.init_noise_std=0"], "policy.init_noise_std"),
    "unknown device": (["device=tpu"], "device"),
    "unknown task": (["task=flying"], "flying"),
    "unknown policy group": (["policy=nonexistent"], "nonexistent"),
    "unknown preset": (["preset=huge"], "huge"),
    "unknown backend": (["env.backend=gpu"], "env.backend"),
    "physics step too long": (["env.sim.dt_s=0.1"], "env.sim.dt_s"),
    "zero physics step": (["env.sim.dt_s=0"], "env.sim.dt_s"),
    "no decimation": (["env.sim.decimation=0"], "env.sim.decimation"),
    "unknown friction cone": (["env.sim.cone=round"], "env.sim.cone"),
    "no history": (["env.observations.history_length=0"], "env.observations.history_length"),
    "zero action scale": (["env.control.action_scale=0"], "env.control.action_scale"),
    "negative trunk mass range": (["env.domain_rand.train.trunk_mass_kg=[-1,2]"], "trunk_mass_kg"),
    "reversed friction range": (["env.domain_rand.train.foot_friction=[2,1]"], "foot_friction"),
    "unknown randomization split": (["env.domain_rand.split=val"], "env.domain_rand.split"),
    "unknown reward term": (["+env.rewards.weights.bogus=1"], "bogus"),
    "negative reward sigma": (["env.rewards.sigma_center_m=-1"], "env.rewards.sigma_center_m"),
    "unknown spline kind": (["env.trajectory.kind=bezier"], "env.trajectory.kind"),
    "zero trajectory duration": (["env.trajectory.duration_s=0"], "env.trajectory.duration_s"),
    "curriculum levels reversed": (["env.curriculum.level_min=20"], "env.curriculum"),
    "negative platform mass": (["env.platform.mass_kg=-1"], "env.platform.mass_kg"),
    "feet far above the platform": (["env.init_state.foot_clearance_m=1"], "foot_clearance_m"),
    "negative joint speed limit": (["env.termination.max_joint_vel_rad_s=-1"], "max_joint_vel_rad_s"),
    # one rule for every seed (lasmp.io.inputs.check_seed), before any env is built (T03, T04)
    "a negative seed": (["seed=-1"], r"seed must be an integer in \[0, 2\*\*32 - 1\], got -1"),
    "a seed of 2**64": (["seed=18446744073709551616"], r"seed must be an integer in \[0, 2\*\*32 - 1\]"),
    "a seed just past 2**32 - 1": (["seed=4294967296"], r"seed must be an integer"),
}


@pytest.mark.parametrize("case", sorted(CONFIG_CASES))
def test_a_config_typo_or_out_of_range_value_fails_at_start_up_naming_the_key(tmp_path, case):
    overrides, pattern = CONFIG_CASES[case]
    run = tmp_path / "run"
    out = train(tiny(*overrides, f"runner.log_dir={run}"))
    refused(out, pattern)
    assert not run.exists()  # nothing was started


def test_cuda_without_a_cuda_device_fails_at_start_up_naming_it(tmp_path):
    if torch.cuda.is_available():
        pytest.skip("this machine has a CUDA device")
    out = train(tiny("device=cuda", f"runner.log_dir={tmp_path / 'run'}"))
    refused(out, "CUDA")
    assert files(tmp_path / "run") == {}


def test_an_env_count_that_cannot_fit_in_memory_is_refused_up_front_with_its_estimate(tmp_path):
    """T02: a million envs of 1,000-step rollouts (terabytes); refused in seconds, before any of them is
    allocated, with the estimate. (A billion is refused by env.num_envs's range: test_bad_setting_ranges.)"""
    run = tmp_path / "run"
    out = train(tiny("env.num_envs=1000000", "runner.num_steps_per_env=1000", f"runner.log_dir={run}"))
    refused(out, r"env\.num_envs=1000000 cannot fit in memory", r"needs at least \d", "per env", "available")
    assert not run.exists()


MEASURE_ENV_GROWTH = """
import dataclasses, json, os, sys
from hydra import compose, initialize_config_dir
from lasmp.cli.build import make_env
from lasmp.config.train import register_configs, to_train_cfg
from lasmp.cli.resources import env_bytes

def resident():
    return int(open("/proc/self/statm").read().split()[1]) * os.sysconf("SC_PAGE_SIZE")

root, overrides = sys.argv[1], json.loads(sys.argv[2])
register_configs()  # the schemas cfg/config.yaml composes (train.py registers them at its start)
with initialize_config_dir(config_dir=root + "/cfg", version_base="1.3"):
    cfg = to_train_cfg(compose("config", overrides=overrides))
warm = make_env(dataclasses.replace(cfg, env=dataclasses.replace(cfg.env, num_envs=1)))  # imports, warm-up
del warm
before = resident()
env = make_env(dataclasses.replace(cfg, env=dataclasses.replace(cfg.env, num_envs=257)))
grown = (resident() - before) / 256
print(json.dumps({"grown": grown, **env_bytes(cfg)}))
"""


def test_the_memory_estimate_is_a_lower_bound_of_what_the_envs_take():
    """The estimate only refuses what cannot fit: it must not exceed the memory envs really take
    (measured: the resident growth of building 256 envs, per env). Measured in a fresh interpreter:
    inside the test session, pages freed by earlier tests are reused and the growth reads low."""
    import json
    import subprocess
    import sys

    from badkit import ROOT

    run = subprocess.run(
        [sys.executable, "-c", MEASURE_ENV_GROWTH, str(ROOT), json.dumps(tiny())],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    parts = json.loads(run.stdout.strip().splitlines()[-1])
    assert parts["physics"] > 10_000 and parts["observation"] > 0 and parts["rollout storage"] > 0
    assert parts["physics"] + parts["observation"] < parts["grown"]  # one env holds at most what it takes


# -- a trajectory file given to training ---------------------------------------------------------
def test_a_bad_trajectory_file_given_to_training_is_refused_with_one_message(tmp_path):
    run = tmp_path / "run"
    out = train(tiny(f"env.trajectory.file={tmp_path / 'nope.npz'}", f"runner.log_dir={run}"))
    refused(out, "nope.npz")
    assert not list(run.glob("model_*.pt")) and not (run / "config.yaml").exists()


# -- the real CLI --------------------------------------------------------------------------------
def test_train_py_prints_a_config_typo_without_a_traceback(tmp_path):
    proc = train_py(["env.num_env=3"], tmp_path)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode != 0 and "num_env" in err and "Traceback" not in out + err
