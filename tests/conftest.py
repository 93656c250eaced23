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


@pytest.fixture(autouse=True)
def default_signal_handlers():
    """Every test starts with Python's own SIGINT and SIGTERM handling, and leaves it so: a training
    run in this process installs its stop handlers, and a test that ends mid-run could leave them (or
    an ignored SIGINT, which subprocesses inherit) to the Ctrl-C tests that follow."""
    import signal

    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    yield
    for s, handler in saved.items():
        signal.signal(s, handler if handler is not None else signal.SIG_DFL)
