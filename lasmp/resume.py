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

import contextlib
import re
import shlex
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch
from omegaconf import OmegaConf

from lasmp.algo.checkpoint import (
    CheckpointError,
    check_finite,
    read_checkpoint,
    refuse_policy_only,
    run_checkpoints,
)
from lasmp.checkpoint_cfg import rebuilding
from lasmp.envs.trajectories.splines import PADDING
from lasmp.rsl_compat import NORMALIZER_STD_KEY, NORMALIZER_VAR_KEY
from lasmp.rundir import CHECKPOINT_NAME, RunDirError, describe, run_files
from lasmp.train_bounds import ITERATIONS
from lasmp.train_cfg import TrainCfg, to_plain, to_train_cfg

if TYPE_CHECKING:
    from hydra.plugins.config_source import ConfigResult

    from lasmp.algo.runner import LasmpRunner

CFG_DIR = Path(__file__).resolve().parents[1] / "cfg"

# keys a resume takes from the command, never from the checkpoint's config
FROM_COMMAND = ("resume", "resume_drop_env_state", "warm_start", "runner.log_dir")
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


def explicit_keys(overrides: list[str]) -> set[str]:
    """The config keys a command line sets, read from its overrides as Hydra parsed them: `key=value`
    (`+key=`, `~key`) names its key; a group option (`task=`, `policy=`, `preset=`, `env=`) stands
    for the keys its own config sets, under its package (preset=paper: device, env.num_envs and
    runner.max_iterations; task=rough_static: task). Nothing is composed: each option's config is
    read alone, from the config sources Hydra composed with."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    keys: set[str] = set()
    with _config_sources() as sources:
        for override in OverridesParser.create().parse_overrides(overrides):
            name, option = override.key_or_group, override.value()
            path = f"{name}/{option}"
            source = next((s for s in sources if isinstance(option, str) and s.is_config(path)), None)
            keys |= _option_keys(source.load_config(path), name) if source else {name}
    return keys


def _option_keys(option: ConfigResult, group: str) -> set[str]:
    """The keys a group option's config sets, under its package (Hydra's default: the group's node)."""
    package = option.header.get("package")
    if package in (None, "_group_"):
        package = group.replace("/", ".")
    package = package.removeprefix("_global_").lstrip(".")
    content = OmegaConf.to_container(option.config)
    content.pop("defaults", None)  # the other options it selects, not keys it sets
    return {f"{package}.{key}" if package else key for key in flatten(content)}


@contextlib.contextmanager
def _config_sources():
    """Hydra's config sources: those of the app (or the caller's `initialize`) that composed the
    config, else cfg/'s."""
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    if GlobalHydra.instance().is_initialized():
        yield GlobalHydra.instance().config_loader().get_sources()
        return
    with initialize_config_dir(config_dir=str(CFG_DIR), version_base="1.3"):
        yield GlobalHydra.instance().config_loader().get_sources()


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
    with rebuilding(data):
        merged = OmegaConf.create(data["config"])
        for key, value in taken.items():
            OmegaConf.update(merged, key, value, force_add=True)
        return to_train_cfg(merged)


def check_iteration(data: dict) -> None:
    """Refuse a checkpoint whose stored iteration is no iteration count, or disagrees with its file's
    name (`model_<N>.pt`, `policy_<N>.pt`): renamed or altered, it would continue the run from one
    place and number its saves from another (an iteration of 10^15 wrote model_1000000000000001.pt)."""
    path, stored = Path(data["path"]), data.get("iter")
    if not ITERATIONS.holds(stored, integer=True):
        raise CheckpointError(
            f"{path} stores iteration {stored!r}, not an iteration count in {ITERATIONS.interval()} "
            f"({ITERATIONS.why}): the file was altered; give another checkpoint"
        )
    named = CHECKPOINT_NAME.fullmatch(path.name)
    if named and int(named.group(2)) != stored:
        raise CheckpointError(
            f"{path} stores iteration {stored}, but its name says {named.group(2)}: it was renamed or altered, "
            f"so where the run stands is unclear. Rename it {named.group(1)}_{stored}.pt if it holds that "
            "iteration, or give another checkpoint"
        )


def check_state(data: dict, consequence: str) -> None:
    """Refuse a checkpoint a training cannot go on from (a resume or a warm start): its stored
    iteration (`check_iteration`), a non-finite network, an insane entry (`insane_entry`);
    `consequence` ends the message."""
    path = data["path"]
    check_iteration(data)
    try:
        check_finite({k: data[k] for k in data if k.endswith("state_dict")}, f"checkpoint {path}")
    except FloatingPointError as err:
        raise CheckpointError(f"{err}: {consequence}") from None
    insane = insane_entry(data)
    if insane:
        raise CheckpointError(f"checkpoint {path}: {insane}: {consequence}")


def check_resume(cfg: TrainCfg, data: dict) -> dict[str, tuple]:
    """Refuse a resume that cannot go as `cfg` says, before anything is built or written; return
    the keys it changes from the checkpoint's config, {key: (saved, now)}."""
    path = data["path"]
    refuse_policy_only(data)
    check_state(data, "it cannot be resumed (give an earlier checkpoint)")
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


# what a resumed training reads from a checkpoint besides its networks: every number in them must be finite
RESUMED_STATE = (
    "optimizer_state_dict",
    "estimator_optimizer_state_dict",
    "rnd_optimizer_state_dict",
    "env_state",
    "rng_state",
    "episode_log_state",
)


def _numbers(obj, name: str):
    """(entry name, value) of every number in a checkpoint's nested state: tensors and numpy arrays
    (floating ones), floats."""
    if isinstance(obj, torch.Tensor):
        if obj.is_floating_point():
            yield name, obj
    elif isinstance(obj, np.ndarray):
        if obj.dtype.kind == "f":
            yield name, obj
    elif isinstance(obj, float):
        yield name, obj
    elif isinstance(obj, dict):
        for key, value in obj.items():
            yield from _numbers(value, f"{name}.{key}" if name else str(key))
    elif isinstance(obj, (list, tuple)):
        for i, value in enumerate(obj):
            yield from _numbers(value, f"{name}[{i}]")


def _all(value, test) -> bool:
    if isinstance(value, torch.Tensor):
        return bool(test(value.double()).all()) if value.numel() else True
    return bool(np.all(test(np.asarray(value, dtype=np.float64))))


def _shown(value) -> str:
    """The first offending number of `value`, for the message."""
    flat = (
        value.detach().double().flatten().tolist()
        if isinstance(value, torch.Tensor)
        else np.ravel(value).tolist()
    )
    return (
        str(flat[0])
        if len(flat) == 1
        else f"[{', '.join(str(v) for v in flat[:3])}{', ...' if len(flat) > 3 else ''}]"
    )


# ranges of the training state a resume continues from, by the entry's last name: a NaN learning rate
# or a negative standard deviation is as fatal as a NaN weight (torch.normal fails on std < 0 at the
# first action), but check_finite, which reads tensors only, lets a float `lr` through
SANE = {
    "lr": (lambda v: v > 0, "a learning rate must be > 0"),
    "eps": (lambda v: v >= 0, "Adam's eps must be >= 0"),
    "betas": (lambda v: (v >= 0) & (v < 1), "Adam's betas must be in [0, 1)"),
    "weight_decay": (lambda v: v >= 0, "a weight decay must be >= 0"),
    "exp_avg_sq": (lambda v: v >= 0, "Adam's second moments must be >= 0"),
    "step": (lambda v: v >= 0, "Adam's step count must be >= 0"),
    "std_param": (lambda v: v > 0, "the action noise's standard deviation must be > 0"),
    NORMALIZER_VAR_KEY: (lambda v: v >= 0, "a normalizer's variance must be >= 0"),
    NORMALIZER_STD_KEY: (lambda v: v >= 0, "a normalizer's standard deviation must be >= 0"),
    "count": (lambda v: v >= 0, "a normalizer's count must be >= 0"),
}


def _finite_but_padding(value, pad: float) -> bool:
    """A trajectory's padded field (`PADDING`): finite but for whole trailing slots of `pad` per row
    (axis 0 rows, axis 1 slots), a row's first slot always real."""
    a = value.detach().double().numpy() if isinstance(value, torch.Tensor) else np.asarray(value, np.float64)
    if a.ndim < 2 or a.shape[1] == 0:
        return bool(np.isfinite(a).all())
    slots = a.reshape(a.shape[0], a.shape[1], -1)
    real = np.isfinite(slots).all(axis=2)
    padded = (np.isnan(slots) if np.isnan(pad) else slots == pad).all(axis=2)
    trailing = (padded[:, 1:] >= padded[:, :-1]).all()  # once padded, padded to the row's end
    return bool((real | padded).all() and trailing and real[:, 0].all())


def insane_entry(data: dict) -> str | None:
    """The first entry of a checkpoint's training state that a training cannot continue from, in
    words (None: all sane): a non-finite number anywhere in the state a resume restores (networks,
    optimizers, the envs' running state, random and logging state), or a value outside its range
    (`SANE`: learning rates > 0, standard deviations > 0, ...). Why: such a state trains on for a
    step or two and then fails far from its cause (`normal expects std >= 0`, rsl_rl's reward-NaN
    error)."""
    state = {k: data[k] for k in data if k.endswith("state_dict") or k in RESUMED_STATE}
    for name, value in _numbers(state, ""):
        pad = PADDING.get(name.removesuffix(".data").rsplit(".", 1)[-1])
        if pad is not None:
            if not _finite_but_padding(value, pad):
                return (
                    f"{name} is not finite where it is not padding (a row's trailing {pad}) ({_shown(value)})"
                )
        elif not _all(value, np.isfinite if not isinstance(value, torch.Tensor) else torch.isfinite):
            return f"{name} is not finite ({_shown(value)})"
        last = name.rsplit(".", 1)[-1].split("[")[0]
        rule = SANE.get(last) if not last.startswith("log_") else None
        if last.endswith("std_param") and not last.startswith("log"):
            rule = SANE["std_param"]
        if rule and not _all(value, rule[0]):
            return f"{name} = {_shown(value)} is out of range ({rule[1]})"
    return None


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


@dataclass
class Resume:
    """A resume checked whole before anything is built or written: the config it runs, the
    checkpoint as read (once), and the keys it changes from the run's config, {key: (saved, now)}."""

    cfg: TrainCfg
    data: dict
    changed: dict[str, tuple]

    @classmethod
    def check(cls, cfg: TrainCfg, explicit: set[str] | None) -> Resume:
        """`cfg.resume` read and checked against `cfg` (`explicit`: as in `resumed_cfg`)."""
        data = read_checkpoint(cfg.resume, "cpu", full_only=True)
        cfg = resumed_cfg(cfg, data, explicit)
        return cls(cfg, data, check_resume(cfg, data))

    def restore(self, runner: LasmpRunner, say: Callable[..., None]) -> None:
        """Load the checkpoint into the runner built from `cfg`, apply the changed keys, and say
        what changed and where the run goes on."""
        keep = {
            "actor": True,
            "critic": True,
            "optimizer": True,
            "iteration": True,
            "env_run_state": not self.cfg.resume_drop_env_state,
        }
        runner.load(self.data, load_cfg=keep)
        apply_learning_rates(runner, self.changed)
        others = {k: v for k, v in self.changed.items() if k not in LEARNING_RATES}
        if others:
            say(
                "resume: in effect from now on, changed from the run's config: "
                + ", ".join(f"{k} {old} -> {new}" for k, (old, new) in others.items()),
                flush=True,
            )
        first = runner.current_learning_iteration
        last = first + self.cfg.runner.max_iterations - 1
        abandoned = self.data.get("abandoned_rollout")
        if abandoned and not self.cfg.resume_drop_env_state:
            say(
                f"resume: not exact: {self.data['path']} was saved when a signal stopped iteration "
                f"{abandoned['iteration']}'s rollout {abandoned['env_steps']} env-steps in; the envs go on from "
                "that moment, not from the end of the saved iteration",
                flush=True,
            )
        say(
            f"resumed from {self.data['path']} at iteration {first} (0\u2013{first - 1} done); runner.max_iterations "
            f"counts the iterations to add: {self.cfg.runner.max_iterations} more, to {last}",
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
                # only a full checkpoint can be resumed: never advise a policy checkpoint, whose refusal
                # would send the user back here
                full = [p.name for n, p in run_checkpoints(run_dir, full_only=True).items() if n > position]
                advice = (
                    f"Resume from {full[-1]}, the newest full checkpoint, or give"
                    if full
                    else "The later ones are policy checkpoints, which cannot resume: give"
                )
                raise RunDirError(
                    f"resume={data['path']} is not the latest checkpoint of {run_dir} ({describe(later)} came "
                    f"later): continuing there would overwrite them. {advice} runner.log_dir=NEW_DIR to branch "
                    "off into a new directory"
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
    """The overrides Hydra parsed from train.py's command line; None outside its app."""
    from hydra.core.hydra_config import HydraConfig

    return list(HydraConfig.get().overrides.task) if HydraConfig.initialized() else None


def resume_command(checkpoint: str, log_dir: str, iterations_left: int | None = None) -> str:
    """The train.py command line that continues a run: this run's own overrides (from Hydra, when
    it composed the config) with resume= and runner.log_dir= set, and runner.max_iterations= the
    iterations left to the end the interrupted command set (a resume runs that many more)."""
    overrides = hydra_overrides() or []
    # a `+key=` that composed names a key of the schema (validation refuses others), and Hydra now
    # refuses `+` on an existing key: repeat it without the `+`
    drop = ("resume=", "warm_start=", "runner.log_dir=") + (
        ("runner.max_iterations=",) if iterations_left is not None else ()
    )
    keep = [o.removeprefix("+") for o in overrides if not o.lstrip("+~").startswith(drop)]
    if iterations_left is not None:
        keep.append(f"runner.max_iterations={max(iterations_left, 1)}")
    keep += [f"resume={hydra_quote(checkpoint)}", f"runner.log_dir={hydra_quote(log_dir)}"]
    # quoted for the shell, so that it can be pasted: a path with a space, brackets of a list
    return " ".join(["python train.py", *map(shlex.quote, keep)])


def hydra_quote(value: str) -> str:
    """`value` as a Hydra override's value: as it is where Hydra reads it whole, else in Hydra's
    double quotes (a path with a comma would be a sweep, one with brackets or quotes a parse error).
    In them a quote is escaped, and so are the backslashes before a quote or at the end (Hydra's rule)."""
    if re.fullmatch(r"[\w./@:+-]+", value):
        return value
    escaped = re.sub(r'(\\*)"', lambda m: m.group(1) * 2 + '\\"', value)
    escaped = re.sub(r"(\\+)$", lambda m: m.group(1) * 2, escaped)
    return f'"{escaped}"'
