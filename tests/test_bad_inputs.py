"""The bad-input matrix (issue 25): what a hostile file or a hurried user gives the tools.

Each case asserts a clear error (exit code != 0, a message that names the problem, no traceback) or
the correct behaviour, and that nothing was lost (the files already there are unchanged). Groups:
config, checkpoints given to resume, resume overrides, run directories, faults, interruption, full
disk, the checkpoint tool's output paths, evaluation inputs and outputs, trajectory and benchmark
files. Most cases call the entry points in this process (`lasmp.train.main` after Hydra's
composition, `lasmp.algo.checkpoint.main`, `lasmp.eval.cli.main`); a few run the real CLI where only
it shows the behaviour (Hydra's error printing, signals, another process holding a run's lock).
"""

from __future__ import annotations

import contextlib
import errno
import io
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import traceback
import warnings
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_dir
from hydra.errors import CompactHydraException
from omegaconf import OmegaConf
from testkit import hostile_checkpoint

from lasmp.algo import checkpoint as ckpt_tool
from lasmp.algo.runner import LasmpRunner
from lasmp.envs import trajectories as trj
from lasmp.eval import benchmark as bm
from lasmp.train_cfg import register_configs

ROOT = Path(__file__).resolve().parents[1]
register_configs()

# a tiny run: 4 envs, small networks, the float32 learner (no compilation), one iteration
TINY = {
    "env.num_envs": "4",
    "runner.num_steps_per_env": "5",
    "runner.save_interval": "1",
    "runner.max_iterations": "1",
    "policy.actor_hidden_dims": "[32,32,32]",
    "policy.critic_hidden_dims": "[32,32]",
    "algo.num_mini_batches": "2",
    "algo.num_learning_epochs": "1",
    "algo.precision": "float32",
    "torch_threads": "1",
}


def tiny(*overrides: str) -> list[str]:
    """TINY with `overrides` (key=value) replacing or adding keys."""
    keys = dict(TINY)
    for o in overrides:
        key, value = o.split("=", 1)
        keys[key] = value
    return [f"{k}={v}" for k, v in keys.items()]


@dataclass
class Outcome:
    code: int
    text: str  # stdout and stderr


def call(fn, *args) -> Outcome:
    """Run fn(*args) as a process would: its return value or SystemExit is the exit code; an exception
    escaping it is printed as the interpreter prints it (a traceback), exit code 1."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = fn(*args) or 0
        except SystemExit as stop:
            code = stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 1)
        except Exception:
            traceback.print_exc(file=err)
            code = 1
    return Outcome(code, out.getvalue() + err.getvalue())


def _entry(cfg, overrides: list[str]) -> int:
    """What train.py does with a composed config."""
    import lasmp.train as lt

    if hasattr(lt, "main"):
        return lt.main(cfg, overrides)
    # train.py as it was before issue 25
    from lasmp.algo.checkpoint import CheckpointError
    from lasmp.algo.runner import TrainingInterrupted
    from lasmp.config import ConfigError

    try:
        lt.train(cfg)
    except TrainingInterrupted as stop:
        return 128 + stop.signum
    except (CheckpointError, ConfigError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0


def train(overrides: list[str]) -> Outcome:
    """`python train.py OVERRIDES` in this process: Hydra's composition (its errors printed as Hydra
    prints them), then the entry point."""

    def run():
        with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
            try:
                cfg = compose("config", overrides=overrides)
            except CompactHydraException as err:
                print(err, file=sys.stderr)
                if isinstance(err.__cause__, Exception):
                    print(err.__cause__, file=sys.stderr)
                return 1
            return _entry(cfg, overrides)

    return call(run)


def files(d: Path) -> dict[str, bytes]:
    """Every file under d (relative path -> bytes); {} if d does not exist."""
    if not d.exists():
        return {}
    if d.is_file():
        return {d.name: d.read_bytes()}
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


def refused(out: Outcome, *patterns: str) -> None:
    """A clear error: exit code != 0, no traceback, and each pattern found in the output."""
    assert out.code != 0, out.text[-3000:]
    assert "Traceback" not in out.text, out.text[-3000:]
    for pattern in patterns:
        assert re.search(pattern, out.text), f"{pattern!r} not in:\n{out.text[-3000:]}"


def succeeded(out: Outcome) -> None:
    assert out.code == 0, out.text[-3000:]
    assert "Traceback" not in out.text, out.text[-3000:]


def progress_lines(out: Outcome) -> list[str]:
    return [line for line in out.text.splitlines() if line.startswith("it ")]


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a default run directory (logs/...) lands here


@pytest.fixture(scope="module")
def base_run(tmp_path_factory) -> Path:
    """A finished tiny run: config.yaml, model_0.pt, model_1.pt."""
    run = tmp_path_factory.mktemp("base") / "run"
    out = train(tiny("runner.max_iterations=2", f"runner.log_dir={run}"))
    succeeded(out)
    assert (run / "model_1.pt").exists() and (run / "config.yaml").exists()
    return run


@pytest.fixture
def run_copy(base_run, tmp_path) -> Path:
    dst = tmp_path / "run"
    shutil.copytree(base_run, dst)
    return dst


def latest(run: Path) -> Path:
    return max(run.glob("model_*.pt"), key=lambda p: int(p.stem.split("_")[1]))


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


# -- checkpoints given to resume -----------------------------------------------------------------
def _saved(good: Path) -> dict:
    return torch.load(good, weights_only=True)


def _edit(change):
    def make(good: Path, dst: Path) -> Path:
        data = _saved(good)
        change(data)
        torch.save(data, dst)
        return dst

    return make


def _first_tensor(data, key):
    return next(iter(data[key].values()))


def _write(content: bytes):
    def make(good: Path, dst: Path) -> Path:
        dst.write_bytes(content)
        return dst

    return make


def _not_torch_zip(good: Path, dst: Path) -> Path:
    with zipfile.ZipFile(dst, "w") as z:
        z.writestr("notes.txt", "not a checkpoint")
    return dst


def _truncated(good: Path, dst: Path) -> Path:
    dst.write_bytes(good.read_bytes()[:2000])
    return dst


def _missing(good: Path, dst: Path) -> Path:
    return dst


def _empty_dir(good: Path, dst: Path) -> Path:
    return dst.parent


def _hostile(good: Path, dst: Path) -> Path:
    return hostile_checkpoint(dst, dst.parent.parent / "marker")


def _policy_only(good: Path, dst: Path) -> Path:
    return ckpt_tool.policy_checkpoint(good, dst)


def _nan_weight(data):
    _first_tensor(data, "actor_state_dict").view(-1)[0] = float("nan")


def _wrong_shape(data):
    key = next(iter(data["actor_state_dict"]))
    data["actor_state_dict"][key] = torch.zeros(3)


def _missing_weight(data):
    data["actor_state_dict"].pop(next(iter(data["actor_state_dict"])))


def _optimizer_mismatch(data):
    data["optimizer_state_dict"]["param_groups"][0]["params"] = [0]


def _run_state_other_size(data):
    data["env_state"]["run"]["num_envs"] = 8


def _run_state_lacking(data):
    data["env_state"]["run"]["attrs"].pop("history")


def _bad_rng(data):
    data["rng_state"]["torch"] = torch.zeros(3)


def _config_unknown_key(data):
    data["config"]["env"]["bogus"] = 1


def _pop(key):
    return lambda data: data.pop(key)


CHECKPOINT_CASES = {
    "a missing file": (_missing, "does not exist"),
    "an empty run directory": (_empty_dir, "no checkpoint"),
    "an empty file": (_write(b""), "unreadable"),
    "a text file": (_write(b"hello, I am not a checkpoint\n" * 10), "unreadable"),
    "a zip that is not a torch file": (_not_torch_zip, "unreadable"),
    "a truncated checkpoint": (_truncated, "unreadable"),
    "a torch file holding a list": (
        lambda good, dst: torch.save([1, 2], dst) or dst,
        "not a lasmp checkpoint",
    ),
    "a dict without the format": (_edit(_pop("format")), "not a lasmp checkpoint"),
    "another format version": (
        _edit(lambda d: d.update(format="lasmp-checkpoint-v0")),
        "not a lasmp checkpoint",
    ),
    "no actor weights": (_edit(_pop("actor_state_dict")), "lacks 'actor_state_dict'"),
    "no observation layout": (_edit(_pop("obs_layout")), "lacks 'obs_layout'"),
    "no config": (_edit(_pop("config")), "lacks 'config'"),
    "no iteration": (_edit(_pop("iter")), "lacks 'iter'"),
    "an iteration that is not a number": (_edit(lambda d: d.update(iter="five")), "iter"),
    "a hostile payload": (_hostile, "pickled Python objects"),
    "a policy checkpoint": (_policy_only, "policy checkpoint"),
    "a NaN weight": (_edit(_nan_weight), "non-finite"),
    "another observation layout": (_edit(lambda d: d["obs_layout"].update(history=[15, 44])), "'history'"),
    "another action size": (_edit(lambda d: d.update(num_actions=8)), "actions"),
    "a weight of another shape": (_edit(_wrong_shape), "size mismatch"),
    "a missing weight": (_edit(_missing_weight), "[Mm]issing key"),
    "an optimizer of another layout": (_edit(_optimizer_mismatch), "optimizer"),
    "a running state for another number of envs": (_edit(_run_state_other_size), "resume_drop_env_state"),
    "a running state lacking a buffer": (_edit(_run_state_lacking), "running state"),
    "a corrupt random state": (_edit(_bad_rng), "random state"),
    "a config this code cannot rebuild": (_edit(_config_unknown_key), "bogus"),
}


@pytest.mark.parametrize("case", sorted(CHECKPOINT_CASES))
def test_a_bad_checkpoint_given_to_resume_is_refused_and_nothing_is_written(base_run, tmp_path, case):
    make, pattern = CHECKPOINT_CASES[case]
    bad_dir = tmp_path / "bad"
    bad_dir.mkdir()
    given = make(base_run / "model_1.pt", bad_dir / "model_5.pt")
    before = files(bad_dir)
    out = train(tiny(f"resume={given}", f"runner.log_dir={bad_dir}"))
    refused(out, pattern)
    assert files(bad_dir) == before
    assert not (tmp_path / "marker").exists()  # no payload ran


def test_a_bad_latest_checkpoint_of_a_run_is_refused_and_the_run_is_left_as_it_was(run_copy):
    (run_copy / "model_2.pt").write_bytes((run_copy / "model_1.pt").read_bytes()[:3000])
    before = files(run_copy)
    out = train(tiny(f"resume={run_copy}"))
    refused(out, "unreadable", "model_2.pt")
    assert files(run_copy) == before


# -- resume overrides ----------------------------------------------------------------------------
RESUME_REFUSED = {
    "more envs without dropping their state": (["env.num_envs=8"], "resume_drop_env_state"),
    "other actor layers": (["policy.actor_hidden_dims=[16,16,16]"], "policy.actor_hidden_dims"),
    "another activation": (["policy.activation=tanh"], "policy.activation"),
    "another initial action noise": (["policy.init_noise_std=0.7"], "policy.init_noise_std"),
    "another seed": (["seed=7"], "seed"),
    "another task": (["task=rough_static"], "task"),
    "another observation history": (["env.observations.history_length=15"], "history"),
}


@pytest.mark.parametrize("case", sorted(RESUME_REFUSED))
def test_a_resume_override_that_cannot_take_effect_is_refused_and_the_run_is_left_as_it_was(run_copy, case):
    overrides, pattern = RESUME_REFUSED[case]
    before = files(run_copy)
    out = train(tiny(*overrides, f"resume={run_copy}", f"runner.log_dir={run_copy}"))
    refused(out, pattern)
    assert files(run_copy) == before


def test_more_envs_on_resume_with_the_option_to_drop_their_state_trains_on(run_copy):
    out = train(tiny("env.num_envs=8", "resume_drop_env_state=true", f"resume={run_copy}"))
    succeeded(out)
    assert latest(run_copy).name == "model_2.pt"
    assert OmegaConf.load(run_copy / "config.yaml").env.num_envs == 8


def test_a_new_learning_rate_on_resume_is_applied_not_ignored(run_copy):
    out = train(tiny("algo.schedule=fixed", "algo.learning_rate=0.0005", f"resume={run_copy}"))
    succeeded(out)
    saved = torch.load(latest(run_copy), weights_only=True)
    assert saved["optimizer_state_dict"]["param_groups"][0]["lr"] == pytest.approx(0.0005)
    assert OmegaConf.load(run_copy / "config.yaml").algo.learning_rate == pytest.approx(0.0005)


def test_a_new_learning_rate_under_the_adaptive_schedule_is_applied_and_said(run_copy):
    out = train(tiny("algo.learning_rate=0.0005", f"resume={run_copy}"))
    succeeded(out)
    assert re.search(r"algo\.learning_rate.*0\.0005", out.text), out.text[-3000:]


def test_a_changed_reward_setting_on_resume_takes_effect_and_is_recorded(run_copy):
    out = train(tiny("env.rewards.sigma_center_m=1.0", f"resume={run_copy}"))
    succeeded(out)
    assert OmegaConf.load(run_copy / "config.yaml").env.rewards.sigma_center_m == 1.0
    assert (
        torch.load(latest(run_copy), weights_only=True)["config"]["env"]["rewards"]["sigma_center_m"] == 1.0
    )


def test_resume_with_the_run_directory_alone_continues_the_runs_own_config(run_copy):
    out = train([f"resume={run_copy}"])  # no other override: the run's 4 envs, small networks, 2 iterations
    succeeded(out)
    assert latest(run_copy).name == "model_3.pt"
    assert OmegaConf.load(run_copy / "config.yaml").env.num_envs == 4


# -- run directories -----------------------------------------------------------------------------
def test_a_new_training_into_a_directory_that_holds_a_run_is_refused_naming_both(run_copy):
    before = files(run_copy)
    out = train(tiny(f"runner.log_dir={run_copy}"))
    refused(out, re.escape(str(run_copy)), "model_1.pt", "resume=")
    assert files(run_copy) == before


@pytest.mark.parametrize("name", ["config.yaml", "model_3.pt"])
def test_a_directory_holding_only_part_of_a_run_is_refused_too(tmp_path, name):
    run = tmp_path / "run"
    run.mkdir()
    (run / name).write_text("from an earlier run")
    out = train(tiny(f"runner.log_dir={run}"))
    refused(out, re.escape(str(run)), re.escape(name))
    assert files(run) == {name: b"from an earlier run"}


def test_a_directory_with_unrelated_files_trains_and_keeps_them(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / "notes.txt").write_text("mine")
    succeeded(train(tiny(f"runner.log_dir={run}")))
    assert (run / "notes.txt").read_text() == "mine" and (run / "model_0.pt").exists()


def test_a_run_directory_that_is_a_file_is_refused_naming_it(tmp_path):
    target = tmp_path / "run"
    target.write_text("a file")
    out = train(tiny(f"runner.log_dir={target}"))
    refused(out, re.escape(str(target)))
    assert target.read_text() == "a file"


def test_a_run_directory_below_a_file_is_refused_naming_it(tmp_path):
    (tmp_path / "afile").write_text("a file")
    out = train(tiny(f"runner.log_dir={tmp_path / 'afile' / 'run'}"))
    refused(out, "afile")
    assert (tmp_path / "afile").read_text() == "a file"


def test_a_second_training_into_a_locked_run_directory_names_the_first_ones_pid(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time\nfrom lasmp.rundir import RunLock\nRunLock(sys.argv[1]).acquire()\n"
            "print('locked', flush=True)\ntime.sleep(120)",
            str(run),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    try:
        line = holder.stdout.readline()
        assert line.strip() == "locked", holder.stderr.read()[-2000:]
        before = files(run)
        out = train(tiny(f"runner.log_dir={run}"))
        refused(out, f"PID {holder.pid}", re.escape(str(run)))
        assert files(run) == before
    finally:
        holder.kill()
        holder.wait(timeout=30)


def test_a_stale_lock_file_of_a_process_that_ended_does_not_block(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / ".lock").write_text("999999\n")
    succeeded(train(tiny(f"runner.log_dir={run}")))
    assert (run / "model_0.pt").exists()


def test_resume_of_a_run_directory_continues_in_it(run_copy, tmp_path):
    out = train(tiny(f"resume={run_copy}"))
    succeeded(out)
    assert latest(run_copy).name == "model_2.pt"
    assert not (tmp_path / "logs").exists()  # no new dated run directory


def test_resume_of_a_checkpoint_file_continues_in_its_directory(run_copy, tmp_path):
    succeeded(train(tiny(f"resume={run_copy / 'model_1.pt'}")))
    assert latest(run_copy).name == "model_2.pt"
    assert not (tmp_path / "logs").exists()


def test_resume_with_the_printed_command_continues_in_the_run_directory(run_copy):
    succeeded(train(tiny(f"resume={run_copy / 'model_1.pt'}", f"runner.log_dir={run_copy}")))
    assert latest(run_copy).name == "model_2.pt"


def test_resume_of_an_older_checkpoint_into_its_own_directory_is_refused(run_copy):
    before = files(run_copy)
    out = train(tiny(f"resume={run_copy / 'model_0.pt'}"))
    refused(out, "model_1.pt", "runner.log_dir")
    assert files(run_copy) == before


def test_resume_into_another_empty_directory_branches_there_and_keeps_the_run(run_copy, tmp_path):
    before = files(run_copy)
    branch = tmp_path / "branch"
    succeeded(train(tiny(f"resume={run_copy}", f"runner.log_dir={branch}")))
    assert latest(branch).name == "model_2.pt"
    assert files(run_copy) == before


def test_resume_into_another_directory_that_holds_a_run_is_refused(run_copy, base_run, tmp_path):
    other = tmp_path / "other"
    shutil.copytree(base_run, other)
    before, before_other = files(run_copy), files(other)
    out = train(tiny(f"resume={run_copy}", f"runner.log_dir={other}"))
    refused(out, re.escape(str(other)))
    assert files(run_copy) == before and files(other) == before_other


def test_a_stale_temporary_file_of_a_killed_save_is_removed_by_the_next_start(run_copy):
    stale = run_copy / ".model_2.pt.k1ll3d.tmp"
    stale.write_bytes(b"PK\x03\x04 half a checkpoint")
    out = train(tiny(f"resume={run_copy}"))
    succeeded(out)
    assert not stale.exists() and "removed" in out.text
    assert not list(run_copy.glob(".*.tmp"))


# -- faults --------------------------------------------------------------------------------------
ALL_FAULT = "env.termination.max_joint_vel_rad_s=1e-9"  # every joint moves faster: every env-step faults


def test_a_run_in_which_every_env_faults_stops_naming_the_cause(tmp_path):
    run = tmp_path / "run"
    out = train(tiny(ALL_FAULT, "runner.max_iterations=3", f"runner.log_dir={run}"))
    refused(out, "fault", "runner.max_fault_fraction")
    assert not list(run.glob("model_*.pt"))  # no checkpoint of the faulting state


def test_a_faulting_run_trains_on_when_the_threshold_allows_it_and_the_progress_line_counts_the_faults(
    tmp_path,
):
    out = train(tiny(ALL_FAULT, "runner.max_fault_fraction=1", f"runner.log_dir={tmp_path / 'run'}"))
    succeeded(out)
    assert "faults 20" in progress_lines(out)[0]  # 4 envs x 5 steps, all faulted


def test_the_progress_line_shows_the_fault_count(tmp_path):
    out = train(tiny(f"runner.log_dir={tmp_path / 'run'}"))
    succeeded(out)
    assert progress_lines(out) and "faults 0" in progress_lines(out)[0]


def test_a_diverging_loss_stops_with_one_message_naming_it(tmp_path, monkeypatch):
    from rsl_rl.algorithms import PPO

    real = PPO.update  # PPO's own update diverges; PPOROA's update, around it, guards it
    monkeypatch.setattr(PPO, "update", lambda self: {**real(self), "value": float("nan")})
    run = tmp_path / "run"
    out = train(tiny(f"runner.log_dir={run}"))
    refused(out, "non-finite loss", "value")
    assert not list(run.glob("model_*.pt"))


# -- interruption --------------------------------------------------------------------------------
def train_py(args: list[str], cwd: Path, **kw) -> subprocess.Popen:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen(
        [sys.executable, str(ROOT / "train.py"), *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=cwd,
        env=env,
        **kw,
    )


def _wait_for(proc: subprocess.Popen, prefix: str, timeout_s: float = 300) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        assert line, f"train.py ended before {prefix!r}: {proc.stderr.read()[-2000:]}"
        if prefix in line:
            return
    raise AssertionError(f"no {prefix!r} within {timeout_s} s")


def test_a_second_sigterm_exits_at_once_without_a_traceback(tmp_path):
    signum, code = signal.SIGTERM, 143
    run = tmp_path / "run"
    # long iterations (2,000 steps each), so that the second signal arrives while the first waits
    proc = train_py(
        tiny(
            "runner.num_steps_per_env=2000",
            "runner.max_iterations=50",
            "runner.save_interval=1000",
            f"runner.log_dir={run}",
        ),
        tmp_path,
    )
    try:
        _wait_for(proc, "training ")
        time.sleep(1.0)
        proc.send_signal(signum)
        _wait_for(proc, "finishing this iteration")
        time.sleep(LasmpRunner.REPEAT_WINDOW_S + 0.5)  # not an echo of the first (torchrun sends two)
        started = time.monotonic()
        proc.send_signal(signum)
        out, err = proc.communicate(timeout=120)
        waited = time.monotonic() - started
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == code, err[-2000:]
    assert "Traceback" not in out + err, err[-2000:]
    assert waited < 30
    assert not list(run.glob("model_*.pt")) and not list(run.glob(".*.tmp"))


def test_a_second_ctrl_c_exits_with_130_and_no_checkpoint(tmp_path):
    """The same handler as SIGTERM's (test above), called as Python calls it on two Ctrl-C."""
    runner = LasmpRunner.__new__(LasmpRunner)  # the handler reads nothing but the signal state
    runner._signal = None

    def twice():
        runner._on_signal(signal.SIGINT, None)
        runner._on_signal(signal.SIGINT, None)  # an echo at once (as torchrun forwards): ignored
        assert runner._signal == signal.SIGINT
        runner._signal_time_s -= LasmpRunner.REPEAT_WINDOW_S + 1.0  # a second Ctrl-C, later
        runner._on_signal(signal.SIGINT, None)

    out = call(twice)
    assert out.code == 130 and "Traceback" not in out.text and "SIGINT again" in out.text


def test_a_save_that_fails_leaves_no_temporary_file(tmp_path, monkeypatch):
    def broken(obj, f):
        f.write(b"PK\x03\x04 partial")
        raise RuntimeError("the writer broke")

    monkeypatch.setattr(torch, "save", broken)
    run = tmp_path / "run"
    out = train(tiny(f"runner.log_dir={run}"))
    assert out.code != 0
    assert not list(run.glob(".*.tmp")) and not list(run.glob("model_*.pt"))


# -- full disk -----------------------------------------------------------------------------------
def _disk_full(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def _one_line_naming(out: Outcome, where: str) -> None:
    refused(out, "No space left on device")
    lines = [line for line in out.text.splitlines() if "No space left on device" in line]
    assert len(lines) == 1 and where in lines[0], out.text[-3000:]


def test_a_full_disk_when_training_starts_gives_one_line_naming_the_file(tmp_path, monkeypatch):
    monkeypatch.setattr(os, "fsync", _disk_full)
    run = tmp_path / "run"
    out = train(tiny(f"runner.log_dir={run}"))
    _one_line_naming(out, str(run))
    assert not list(run.glob(".*.tmp")) and not list(run.glob("model_*.pt"))


def test_a_full_disk_at_a_checkpoint_gives_one_line_naming_it_and_leaves_no_temporary_file(
    tmp_path, monkeypatch
):
    def full(obj, f):
        f.write(b"PK\x03\x04 partial")
        _disk_full()

    monkeypatch.setattr(torch, "save", full)
    run = tmp_path / "run"
    out = train(tiny(f"runner.log_dir={run}"))
    _one_line_naming(out, "model_0.pt")
    assert not list(run.glob(".*.tmp")) and not list(run.glob("model_*.pt"))


def test_a_full_disk_when_writing_a_policy_checkpoint_gives_one_line_naming_it(
    base_run, tmp_path, monkeypatch
):
    monkeypatch.setattr(os, "fsync", _disk_full)
    dst = tmp_path / "policy.pt"
    out = call(ckpt_tool.main, ["policy", str(base_run), str(dst)])
    _one_line_naming(out, str(dst))
    assert not dst.exists() and not list(tmp_path.glob(".*.tmp"))


# -- the checkpoint tool's output paths ----------------------------------------------------------
def test_policy_refuses_to_overwrite_its_own_full_checkpoint(run_copy):
    before = files(run_copy)
    out = call(ckpt_tool.main, ["policy", str(run_copy / "model_1.pt"), str(run_copy / "model_1.pt")])
    refused(out, "model_1.pt", "--force")
    assert files(run_copy) == before


def test_policy_refuses_to_overwrite_another_full_checkpoint(run_copy):
    before = files(run_copy)
    out = call(ckpt_tool.main, ["policy", str(run_copy / "model_1.pt"), str(run_copy / "model_0.pt")])
    refused(out, "model_0.pt", "--force")
    assert files(run_copy) == before


def test_policy_refuses_to_overwrite_an_existing_file(run_copy, tmp_path):
    for name, content in (("notes.txt", None), ("policy.pt", "policy")):
        dst = tmp_path / name
        if content == "policy":
            ckpt_tool.policy_checkpoint(run_copy, dst)
        else:
            dst.write_text("mine")
        before = dst.read_bytes()
        out = call(ckpt_tool.main, ["policy", str(run_copy), str(dst)])
        refused(out, re.escape(name), "--force")
        assert dst.read_bytes() == before


def test_policy_with_force_overwrites_the_full_checkpoint_as_asked(run_copy):
    target = run_copy / "model_1.pt"
    succeeded(call(ckpt_tool.main, ["policy", str(target), str(target), "--force"]))
    assert ckpt_tool.is_policy_only(ckpt_tool.read_checkpoint(target))


def test_policy_of_a_run_directory_writes_a_new_file(base_run, tmp_path):
    dst = tmp_path / "out" / "policy.pt"
    succeeded(call(ckpt_tool.main, ["policy", str(base_run), str(dst)]))
    data = ckpt_tool.read_checkpoint(dst)
    assert ckpt_tool.is_policy_only(data) and data["iter"] == 1


def test_policy_into_a_directory_that_is_a_file_gives_one_line(base_run, tmp_path):
    (tmp_path / "afile").write_text("a file")
    out = call(ckpt_tool.main, ["policy", str(base_run), str(tmp_path / "afile" / "policy.pt")])
    refused(out, "afile")
    assert (tmp_path / "afile").read_text() == "a file"


CHECKPOINT_TOOL_CASES = {
    "policy of a missing file": (
        lambda d: ["policy", str(d / "nope.pt"), str(d / "out.pt")],
        "does not exist",
    ),
    "info of a missing file": (lambda d: ["info", str(d / "nope.pt")], "does not exist"),
    "info of a truncated file": (
        lambda d: ["info", str(_truncated(d / "run" / "model_1.pt", d / "t.pt"))],
        "unreadable",
    ),
    "info of a text file": (lambda d: ["info", str(_write(b"text")(None, d / "t.pt"))], "unreadable"),
    "info of a hostile file": (
        lambda d: ["info", str(hostile_checkpoint(d / "h.pt", d / "marker"))],
        "pickled Python objects",
    ),
    "convert without --trust": (
        lambda d: ["convert", str(d / "run" / "model_1.pt"), str(d / "c.pt")],
        "--trust",
    ),
    "convert onto an existing file": (
        lambda d: ["convert", "--trust", str(d / "run" / "model_1.pt"), str(d / "run" / "model_0.pt")],
        "exists",
    ),
    "convert onto itself": (
        lambda d: ["convert", "--trust", str(d / "run" / "model_1.pt"), str(d / "run" / "model_1.pt")],
        "differ",
    ),
}


@pytest.mark.parametrize("case", sorted(CHECKPOINT_TOOL_CASES))
def test_the_checkpoint_tool_refuses_a_bad_input_with_one_message(run_copy, tmp_path, case):
    argv, pattern = CHECKPOINT_TOOL_CASES[case]
    argv = argv(tmp_path)
    before = files(run_copy)
    out = call(ckpt_tool.main, argv)
    refused(out, pattern)
    assert files(run_copy) == before and not (tmp_path / "marker").exists()
    assert not (tmp_path / "out.pt").exists() and not (tmp_path / "c.pt").exists()


def test_info_of_a_policy_checkpoint_says_so(base_run, tmp_path):
    ckpt_tool.policy_checkpoint(base_run, tmp_path / "p.pt")
    out = call(ckpt_tool.main, ["info", str(tmp_path / "p.pt")])
    succeeded(out)
    assert "policy checkpoint" in out.text


# -- trajectory files ----------------------------------------------------------------------------
def _generated(n: int = 3) -> dict:
    traj = trj.sample(n, trj.ranges_for_split("test"), np.random.default_rng(0))
    return {
        "format": np.array("lasmp-trajectories"),
        "version": np.array(2),
        "kind": np.array("waypoints"),
        **trj.waypoint_arrays(traj),
    }


def _samples(t, poses) -> dict:
    return {
        "format": np.array("lasmp-trajectories"),
        "version": np.array(2),
        "kind": np.array("samples"),
        "t_s": np.asarray(t, dtype=np.float64),
        "poses": np.asarray(poses, dtype=np.float64),
    }


def _line_samples(k: int = 11, duration_s: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, duration_s, k)
    poses = np.zeros((1, k, 6))
    poses[0, :, 0] = 0.1 * t  # 0.1 m/s along x
    poses[0, :, 5] = 0.05 * t
    return t, poses


def _traj_case(kind: str, change=None):
    """A trajectory file: a generated set or a user-made line, its arrays changed by `change`."""

    def make(path: Path) -> Path:
        arrays = _generated() if kind == "waypoints" else _samples(*_line_samples())
        if change is not None:
            change(arrays)
        np.savez(path, **arrays)
        return path

    return make


def _set(**values):
    return lambda a: a.update({k: np.array(v) for k, v in values.items()})


def _times_nan_inside(a):
    a["t_s"][3] = np.nan


def _times_reversed(a):
    a["t_s"][3], a["t_s"][4] = a["t_s"][4], a["t_s"][3]


def _times_late(a):
    a["t_s"] += 1.0


def _pose_start_off(a):
    a["poses"][0, 0, 2] = 0.5


def _pose_inf(a):
    a["poses"][0, 4, 1] = np.inf


def _pose_far(a):
    a["poses"][0, 5, 0] = 1e6  # a waypoint 1,000 km away


def _yaw_many_turns(a):
    a["poses"][0, 5, 5] = 1e4


def _fast_jump(a):
    a["poses"][0, 5:, 0] += 100.0  # 100 m in one second


def _waypoint_far(a):
    a["waypoints"][0, 2, 0] = 1e6


def _path_in_a_tenth(a):
    a["knot_times_s"] = a["knot_times_s"] / 100.0  # the whole 10 s path in 0.1 s


def _count_off(a):
    a["n_waypoints"] = a["n_waypoints"] + 1


def _drop(key):
    return lambda a: a.pop(key)


def _raw(content: bytes):
    def make(path: Path) -> Path:
        path.write_bytes(content)
        return path

    return make


def _truncated_npz(path: Path) -> Path:
    _traj_case("waypoints")(path)
    path.write_bytes(path.read_bytes()[:300])
    return path


def _single_npy(path: Path) -> Path:
    with open(path, "wb") as f:
        np.save(f, np.zeros(3))
    return path


TRAJECTORY_REFUSED = {
    "a missing file": (lambda path: path, "no such trajectory file"),
    "a text file": (_raw(b"x, y, z\n0, 0, 0\n"), "not a readable .npz"),
    "a truncated file": (_truncated_npz, "not a readable .npz"),
    "a single .npy array": (_single_npy, "single .npy"),
    "no format key": (_traj_case("samples", _drop("format")), "missing key 'format'"),
    "another format": (_traj_case("samples", _set(format="something-else")), "format is"),
    "version 1": (_traj_case("waypoints", _set(version=1)), "unsupported version 1"),
    "version 3": (_traj_case("waypoints", _set(version=3)), "unsupported version 3"),
    "an unknown kind": (_traj_case("samples", _set(kind="spline")), "unknown kind"),
    "NaN inside the times": (_traj_case("samples", _times_nan_inside), "NaN"),
    "times out of order": (_traj_case("samples", _times_reversed), "strictly increasing"),
    "times that start late": (_traj_case("samples", _times_late), "start at 0"),
    "a path that starts away from the platform": (_traj_case("samples", _pose_start_off), "initial pose"),
    "an infinite pose": (_traj_case("samples", _pose_inf), "finite"),
    "poses of 5 values": (_traj_case("samples", lambda a: a.update(poses=a["poses"][..., :5])), "poses"),
    "integer times": (_traj_case("samples", lambda a: a.update(t_s=np.arange(11))), "float"),
    "a waypoint count that disagrees": (_traj_case("waypoints", _count_off), "n_waypoints"),
    "an unknown spline": (_traj_case("waypoints", _set(spline="bezier")), "bezier"),
    "meta that is not JSON": (_traj_case("samples", _set(meta_json="{not json")), "meta_json"),
    "no waypoints": (_traj_case("waypoints", _drop("waypoints")), "missing key 'waypoints'"),
    "a sample 1,000 km away": (_traj_case("samples", _pose_far), "physical range"),
    "a waypoint 1,000 km away": (_traj_case("waypoints", _waypoint_far), "physical range"),
    "a yaw of 10,000 rad": (_traj_case("samples", _yaw_many_turns), "physical range"),
}


@pytest.mark.parametrize("case", sorted(TRAJECTORY_REFUSED))
def test_a_bad_trajectory_file_is_refused_naming_the_file_and_the_problem(tmp_path, case):
    make, pattern = TRAJECTORY_REFUSED[case]
    path = make(tmp_path / "traj.npz")
    before = files(tmp_path)
    with pytest.raises(trj.TrajectoryFileError, match=pattern) as err:
        trj.load(path)
    assert str(path) in str(err.value)
    assert files(tmp_path) == before


TRAJECTORY_ABSURD = {
    "a whole generated path in 0.1 s": _traj_case("waypoints", _path_in_a_tenth),
    "a whole user path in 0.1 s": _traj_case(
        "samples", lambda a: a.update(t_s=a["t_s"] / 100.0, poses=a["poses"] * 10.0)
    ),
    "100 m in a second": _traj_case("samples", _fast_jump),
}


@pytest.mark.parametrize("case", sorted(TRAJECTORY_ABSURD))
def test_a_trajectory_far_outside_any_physical_motion_is_refused_or_warned_about(tmp_path, case):
    path = TRAJECTORY_ABSURD[case](tmp_path / "traj.npz")
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        try:
            trj.load(path)
        except trj.TrajectoryFileError as err:
            assert "physical range" in str(err) and str(path) in str(err)
            return
    assert any("physical range" in str(w.message) and str(path) in str(w.message) for w in seen), [
        str(w.message) for w in seen
    ]


@pytest.mark.parametrize("kind", ["a generated set", "a 360 m train ride at 18 m/s"])
def test_a_physical_trajectory_file_loads_without_a_warning(tmp_path, kind):
    path = tmp_path / "traj.npz"
    if kind == "a generated set":
        np.savez(path, **_generated(50))
    else:
        t = np.linspace(0.0, 20.0, 2001)
        poses = np.zeros((1, len(t), 6))
        poses[0, :, 0] = 18.0 * t
        np.savez(path, **_samples(t, poses))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        trj.load(path)


def test_a_bad_trajectory_file_given_to_training_is_refused_with_one_message(tmp_path):
    run = tmp_path / "run"
    out = train(tiny(f"env.trajectory.file={tmp_path / 'nope.npz'}", f"runner.log_dir={run}"))
    refused(out, "nope.npz")
    assert not list(run.glob("model_*.pt")) and not (run / "config.yaml").exists()


# -- benchmark files -----------------------------------------------------------------------------
def _bench_arrays() -> dict:
    bench = bm.generate(4, 2, seed=0)
    path = Path("bench_base.npz")
    bm.save(path, bench)
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    path.unlink()
    return arrays


def _bench_case(change):
    def make(path: Path) -> Path:
        arrays = _bench_arrays()
        change(arrays)
        np.savez(path, **arrays)
        return path

    return make


def _scale(key, value, index=(0,)):
    def change(a):
        a[key] = a[key].copy()
        a[key][index] = value

    return change


BENCHMARK_REFUSED = {
    "a missing file": (lambda path: path, "no such benchmark file"),
    "a text file": (_raw(b"not a benchmark"), "not an .npz"),
    "another format": (_bench_case(lambda a: a.update(format=np.array("lasmp-trajectories"))), "format is"),
    "version 1": (_bench_case(lambda a: a.update(version=np.array(1))), "unsupported version 1"),
    "no joint gains": (_bench_case(lambda a: a.pop("robot_joint_kp")), "missing key 'robot_joint_kp'"),
    "a NaN gain": (_bench_case(_scale("robot_joint_kp", np.nan)), "non-finite"),
    "damping of 11 joints": (
        _bench_case(lambda a: a.update(robot_joint_kd=a["robot_joint_kd"][:, :11])),
        "wrong shape",
    ),
    "a negative trunk mass": (_bench_case(_scale("robot_trunk_mass_kg", -4.0)), "robot_trunk_mass_kg"),
    "a trunk without mass": (_bench_case(_scale("robot_trunk_mass_kg", 0.0)), "robot_trunk_mass_kg"),
    "a trunk of 1,000 t": (_bench_case(_scale("robot_trunk_mass_kg", 1e6)), "robot_trunk_mass_kg"),
    "a negative friction": (_bench_case(_scale("robot_foot_friction", -1.0)), "robot_foot_friction"),
    "a friction of 100": (_bench_case(_scale("robot_foot_friction", 100.0)), "robot_foot_friction"),
    "a centre of mass 3 m off": (_bench_case(_scale("robot_com_shift_m", 3.0, (0, 0))), "robot_com_shift_m"),
    "a negative joint stiffness": (_bench_case(_scale("robot_joint_kp", -40.0, (0, 0))), "robot_joint_kp"),
    "a negative joint damping": (_bench_case(_scale("robot_joint_kd", -1.0, (0, 0))), "robot_joint_kd"),
    "a negative platform stiffness": (
        _bench_case(_scale("robot_platform_kp_factor", -1.0, (0, 0))),
        "robot_platform_kp_factor",
    ),
    "a negative platform damping": (
        _bench_case(_scale("robot_platform_kd_factor", -0.02, (0, 0))),
        "robot_platform_kd_factor",
    ),
    "a waypoint 1,000 km away": (_bench_case(_waypoint_far), "physical range"),
}


@pytest.mark.parametrize("case", sorted(BENCHMARK_REFUSED))
def test_a_bad_benchmark_file_is_refused_naming_the_file_and_the_problem(tmp_path, case):
    make, pattern = BENCHMARK_REFUSED[case]
    path = make(tmp_path / "bench.npz")
    with pytest.raises(bm.BenchmarkFileError, match=pattern) as err:
        bm.load(path)
    assert str(path) in str(err.value)


def test_a_sound_benchmark_file_loads(tmp_path):
    path = _bench_case(lambda a: None)(tmp_path / "bench.npz")
    assert bm.load(path).num_robots == 2


# -- evaluation inputs and outputs ---------------------------------------------------------------
def evaluate(*argv: str) -> Outcome:
    from lasmp.eval import cli

    return call(cli.main, list(argv))


def _stand_still(bench: Path, out_dir: Path, *extra: str) -> Outcome:
    return evaluate(
        "--controller",
        "stand_still",
        "--benchmark",
        str(bench),
        "--num-trajectories",
        "1",
        "--batch-envs",
        "1",
        "--out",
        str(out_dir),
        *extra,
    )


def test_evaluate_refuses_a_benchmark_robot_with_negative_friction_before_playing(tmp_path):
    bench = _bench_case(_scale("robot_foot_friction", -1.0))(tmp_path / "bench.npz")
    out = _stand_still(bench, tmp_path / "eval")
    refused(out, "robot_foot_friction")
    assert files(tmp_path / "eval") == {}  # no results of NaN


@pytest.mark.parametrize("case", ["a missing checkpoint", "a truncated checkpoint", "a hostile checkpoint"])
def test_evaluate_refuses_a_bad_checkpoint_with_one_message(base_run, tmp_path, case):
    path = {
        "a missing checkpoint": lambda: tmp_path / "nope.pt",
        "a truncated checkpoint": lambda: _truncated(base_run / "model_1.pt", tmp_path / "t.pt"),
        "a hostile checkpoint": lambda: hostile_checkpoint(tmp_path / "h.pt", tmp_path / "marker"),
    }[case]()
    bench = _bench_case(lambda a: None)(tmp_path / "bench.npz")
    out = evaluate(
        "--checkpoint",
        str(path),
        "--benchmark",
        str(bench),
        "--num-trajectories",
        "1",
        "--out",
        str(tmp_path / "eval"),
    )
    refused(out, re.escape(path.name))
    assert not (tmp_path / "marker").exists() and files(tmp_path / "eval") == {}


def test_evaluate_refuses_a_bad_trajectory_file_with_one_message(tmp_path):
    bench = _bench_case(lambda a: None)(tmp_path / "bench.npz")
    traj = _traj_case("samples", _pose_far)(tmp_path / "traj.npz")
    out = _stand_still(bench, tmp_path / "eval", "--trajectories", str(traj))
    refused(out, "traj.npz", "physical range")


def test_evaluate_refuses_an_output_path_that_is_a_file_before_playing(tmp_path):
    bench = _bench_case(lambda a: None)(tmp_path / "bench.npz")
    (tmp_path / "eval").write_text("mine")
    started = time.monotonic()
    out = _stand_still(bench, tmp_path / "eval")
    refused(out, "eval")
    assert (tmp_path / "eval").read_text() == "mine"
    assert time.monotonic() - started < 20  # before the episode, not after it


def test_evaluate_never_overwrites_an_earlier_result_silently(tmp_path):
    bench = _bench_case(lambda a: None)(tmp_path / "bench.npz")
    earlier = tmp_path / "eval"
    earlier.mkdir()
    (earlier / "metrics.json").write_text(json.dumps({"method": "earlier"}))
    out = _stand_still(bench, earlier)
    assert (earlier / "metrics.json").read_text() == json.dumps({"method": "earlier"})
    if out.code != 0:
        refused(out, "metrics.json|eval")


# -- the real CLI --------------------------------------------------------------------------------
def test_train_py_prints_a_config_typo_without_a_traceback(tmp_path):
    proc = train_py(["env.num_env=3"], tmp_path)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode != 0 and "num_env" in err and "Traceback" not in out + err


def test_a_training_leaves_the_working_directory_clean_but_for_its_run(tmp_path):
    proc = train_py(tiny("runner.log_dir=run"), tmp_path)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err[-2000:]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]  # no train.log, no outputs/
    assert (tmp_path / "run" / "model_0.pt").exists() and not list((tmp_path / "run").glob(".*"))
