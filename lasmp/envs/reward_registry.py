"""A registry of named reward terms (small pure functions) for a task, and shared helpers.

`check_reward_weights` is the one place where reward weights are checked against a task's
registered terms: both tasks' reward schemas (`lasmp/envs/*/cfg.py`) and `RewardManager` call it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

import torch

from lasmp.config import ConfigError


def make_registry() -> tuple[dict[str, Callable], Callable[[Callable], Callable]]:
    """(terms, register): `@register` adds a function to `terms` under its name, once."""
    terms: dict[str, Callable] = {}

    def register(fn: Callable) -> Callable:
        if fn.__name__ in terms:
            raise ValueError(f"reward term {fn.__name__!r} registered twice")
        terms[fn.__name__] = fn
        return fn

    return terms, register


def check_reward_weights(weights: Mapping[str, float], terms: Mapping[str, Callable], where: str) -> None:
    """Refuse a weight for a term that is not registered in `terms` (listing the valid names) or a
    non-finite weight; `where` names the weights in the message (e.g. `env.rewards.weights`)."""
    unknown = sorted(set(weights) - set(terms))
    if unknown:
        raise ConfigError(f"{where}: unknown reward term(s) {unknown}; valid terms: {sorted(terms)}")
    for name, weight in weights.items():
        if not math.isfinite(float(weight)):
            raise ConfigError(f"{where}.{name} must be finite, got {weight}")


def squared_norm(x: torch.Tensor) -> torch.Tensor:
    """Sum of squares over the last dimension."""
    return torch.sum(torch.square(x), dim=-1)
