"""Shared test set-up."""

from __future__ import annotations

import pytest


@pytest.fixture(autouse=True)
def eager_learners(request, monkeypatch):
    """Keep the in-process tests' learners eager: `algo.precision=auto` compiles every new learner's
    networks, seconds per tiny training, over hundreds of them. A test that asks for compiled MLPs
    (compile_mlps=true) still gets them, and tests/algo/test_precision.py tests `auto` itself, compile
    included. Subprocess tests (the real CLI) run the defaults as a user does."""
    if request.module.__name__.endswith("test_precision"):
        return
    from lasmp.algo import ppo_roa

    real = ppo_roa.resolve_precision

    def eager(precision, device, use_mixed_precision=None, fused_adam=None, compile_mlps=None):
        return real(
            precision,
            device,
            use_mixed_precision,
            fused_adam,
            False if compile_mlps is None else compile_mlps,
        )

    monkeypatch.setattr(ppo_roa, "resolve_precision", eager)
