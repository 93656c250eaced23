"""Sizes that cannot fit in memory, refused up front with the estimate and the limit they meet.

Every limit counts (`lasmp.io.memory.available_memory`): the machine's free memory, this process's
`ulimit -v` (RLIMIT_AS) and each cgroup limit along its path (v2 memory.max, v1 memory.limit_in_bytes).
Every size counts too: a training's envs, their rollout storage (runner.num_steps_per_env), their
observation history, the networks and the validation env (`lasmp.cli.resources.memory_need`); a
trajectory set's rows (`python -m lasmp.envs.trajectories ... --num N`).

The limits are lowered in a child process (RLIMIT_AS) or given as mocked cgroup files."""

from __future__ import annotations

import json
import subprocess
import sys
from functools import cache

import pytest
from badkit import ROOT, call, refused
from hydra import compose, initialize_config_dir

from lasmp.cli.resources import check_memory, memory_need
from lasmp.config.checks import ConfigError
from lasmp.config.train import TrainCfg, to_train_cfg
from lasmp.envs.trajectories.cli import main as trajectories_main
from lasmp.io.memory import available_memory

GiB = 1 << 30


@cache
def config(*overrides: str) -> TrainCfg:
    with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
        return to_train_cfg(compose("config", overrides=list(overrides)))


def machine_has(n_bytes: int) -> bool:
    found = available_memory()
    return found is not None and found[0] > n_bytes


def mocked_cgroup(tmp_path, lines: str, files: dict[str, str]):
    """A cgroup tree under tmp_path/cgroup with `files` (path -> content), and a /proc/self whose
    `cgroup` file holds `lines`: the arguments of available_memory."""
    root, proc = tmp_path / "cgroup", tmp_path / "proc"
    proc.mkdir()
    (proc / "cgroup").write_text(lines)
    for path, content in files.items():
        (root / path).parent.mkdir(parents=True, exist_ok=True)
        (root / path).write_text(content)
    return root, proc


# -- cgroups -------------------------------------------------------------------------------------
def test_a_cgroup_v2_limit_above_the_process_own_cgroup_is_read_less_its_usage(tmp_path):
    if not machine_has(3 * GiB):
        pytest.skip("the machine itself has less than the mocked limit")
    root, proc = mocked_cgroup(
        tmp_path,
        "0::/a/b\n",
        {
            "memory.max": "max",
            "a/memory.max": "3000000000",
            "a/memory.current": "1000000000",
            "a/b/memory.max": "max",
        },
    )
    left, source = available_memory(root, proc)
    assert left == 2_000_000_000 and str(root / "a" / "memory.max") in source and "in use" in source


def test_a_cgroup_v1_memory_limit_is_read_from_the_memory_hierarchy(tmp_path):
    if not machine_has(3 * GiB):
        pytest.skip("the machine itself has less than the mocked limit")
    root, proc = mocked_cgroup(
        tmp_path,
        "4:memory:/job\n1:cpu:/other\n0::/\n",
        {
            "memory/memory.limit_in_bytes": "9223372036854771712",  # v1's "no limit"
            "memory/job/memory.limit_in_bytes": "1500000000",
            "memory/job/memory.usage_in_bytes": "500000000",
        },
    )
    left, source = available_memory(root, proc)
    assert left == 1_000_000_000 and "memory.limit_in_bytes" in source


def test_sixty_thousand_envs_under_a_3_gb_cgroup_are_refused_naming_the_limit(tmp_path):
    """A check that read the machine's free memory alone would pass this, and MuJoCo would then fail."""
    root, proc = mocked_cgroup(tmp_path, "0::/\n", {"memory.max": str(3 * 10**9), "memory.current": "0"})
    cfg = config("env.num_envs=60000")
    with pytest.raises(ConfigError) as err:
        check_memory(cfg, available=available_memory(root, proc))
    message = str(err.value)
    assert "env.num_envs=60000 cannot fit in memory" in message and str(root / "memory.max") in message
    assert "Give env.num_envs=" in message


# -- every size counts ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("key", "big"),
    [
        ("runner.num_steps_per_env", "2000"),
        ("env.observations.history_length", "500"),
        ("policy.actor_hidden_dims", "[4096,4096,4096,4096]"),
        ("runner.validation_episodes", "2000"),
    ],
)
def test_each_size_setting_counts_in_the_memory_estimate(key, big):
    base = config("env.num_envs=64")
    grown = config("env.num_envs=64", f"{key}={big}")
    assert memory_need(grown).total > 2 * memory_need(base).total
    limit = (2 * memory_need(base).total, "a mocked limit")
    check_memory(base, available=limit)  # fits
    with pytest.raises(ConfigError, match="cannot fit in memory.*a mocked limit"):
        check_memory(grown, available=limit)


def test_the_estimate_counts_each_process_of_a_torchrun_job():
    cfg = config("env.num_envs=64")
    one, four = memory_need(cfg, 1), memory_need(cfg, 4)
    assert four.envs == 4 * one.envs and four.networks == 4 * one.networks
    with pytest.raises(ConfigError, match=r"x 4 processes cannot fit"):
        check_memory(cfg, 4, available=(2 * one.total, "a mocked limit"))


@pytest.mark.parametrize("task", ["moving_platform", "rough_static"])
def test_an_env_hands_its_model_and_widths_to_the_memory_check_before_it_allocates_its_envs(
    task, monkeypatch
):
    """`lasmp.cli.build.make_env`: the check sees the model the env is built on and the widths it
    declares, the same figures the check makes alone, and a refusal stops the build before the backend
    allocates anything."""
    import mujoco

    import lasmp.envs.base_env
    from lasmp.envs import registry

    cfg = config(f"task={task}", "env.num_envs=3")
    env_class = registry.env_class(task)
    seen = []

    def refuse(model, widths):
        seen.append((mujoco.MjData(model).nbuffer, widths))
        raise ConfigError("refused by the check")

    def no_backend(*_, **__):
        raise AssertionError("the envs' data were allocated before the memory check")

    monkeypatch.setattr(lasmp.envs.base_env, "make_backend", no_backend)
    with pytest.raises(ConfigError, match="refused by the check"):
        registry.make_env(task, cfg.env, check_fit=refuse)
    alone = (mujoco.MjData(env_class.build_model(cfg.env)).nbuffer, env_class.observation_widths(cfg.env))
    assert seen == [alone]
    model, widths = env_class.build_model(cfg.env), env_class.observation_widths(cfg.env)
    assert memory_need(cfg, built=(model, widths)) == memory_need(cfg)


# -- this process's own limit (ulimit -v) --------------------------------------------------------
UNDER_RLIMIT_AS = """
import json, resource, sys
from hydra import compose, initialize_config_dir
from lasmp.config.train import register_configs, to_train_cfg
from lasmp.cli.resources import check_memory
root, what = sys.argv[1], sys.argv[2]

def held():
    return int([l for l in open("/proc/self/status") if l.startswith("VmSize")][0].split()[1]) * 1024

if what == "train":
    register_configs()
    with initialize_config_dir(config_dir=root + "/cfg", version_base="1.3"):
        cfg = to_train_cfg(compose("config", overrides=["env.num_envs=60000"]))
    resource.setrlimit(resource.RLIMIT_AS, (held() + 3 * 2**30, resource.RLIM_INFINITY))  # 3 GiB to go
    try:
        check_memory(cfg)
        print(json.dumps({"refused": None}))
    except Exception as err:
        print(json.dumps({"refused": f"{type(err).__name__}: {err}"}))
else:
    from lasmp.envs.trajectories.cli import main
    resource.setrlimit(resource.RLIMIT_AS, (held() + 2**30, resource.RLIM_INFINITY))  # 1 GiB to go
    sys.exit(main(["generate", "--num", "400000", "--out", sys.argv[3]]))
"""


def under_rlimit_as(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", UNDER_RLIMIT_AS, str(ROOT), *args], capture_output=True, text=True, timeout=300
    )


def test_sixty_thousand_envs_under_a_lowered_ulimit_v_are_refused_naming_it():
    run = under_rlimit_as("train")
    assert run.returncode == 0, run.stderr[-2000:]
    refused = json.loads(run.stdout.strip().splitlines()[-1])["refused"]
    assert refused and refused.startswith("ConfigError: env.num_envs=60000 cannot fit in memory"), refused
    assert "`ulimit -v` (RLIMIT_AS)" in refused


def test_a_trajectory_set_under_a_lowered_ulimit_v_is_refused_before_sampling(tmp_path):
    out = tmp_path / "set.npz"
    run = under_rlimit_as("trajectories", str(out))
    assert run.returncode == 2, run.stderr[-2000:]
    errors = [line for line in run.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "--num 400000" in errors[0] and "RLIMIT_AS" in errors[0], run.stderr
    assert "Traceback" not in run.stderr and not out.exists()


# -- a trajectory set larger than the machine ----------------------------------------------------
def test_a_hundred_million_trajectories_are_refused_up_front_with_the_estimate(tmp_path):
    """Unchecked, numpy would try to allocate 71.5 GiB for the waypoints alone, then fail."""
    out = tmp_path / "set.npz"
    result = call(trajectories_main, ["generate", "--num", "100000000", "--out", str(out)])
    refused(result, r"--num 100000000: sampling 100,000,000 trajectories needs at least \d", "per trajectory")
    lines = [line for line in result.text.splitlines() if line.startswith("error:")]
    assert result.code == 2 and len(lines) == 1 and "is available" in lines[0] and "Give --num" in lines[0]
    assert not out.exists()


def test_a_trajectory_set_that_fits_is_still_generated(tmp_path):
    out = tmp_path / "set.npz"
    result = call(trajectories_main, ["generate", "--num", "100", "--out", str(out)])
    assert result.code == 0 and out.exists(), result.text
