"""The bad-input tests' fixtures: each test runs in its own working directory; one finished tiny run
for the session, and a copy of it per test."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from badkit import succeeded, tiny, train


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a default run directory (logs/...) lands here


@pytest.fixture(scope="session")
def base_run(tmp_path_factory) -> Path:
    """A finished tiny run: config.yaml, model_0.pt, model_1.pt."""
    run = tmp_path_factory.mktemp("base") / "run"
    out = train(tiny("runner.max_iterations=2", f"runner.log_dir={run}"))
    succeeded(out)
    assert (run / "model_1.pt").exists() and (run / "config.yaml").exists()
    return run


@pytest.fixture
def run_copy(base_run, tmp_path) -> Path:
    dst = tmp_path / "run"
    shutil.copytree(base_run, dst)
    return dst
