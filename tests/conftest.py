"""Shared test set-up."""

from __future__ import annotations

import os
from pathlib import Path

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


@pytest.fixture
def study(tmp_path, monkeypatch):
    """scripts/study.py as a module on a constructed tree under tmp_path: the commands it would run
    recorded in `study.ran` (not run), the real ones kept as `real_execute` and `real_check_learner`
    (tests/test_study_*.py). Its modules read as one namespace (testkit.Study), each name set in the
    module that defines it: the paths in studylib.plan, the commands in studylib.runs."""
    from testkit import Study

    mod = Study()
    monkeypatch.setattr(mod.plan, "ROOT", tmp_path)
    monkeypatch.setattr(mod.plan, "RUNS", tmp_path / "runs" / "study")
    monkeypatch.setattr(mod.plan, "RESULTS", tmp_path / "results" / "study")
    monkeypatch.setattr(mod.plan, "FIRST_PASS", tmp_path / "results" / "study" / "entropy_0.01")
    monkeypatch.setattr(mod.plan, "STAND_STILL", tmp_path / "results" / "study" / "stand_still" / "seed0")
    monkeypatch.setattr(mod.plan, "LADDER", tmp_path / "results" / "ladder")
    ran = []
    mod.real_execute = mod.execute
    monkeypatch.setattr(mod.runs, "execute", lambda cmd, log: ran.append(cmd[1:]))
    monkeypatch.setattr(mod.runs, "record_run", lambda *a: None)
    mod.real_check_learner = mod.check_learner
    monkeypatch.setattr(mod.runs, "check_learner", lambda cpuinfo=None: None)  # CI's CPU may lack bfloat16
    mod.ran = ran
    return mod


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    """One tiny trained run (model_0.pt) with a non-default policy shape (tests/test_play_*.py)."""
    from omegaconf import OmegaConf
    from testkit import PLAY_LATENT_DIM

    from lasmp.cli.train import train

    log_dir = tmp_path_factory.mktemp("play_run")
    cfg = {
        "env": {"num_envs": 4},
        "runner": {"max_iterations": 1, "log_dir": str(log_dir)},
        "policy": {
            "latent_dim": PLAY_LATENT_DIM,
            "actor_hidden_dims": [32, 32, 32],
            "critic_hidden_dims": [32, 32],
        },
        "algo": {"num_mini_batches": 2, "num_learning_epochs": 1},
        "torch_threads": 1,
    }
    train(OmegaConf.create(cfg))
    assert list(log_dir.glob("model_*.pt"))
    return log_dir


@pytest.fixture(scope="module")
def loaded(run_dir):
    """run_dir's checkpoint loaded for deployment: (env of 1 env, policy, config, checkpoint), seed 3."""
    from lasmp.deploy import load_deploy_env

    return load_deploy_env(run_dir, num_envs=1, seed=3)
