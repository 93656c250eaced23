"""Shared test set-up."""

from __future__ import annotations

import os

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


@pytest.fixture(scope="module")
def gl():
    """Skip the tests that render or write video where no headless OpenGL context (MUJOCO_GL=egl, or
    osmesa) can be made, or imageio's ffmpeg is missing."""
    from lasmp.render.renderer import select_gl_backend

    select_gl_backend()
    import mujoco

    try:
        mujoco.Renderer(mujoco.MjModel.from_xml_string("<mujoco/>"), 8, 8).close()
    except Exception as err:  # no EGL/OSMesa library, no device, ...
        pytest.skip(f"no offscreen OpenGL with MUJOCO_GL={os.environ.get('MUJOCO_GL')}: {err}")
    pytest.importorskip("imageio_ffmpeg")
