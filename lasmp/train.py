"""Build the env, the runner and train: the logic behind `train.py`.

Run directories (`lasmp.rundir`): a training locks its directory; a new run is refused a directory
that holds a run. `resume=DIR` (its newest full checkpoint: a policy checkpoint holds no training
state) or a full checkpoint in DIR continues in DIR, unless runner.log_dir names another, empty
directory (a branch); runner.max_iterations then counts the iterations to add. A resume is checked
whole (the checkpoint, the config, the envs' count, the networks) before anything is written, so
that a failed resume leaves the run as it was. From the command line a resume runs the
checkpoint's own config with the keys the command sets on top (`explicit_keys`); every key the
command changes is applied and said, or refused where it cannot take effect (`RESUME_FIXED`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime
import os
import re
import sys
from pathlib import Path

import torch
from omegaconf import OmegaConf

from lasmp.algo import distributed as dp
from lasmp.algo.checkpoint import (
    CheckpointError,
    check_finite,
    read_checkpoint,
    refuse_policy_only,
    run_checkpoints,
)
from lasmp.algo.runner import LasmpRunner, TrainingFaulted, TrainingInterrupted
from lasmp.atomic import atomic_open
from lasmp.config import ConfigError
from lasmp.envs import registry
from lasmp.envs.trajectories import TrajectoryFileError
from lasmp.rundir import RunDirError, claim, describe, run_files
from lasmp.train_cfg import TrainCfg, rsl_rl_cfg, to_train_cfg

CFG_DIR = Path(__file__).resolve().parents[1] / "cfg"

# keys a resume takes from the command, never from the checkpoint's config
FROM_COMMAND = ("resume", "resume_drop_env_state", "runner.log_dir")
# keys a resume may change freely: how long and where it runs, on what hardware, how it computes
RESUME_FREE = FROM_COMMAND + (
    "runner.",
    "device",
    "torch_threads",
    "env.seed",
    "env.sim.num_threads",
    "algo.precision",
    "algo.fused_adam",
    "algo.use_mixed_precision",
    "algo.compile_mlps",
)
# keys a resume cannot change: why, for the refusal
RESUME_FIXED = {
    "task": "the checkpoint's networks were trained on its task",
    "seed": "the random streams continue from the checkpoint's",
    "policy.": "the networks (their layers, inputs and action noise) are the checkpoint's",
}
# learning rates restored with the optimizers' states: a new value is applied after the load
LEARNING_RATES = {"algo.learning_rate": "optimizer", "algo.estimator_learning_rate": "estimator_optimizer"}


def seed_everything(seed: int) -> None:
    torch.manual_seed(seed)


def make_env(cfg: TrainCfg):
    """The task's env (`lasmp.envs.registry`), its tensors where its physics runs (cpu backend: the CPU,
    even with the learner on a GPU; warp: `cfg.device`)."""
    return registry.make_env(cfg.task, cfg.env, cfg.device)


def make_runner(cfg: TrainCfg, log_dir: str | None, rank: int = 0) -> LasmpRunner:
    """The env and the runner of `cfg`; in a data-parallel job, rank k's envs and torch streams are
    seeded with seed + k (its own physics, trajectories and curriculum draws); the saved config keeps
    the job's seed."""
    if cfg.device.startswith("cuda") and not torch.cuda.is_available():
        raise ConfigError(
            f"device={cfg.device} but torch sees no CUDA device (install a CUDA build of torch)"
        )
    if cfg.torch_threads > 0:
        torch.set_num_threads(cfg.torch_threads)
    seed_everything(cfg.seed + rank)
    env = make_env(
        cfg if rank == 0 else dataclasses.replace(cfg, env=dataclasses.replace(cfg.env, seed=cfg.seed + rank))
    )
    return LasmpRunner(
        env,
        rsl_rl_cfg(cfg),
        log_dir=log_dir,
        device=cfg.device,
        full_config=to_plain(cfg),
        max_fault_fraction=cfg.runner.max_fault_fraction,
        keep_full=cfg.runner.keep_full,
    )


def to_plain(cfg: TrainCfg) -> dict:
    return OmegaConf.to_container(OmegaConf.structured(cfg))


def default_log_dir(cfg: TrainCfg) -> str:
    stamp = datetime.datetime.now().strftime("%Y-%m-%d_%H-%M-%S")
    return os.path.join("logs", cfg.task, cfg.policy.name, stamp)


def flatten(tree, prefix: str = "") -> dict:
    """{"a.b": leaf} of nested dicts (lists are leaves)."""
    if not isinstance(tree, dict):
        return {prefix: tree}
    out = {}
    for key, value in tree.items():
        out.update(flatten(value, f"{prefix}.{key}" if prefix else str(key)))
    return out


def _matches(key: str, patterns) -> bool:
    return any(key == p or (p.endswith(".") and key.startswith(p)) for p in patterns)


# -- resume --------------------------------------------------------------------------------------
def explicit_keys(cfg, overrides: list[str]) -> set[str]:
    """The config keys a command line sets: those it names (key=value) and those its group overrides
    (task=, policy=, preset=) change, found as the keys where `cfg` (composed with `overrides`)
    differs from the config composed without any."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra
    from hydra.core.override_parser.overrides_parser import OverridesParser

    keys = {o.key_or_group for o in OverridesParser.create().parse_overrides(overrides)}
    if GlobalHydra.instance().is_initialized():  # train.py's Hydra app
        default = compose(config_name="config")
    else:
        with initialize_config_dir(config_dir=str(CFG_DIR), version_base="1.3"):
            default = compose(config_name="config")
    given = flatten(OmegaConf.to_container(cfg, resolve=True))
    base = flatten(OmegaConf.to_container(default, resolve=True))
    return keys | {k for k, v in given.items() if k not in base or base[k] != v}


def resumed_cfg(cfg: TrainCfg, data: dict, explicit: set[str] | None) -> TrainCfg:
    """The config a resume runs: `cfg` as it is (explicit None: every key is the caller's), or the
    checkpoint's config with the keys in `explicit` (and FROM_COMMAND) taken from `cfg`."""
    if explicit is None:
        return cfg
    given, saved = flatten(to_plain(cfg)), flatten(data["config"])
    taken = {
        k: v
        for k, v in given.items()
        if _matches(k, FROM_COMMAND) or k in explicit or any(k.startswith(f"{e}.") for e in explicit)
    }
    _refuse_fixed({k: (saved[k], v) for k, v in taken.items() if k in saved and saved[k] != v})
    merged = OmegaConf.create(data["config"])
    for key, value in taken.items():
        OmegaConf.update(merged, key, value, force_add=True)
    try:
        return to_train_cfg(merged)
    except Exception as err:  # unknown or removed keys, out-of-range values: the code moved on
        raise CheckpointError(
            f"checkpoint {data['path']} has a config this code cannot rebuild: {err}"
        ) from err


def check_resume(cfg: TrainCfg, data: dict) -> dict[str, tuple]:
    """Refuse a resume that cannot go as `cfg` says, before anything is built or written; return
    the keys it changes from the checkpoint's config, {key: (saved, now)}."""
    path = data["path"]
    refuse_policy_only(data)
    try:
        check_finite({k: data[k] for k in data if k.endswith("state_dict")}, f"checkpoint {path}")
    except FloatingPointError as err:
        raise CheckpointError(f"{err}: it cannot be resumed (give an earlier checkpoint)") from None
    saved, now = flatten(data["config"]), flatten(to_plain(cfg))
    changed = {
        k: (saved[k], now[k])
        for k in now
        if k in saved and saved[k] != now[k] and not _matches(k, RESUME_FREE)
    }
    _refuse_fixed(changed)
    saved_run = (data.get("env_state") or {}).get("run")
    if (
        saved_run is not None
        and not cfg.resume_drop_env_state
        and saved_run.get("num_envs") != cfg.env.num_envs
    ):
        n = saved_run.get("num_envs")
        raise CheckpointError(
            f"resume: env.num_envs={cfg.env.num_envs}, but the checkpoint {path} holds the running state of "
            f"{n} envs. Give resume_drop_env_state=true to start every env's episode anew (the resume is then "
            f"not exact), or env.num_envs={n}"
        )
    changed.pop("env.num_envs", None)
    return changed


def _refuse_fixed(changed: dict[str, tuple]) -> None:
    """Refuse a change, {key: (saved, now)}, of a key a resume cannot change (RESUME_FIXED)."""
    for key, (old, new) in changed.items():
        for fixed, why in RESUME_FIXED.items():
            if _matches(key, (fixed,)):
                raise CheckpointError(
                    f"resume: {key}={new} differs from the run's {key}={old}, and a resume cannot change it ({why}): "
                    "drop the override, or start a new run in another runner.log_dir"
                )


def apply_learning_rates(runner: LasmpRunner, changed: dict[str, tuple]) -> None:
    """A learning rate given anew on resume replaces the one the optimizer's state brought back."""
    for key, attr in LEARNING_RATES.items():
        if key not in changed or getattr(runner.alg, attr, None) is None:
            continue
        optimizer, (old, new) = getattr(runner.alg, attr), changed[key]
        restored = optimizer.param_groups[0]["lr"]
        for group in optimizer.param_groups:
            group["lr"] = new
        if attr == "optimizer":
            runner.alg.learning_rate = new
        print(
            f"resume: {key}={new} (the run's was {old}): the learning rate restarts at {new}, not at the "
            f"checkpoint's {restored:.4g}",
            flush=True,
        )


def _check_run_dir(log_dir: Path, data: dict | None):
    """The check `claim` makes once it holds the directory's lock."""

    def check(run_dir: Path) -> None:
        continuing = data is not None and Path(data["path"]).parent.resolve() == run_dir.resolve()
        if continuing:
            m = re.fullmatch(r"model_(\d+)\.pt", Path(data["path"]).name)
            position = int(m.group(1)) if m else data["iter"]  # where the resumed file sits in the run
            later = [p.name for n, p in run_checkpoints(run_dir).items() if n > position]
            if later:
                raise RunDirError(
                    f"resume={data['path']} is not the latest checkpoint of {run_dir} ({describe(later)} came "
                    f"later): continuing there would overwrite them. Resume from {later[-1]}, or give "
                    "runner.log_dir=NEW_DIR to branch off into a new directory"
                )
            return
        held = run_files(run_dir)
        if held:
            saved = "" if run_checkpoints(run_dir) else " (no checkpoint: delete the directory to reuse it)"
            raise RunDirError(
                f"runner.log_dir={run_dir} already holds a run ({describe(held)}){saved}: give resume={run_dir} to "
                "continue it, or another runner.log_dir for a new run"
            )

    return check


def train(cfg, explicit: set[str] | None = None) -> LasmpRunner:
    """Train as `cfg` says (see the module docstring); `explicit`: on resume, the keys the command line
    set (None: every key of `cfg`)."""
    cfg = to_train_cfg(cfg)
    data, changed = None, {}
    if cfg.resume:  # fail before building anything if the checkpoint is unusable; read it once
        data = read_checkpoint(cfg.resume, "cpu", full_only=True)
        cfg = resumed_cfg(cfg, data, explicit)
        changed = check_resume(cfg, data)
    ranks = dp.ranks_from_env()  # torchrun: rank 0 alone holds the run directory, logs and saves
    if ranks.distributed:
        cfg.device = dp.rank_device(cfg.device, ranks)
        dp.setup(ranks, cfg.device)
    log_dir = Path(cfg.runner.log_dir or (Path(data["path"]).parent if data else default_log_dir(cfg)))
    owner = claim(log_dir, _check_run_dir(log_dir, data)) if ranks.is_main else contextlib.nullcontext()
    say = print if ranks.is_main else (lambda *a, **k: None)
    with owner:
        runner = make_runner(cfg, str(log_dir) if ranks.is_main else None, ranks.rank)
        if data is not None:
            keep = {
                "actor": True,
                "critic": True,
                "optimizer": True,
                "iteration": True,
                "env_run_state": not cfg.resume_drop_env_state,
            }
            runner.load(data, load_cfg=keep)
            apply_learning_rates(runner, changed)
            others = {k: v for k, v in changed.items() if k not in LEARNING_RATES}
            if others:
                say(
                    "resume: in effect from now on, changed from the run's config: "
                    + ", ".join(f"{k} {old} -> {new}" for k, (old, new) in others.items()),
                    flush=True,
                )
        first = runner.current_learning_iteration
        last = first + cfg.runner.max_iterations - 1  # the iteration this command ends at
        if data is not None:
            say(
                f"resumed from {data['path']} at iteration {first} (0\u2013{first - 1} done); runner.max_iterations "
                f"counts the iterations to add: {cfg.runner.max_iterations} more, to {last}",
                flush=True,
            )
        if ranks.is_main:  # only now, with everything checked, the run directory's config
            with atomic_open(log_dir / "config.yaml", "w") as f:
                f.write(OmegaConf.to_yaml(OmegaConf.structured(cfg)))
        processes = f" x {ranks.world_size} processes" if ranks.distributed else ""
        span = f" ({first}\u2013{last})" if cfg.runner.max_iterations else ""
        say(
            f"training {cfg.task} / {cfg.policy.name}: {cfg.env.num_envs} envs{processes}, {cfg.runner.max_iterations} "
            f"iterations{span}, logs in {log_dir}",
            flush=True,
        )
        try:
            runner.learn(cfg.runner.max_iterations)
        except TrainingInterrupted as stop:
            if stop.checkpoint:
                # on a resume, runner.max_iterations counts the iterations still to run: those left
                left = last - stop.iteration
                print(
                    f"{stop}\nresume with:\n  {resume_command(stop.checkpoint, str(log_dir), left)}",
                    flush=True,
                )
            raise
    return runner


# what a user can meet: bad input (exit 2) and a run that cannot go on (exit 1), each said in one line
BAD_INPUT = (CheckpointError, ConfigError, RunDirError, TrajectoryFileError)
CANNOT_GO_ON = (TrainingFaulted, FloatingPointError, OSError)


def main(cfg, overrides: list[str] | None = None) -> int:
    """train.py: train `cfg`, composed by Hydra from `overrides` (None: Hydra's own, when it runs);
    return the exit code. Failures a user can meet print one line, no traceback."""
    try:
        if overrides is None:
            overrides = _hydra_overrides()
        resuming = getattr(cfg, "resume", None) and overrides is not None
        explicit = explicit_keys(cfg, overrides) if resuming else None
        train(cfg, explicit)
    except TrainingInterrupted as stop:  # checkpoint written and resume command printed
        return 128 + stop.signum
    except BAD_INPUT as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except CANNOT_GO_ON as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # Ctrl-C before training started (the runner handles it during training)
        print("interrupted before training started: nothing saved", file=sys.stderr)
        return 130
    finally:
        dp.teardown()
    return 0


def _hydra_overrides() -> list[str] | None:
    from hydra.core.hydra_config import HydraConfig

    return list(HydraConfig.get().overrides.task) if HydraConfig.initialized() else None


def resume_command(checkpoint: str, log_dir: str, iterations_left: int | None = None) -> str:
    """The train.py command line that continues a run: this run's own overrides (from Hydra, when
    it composed the config) with resume= and runner.log_dir= set, and runner.max_iterations= the
    iterations left to the end the interrupted command set (a resume runs that many more)."""
    overrides = _hydra_overrides() or []
    # a `+key=` that composed names a key of the schema (validation refuses others), and Hydra now
    # refuses `+` on an existing key: repeat it without the `+`
    drop = ("resume=", "runner.log_dir=") + (
        ("runner.max_iterations=",) if iterations_left is not None else ()
    )
    keep = [o.removeprefix("+") for o in overrides if not o.lstrip("+~").startswith(drop)]
    if iterations_left is not None:
        keep.append(f"runner.max_iterations={max(iterations_left, 1)}")
    return " ".join(["python train.py", *keep, f"resume={checkpoint}", f"runner.log_dir={log_dir}"])
