"""Is a checkpoint's state one a training can go on from (a resume or a warm start)? Its stored
iteration, finite networks, and every number of the state it restores finite and in range, before
anything is built: such a state would train on for a step or two and then fail far from its cause.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import torch

from lasmp.algo.checkpoint import (
    CheckpointError,
    check_finite,
)
from lasmp.compat.rsl_rl import NORMALIZER_STD_KEY, NORMALIZER_VAR_KEY
from lasmp.config.bounds import ITERATIONS
from lasmp.io.rundir import CHECKPOINT_NAME


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


def check_state(data: dict, consequence: str, padding: Mapping[str, float]) -> None:
    """Refuse a checkpoint a training cannot go on from (a resume or a warm start): its stored
    iteration (`check_iteration`), a non-finite network, an insane entry (`insane_entry`);
    `consequence` ends the message. `padding`: the env's padded fields, by name, with their pad value
    (the trajectories' `PADDING`: the caller knows the envs, this layer does not)."""
    path = data["path"]
    check_iteration(data)
    try:
        check_finite({k: data[k] for k in data if k.endswith("state_dict")}, f"checkpoint {path}")
    except FloatingPointError as err:
        raise CheckpointError(f"{err}: {consequence}") from None
    insane = insane_entry(data, padding)
    if insane:
        raise CheckpointError(f"checkpoint {path}: {insane}: {consequence}")


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
    """A padded field (the trajectories' `PADDING`): finite but for whole trailing slots of `pad` per row
    (axis 0 rows, axis 1 slots), a row's first slot always real."""
    a = value.detach().double().numpy() if isinstance(value, torch.Tensor) else np.asarray(value, np.float64)
    if a.ndim < 2 or a.shape[1] == 0:
        return bool(np.isfinite(a).all())
    slots = a.reshape(a.shape[0], a.shape[1], -1)
    real = np.isfinite(slots).all(axis=2)
    padded = (np.isnan(slots) if np.isnan(pad) else slots == pad).all(axis=2)
    trailing = (padded[:, 1:] >= padded[:, :-1]).all()  # once padded, padded to the row's end
    return bool((real | padded).all() and trailing and real[:, 0].all())


def insane_entry(data: dict, padding: Mapping[str, float]) -> str | None:
    """The first entry of a checkpoint's training state that a training cannot continue from, in
    words (None: all sane): a non-finite number anywhere in the state a resume restores (networks,
    optimizers, the envs' running state, random and logging state), or a value outside its range
    (`SANE`: learning rates > 0, standard deviations > 0, ...). Why: such a state trains on for a
    step or two and then fails far from its cause (`normal expects std >= 0`, rsl_rl's reward-NaN
    error)."""
    state = {k: data[k] for k in data if k.endswith("state_dict") or k in RESUMED_STATE}
    for name, value in _numbers(state, ""):
        pad = padding.get(name.removesuffix(".data").rsplit(".", 1)[-1])
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
