"""A registry of named reward terms (small pure functions) for a task, and shared helpers."""

from __future__ import annotations

from collections.abc import Callable

import torch


def make_registry() -> tuple[dict[str, Callable], Callable[[Callable], Callable]]:
    """(terms, register): `@register` adds a function to `terms` under its name, once."""
    terms: dict[str, Callable] = {}

    def register(fn: Callable) -> Callable:
        if fn.__name__ in terms:
            raise ValueError(f"reward term {fn.__name__!r} registered twice")
        terms[fn.__name__] = fn
        return fn

    return terms, register


def squared_norm(x: torch.Tensor) -> torch.Tensor:
    """Sum of squares over the last dimension."""
    return torch.sum(torch.square(x), dim=-1)
