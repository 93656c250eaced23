"""Resume policy: what a resumed run takes from its checkpoint and what from the command, what it
refuses, and the command that continues an interrupted run.

`resume=DIR` (its newest full checkpoint: a policy checkpoint holds no training state) or a full
checkpoint in DIR continues in DIR, unless runner.log_dir names another, empty directory (a branch);
runner.max_iterations then counts the iterations to add. A resume is checked whole (the checkpoint,
the config, the envs' count, the networks) before anything is written, so that a failed resume
leaves the run as it was. From the command line a resume runs the checkpoint's own config with the
keys the command sets on top (`explicit_keys`); every key the command changes is applied and said,
or refused where it cannot take effect (`RESUME_FIXED`).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING

from omegaconf import OmegaConf

from lasmp.algo.checkpoint import CheckpointError, check_finite, refuse_policy_only, run_checkpoints
from lasmp.rundir import RunDirError, describe, run_files
from lasmp.train_cfg import TrainCfg, to_plain, to_train_cfg

if TYPE_CHECKING:
    from lasmp.algo.runner import LasmpRunner

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


def check_run_dir(log_dir: Path, data: dict | None):
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


def hydra_overrides() -> list[str] | None:
    from hydra.core.hydra_config import HydraConfig

    return list(HydraConfig.get().overrides.task) if HydraConfig.initialized() else None


def resume_command(checkpoint: str, log_dir: str, iterations_left: int | None = None) -> str:
    """The train.py command line that continues a run: this run's own overrides (from Hydra, when
    it composed the config) with resume= and runner.log_dir= set, and runner.max_iterations= the
    iterations left to the end the interrupted command set (a resume runs that many more)."""
    overrides = hydra_overrides() or []
    # a `+key=` that composed names a key of the schema (validation refuses others), and Hydra now
    # refuses `+` on an existing key: repeat it without the `+`
    drop = ("resume=", "runner.log_dir=") + (
        ("runner.max_iterations=",) if iterations_left is not None else ()
    )
    keep = [o.removeprefix("+") for o in overrides if not o.lstrip("+~").startswith(drop)]
    if iterations_left is not None:
        keep.append(f"runner.max_iterations={max(iterations_left, 1)}")
    return " ".join(["python train.py", *keep, f"resume={checkpoint}", f"runner.log_dir={log_dir}"])
