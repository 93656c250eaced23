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

import torch
from omegaconf import DictConfig, OmegaConf

from lasmp.algo.checkpoint import CHECKPOINT_FORMAT
from lasmp.train_cfg import TrainCfg, to_train_cfg

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
    spec = importlib.util.spec_from_file_location(Path(path).stem + "_script", ROOT / path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


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
