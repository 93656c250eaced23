"""What several test modules build: the tiny training configuration, a hostile checkpoint and the
scripts (bench/, scripts/) loaded as modules.

A plain module (pytest's `pythonpath` puts tests/ on sys.path): `from testkit import tiny`."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import torch
from omegaconf import DictConfig, OmegaConf

from lasmp.algo.checkpoint import CHECKPOINT_FORMAT
from lasmp.config.base import build_env_cfg
from lasmp.config.train import TrainCfg, to_train_cfg
from lasmp.envs import trajectories as trj
from lasmp.envs.moving_platform.cfg import MovingPlatformCfg
from lasmp.envs.moving_platform.env import MovingPlatformEnv
from lasmp.envs.moving_platform.rewards import RewardsCfg
from lasmp.envs.moving_platform.state import StepState

ROOT = Path(__file__).resolve().parents[1]

# 4 envs, small networks, 2 iterations, a checkpoint every iteration
TINY = {
    "env": {"num_envs": 4},
    "runner": {"max_iterations": 2, "save_interval": 1},
    "policy": {"actor_hidden_dims": [32, 32, 32], "critic_hidden_dims": [32, 32]},
    "algo": {"num_mini_batches": 2, "num_learning_epochs": 1},
    "torch_threads": 1,
}


def tiny(
    log_dir: Path | str,
    *,
    steps: int | None = None,
    precision: str | None = None,
    plain: bool = False,
    **over,
) -> TrainCfg | DictConfig:
    """The tiny training logging into `log_dir`, with `over` (e.g. runner={...}, algo={...}, seed=3)
    merged in: a validated TrainCfg, or with `plain` the OmegaConf config before validation.
    `steps` sets runner.num_steps_per_env and `precision` algo.precision; left out, the TrainCfg
    defaults apply."""
    base = {**TINY, "runner": {**TINY["runner"], "log_dir": str(log_dir)}, "algo": dict(TINY["algo"])}
    if steps is not None:
        base["runner"]["num_steps_per_env"] = steps
    if precision is not None:
        base["algo"]["precision"] = precision
    cfg = OmegaConf.merge(OmegaConf.create(base), OmegaConf.create(over))
    return cfg if plain else to_train_cfg(cfg)


class _Payload:
    """Unpickling this writes `marker`: what a hostile checkpoint would do (any code could run)."""

    def __init__(self, marker: Path):
        self.marker = str(marker)

    def __reduce__(self):
        return (exec, (f"open({self.marker!r}, 'w').write('ran')",))


def hostile_checkpoint(path: Path, marker: Path) -> Path:
    """A file that the old loader (weights_only=False) accepted as a checkpoint, with a payload."""
    data = {
        "format": CHECKPOINT_FORMAT,
        "actor_state_dict": {},
        "critic_state_dict": {},
        "config": {},
        "obs_layout": {},
        "num_actions": 12,
        "iter": 0,
        "env_state": {"payload": _Payload(marker)},
    }
    torch.save(data, path)
    return path


def load_script(path: str) -> ModuleType:
    """A script of the repository (`path` from its root, e.g. "bench/friction_cone.py") as a fresh
    module: the scripts are not a package, and each load runs the file anew."""
    folder = str((ROOT / path).parent)  # first on sys.path, as `python SCRIPT` puts it: a script's
    if folder not in sys.path:  # sibling modules (scripts/studylib/) import by their bare names
        sys.path.insert(0, folder)
    spec = importlib.util.spec_from_file_location(Path(path).stem + "_script", ROOT / path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class Study:
    """scripts/study.py and its modules (scripts/studylib/) read as one namespace, as the script was one
    file: `study.result_dir` is plan's, `study.train` runs'. A name is set (monkeypatch.setattr) in the
    module that defines it, where the study's functions read it: `study.plan` (the paths, the budgets),
    `study.runs` (`execute`, `check_learner`), `study.tables`; setting one here is refused, lest it be
    a copy nothing reads. A name no module has (the `study` fixture's `ran`) is kept here."""

    def __init__(self):
        cli = load_script("scripts/study.py")  # which puts scripts/ on sys.path: studylib imports
        self.plan, self.runs, self.tables = (
            importlib.import_module(f"studylib.{name}") for name in ("plan", "runs", "tables")
        )
        self.cli = cli

    def _owner(self, name: str) -> ModuleType | None:
        # the defining module first: runs and tables import from plan, study.py from all three
        modules = (self.plan, self.runs, self.tables, self.cli)
        return next((m for m in modules if name in vars(m)), None)

    def __getattr__(self, name: str):
        owner = None if name in ("plan", "runs", "tables", "cli") else self._owner(name)
        if owner is None:
            raise AttributeError(name)
        return getattr(owner, name)

    def __setattr__(self, name: str, value) -> None:
        if name in ("plan", "runs", "tables", "cli") or self._owner(name) is None:
            object.__setattr__(self, name, value)
        else:
            raise AttributeError(f"set {name} in {self._owner(name).__name__}, where the study reads it")


# the tiny training as train.py's command-line overrides: 4 envs, 15-step episodes (the first end in
# iteration 1), small networks, the float32 learner (no compilation), a checkpoint every iteration
TINY_CLI = (
    "env.num_envs=4",
    "env.trajectory.duration_s=0.3",
    "torch_threads=1",
    "algo.precision=float32",
    "algo.num_mini_batches=2",
    "algo.num_learning_epochs=1",
    "policy.actor_hidden_dims=[32,32,32]",
    "policy.critic_hidden_dims=[32,32]",
    "runner.save_interval=1",
)


def run_script(script: str, *args: str, cwd: Path, ok: bool = True) -> subprocess.CompletedProcess:
    """A script of the repository root (train.py, evaluate.py) run as a user runs it, unbuffered;
    with `ok`, a failure fails the test showing the end of its stderr."""
    out = subprocess.run(
        [sys.executable, str(ROOT / script), *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
        timeout=600,
    )
    assert not ok or out.returncode == 0, out.stderr[-3000:]
    return out


# ---- the moving-platform env (tests/envs/test_env_*.py, tests/envs/test_platform_*.py) ---------------


def platform_env(n=4, **cfg) -> MovingPlatformEnv:
    """A reset env of `n` envs, `cfg` merged into the default env config."""
    env = MovingPlatformEnv(build_env_cfg({"num_envs": n, **cfg}, schema=MovingPlatformCfg))
    env.reset()
    return env


def static_platform(env: MovingPlatformEnv) -> None:
    """Make every later reset use a platform that does not move."""

    def hold(ids):
        return trj.from_samples(np.array([0.0, 10.0]), np.zeros((len(ids), 2, 6))), np.full(len(ids), -1)

    env._next_trajectories = hold


# The frame and friction tests need a platform that follows its reference closely: a 4 Hz PD with
# velocity feedforward (the real-motion suite's close drive). The calibrated default (a soft position
# drive, a low-pass filter of the reference) has its own test,
# test_position_drive_is_the_filter_of_its_gains.
STIFF_PLATFORM = {"omega_n_rad_s": 2 * np.pi * 4.0, "velocity_feedforward": True, "mass_kg": 800.0}


def replaying_env(n: int, refs: trj.PiecewisePoly, seed: int = 0, **cfg) -> MovingPlatformEnv:
    """A reset env of `n` envs on 2 threads, on STIFF_PLATFORM unless `cfg` names a platform, whose
    env i plays row i of `refs`."""
    cfg.setdefault("platform", STIFF_PLATFORM)
    env = MovingPlatformEnv(
        build_env_cfg(
            {"num_envs": n, "seed": seed, "sim": {"num_threads": 2}, **cfg}, schema=MovingPlatformCfg
        )
    )
    assert len(refs) == n
    # every (re)set env gets its own row of `refs`: after a fall the same reference restarts at t = 0
    env._next_trajectories = lambda ids: (refs.subset(ids), np.full(len(ids), -1))
    env.reset()
    return env


def policy_steps(env: MovingPlatformEnv, t_s: float) -> int:
    """The number of policy steps in `t_s` seconds."""
    return int(round(t_s / env.dt_s))


# ---- reward terms on constructed step states (tests/envs/test_reward_*.py) -----------------------------

REWARD_ENVS = 3  # the envs of a constructed StepState
# what the terms read: h_des in the platform frame (`in_platform_frame`)
REWARDS_P = RewardsCfg(h_des_from="centre")

# four feet at the corners of a 0.36 m x 0.26 m rectangle on the deck (LEG_NAMES order: FR, FL, RR, RL)
FEET_RECTANGLE_P = torch.tensor(
    [[0.18, -0.13, 0.1], [0.18, 0.13, 0.1], [-0.18, -0.13, 0.1], [-0.18, 0.13, 0.1]]
)


def step_state(n: int = REWARD_ENVS, dt_s: float = 0.02, **overrides) -> StepState:
    """A StepState at a 'perfect' pose: centred, level, at h_des, nothing moving."""
    z = lambda *shape: torch.zeros(n, *shape)  # noqa: E731
    p_body = z(3)
    p_body[:, 2] = REWARDS_P.h_des_m
    fields = dict(
        dt_s=dt_s,
        p_body_p=p_body,
        phi_body_w=z(3),
        v_body_b=z(3),
        omega_body_b=z(3),
        v_plf_b=z(3),
        omega_plf_b=z(3),
        u_aln=z(3),
        action=z(12),
        action_prev=z(12),
        tau=z(12),
        tau_prev=z(12),
        q_dot=z(12),
        q_ddot=z(12),
        f_feet_w=z(4, 3),
        contact=torch.zeros(n, 4, dtype=torch.bool),
        touchdown=torch.zeros(n, 4, dtype=torch.bool),
        liftoff=torch.zeros(n, 4, dtype=torch.bool),
        t_air_s=z(4),
        t_contact_s=z(4),
        t_air_running_s=z(4),
        at_time_limit=torch.zeros(n, dtype=torch.bool),
        v_slip_p=z(4, 2),
        p_feet_p=z(4, 3),
        f_feet_p=z(4, 3),
        collision=torch.zeros(n, dtype=torch.bool),
    )
    fields.update(overrides)
    return StepState(**fields)


def assert_close_to(a: torch.Tensor, expected) -> None:
    """`a` equals `expected` (a list, a number or a tensor) up to float rounding."""
    torch.testing.assert_close(a, torch.as_tensor(expected, dtype=a.dtype), rtol=1e-5, atol=1e-6)


# ---- the learner's updates (tests/test_train_*.py) ---------------------------------------------------


def param_copy(module) -> dict[str, torch.Tensor]:
    """A copy of `module`'s state dict, to compare with after an update."""
    return {k: v.detach().clone() for k, v in module.state_dict().items()}


def changed_since(before, module, prefix) -> bool:
    """Whether any entry of `module`'s state dict whose name starts with `prefix` differs from `before`."""
    after = module.state_dict()
    return any(not torch.equal(before[k], after[k]) for k in before if k.startswith(prefix))


def runner_rollout(runner) -> None:
    """One rollout of the runner's env into its learner's storage, returns computed."""
    obs = runner.env.get_observations()
    with torch.inference_mode():
        for _ in range(runner.cfg["num_steps_per_env"]):
            actions = runner.alg.act(obs)
            obs, rew, dones, extras = runner.env.step(actions)
            runner.alg.process_env_step(obs, rew, dones, extras)
        runner.alg.compute_returns(obs)


def bare_learner(tmp_path, algorithm=None, **over):
    """A PPOROA on a tiny env, built as rsl_rl's runner builds it, without a runner or a logger:
    (learner, env, steps per rollout)."""
    from lasmp.algo.ppo_roa import PPOROA
    from lasmp.cli.build import make_env
    from lasmp.config.train import rsl_rl_cfg

    cfg = tiny(tmp_path, **over)
    env = make_env(cfg)
    rsl = rsl_rl_cfg(cfg)
    rsl["multi_gpu"] = None
    if algorithm is not None:
        rsl["algorithm"]["class_name"] = algorithm
    alg = (algorithm or PPOROA).construct_algorithm(env.get_observations(), env, rsl, cfg.device)
    return alg, env, rsl["num_steps_per_env"]


def learner_rollout(alg, env, steps) -> None:
    """One rollout of `steps` steps of `env` into the bare learner's storage, returns computed."""
    obs = env.get_observations()
    with torch.inference_mode():
        for _ in range(steps):
            obs, rew, dones, extras = env.step(alg.act(obs))
            alg.process_env_step(obs, rew, dones, extras)
        alg.compute_returns(obs)


# ---- scripts/study.py on a constructed tree (tests/test_study_*.py) ----------------------------------


def mark_evaluated(d: Path) -> None:
    """A result directory as an evaluation leaves it: its metrics.json."""
    d.mkdir(parents=True, exist_ok=True)
    (d / "metrics.json").write_text("{}")


# ---- play.py on a tiny trained run (tests/conftest.py's run_dir, tests/test_play_*.py) ------------------

PLAY_LATENT_DIM = 8  # not the default (16): play must take it from the checkpoint


def tensorboard_logger(log_dir):
    """rsl_rl's logger (our LoggerCompat) writing TensorBoard into `log_dir`, for one env on the CPU."""
    from lasmp.compat.rsl_rl import LoggerCompat

    return LoggerCompat(
        log_dir=str(log_dir),
        cfg={"algorithm": {}, "logger": "tensorboard"},
        env_cfg={},
        num_envs=1,
        is_distributed=False,
        gpu_world_size=1,
        gpu_global_rank=0,
        device="cpu",
    )
