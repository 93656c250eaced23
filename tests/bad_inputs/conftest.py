"""The bad-input tests' fixtures: each test runs in its own working directory; one finished tiny run
for the session, and a copy of it per test."""

from __future__ import annotations

import shutil
import subprocess
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


@pytest.fixture
def tmpfs(tmp_path):
    """A factory of real, small tmpfs mounts: `tmpfs(size="64k", read_only=False) -> Path`.

    A full or read-only disk fails where a patched `torch.save` does not (inside torch's zip writer,
    in TensorBoard's thread, in a lock's release). Mounting needs root (or CAP_SYS_ADMIN): where it is
    impossible the test is skipped with the reason. Every mount is unmounted at the end."""
    mounts: list[Path] = []

    def make(size: str = "64k", read_only: bool = False) -> Path:
        where = tmp_path / f"tmpfs{len(mounts)}"
        where.mkdir()
        options = f"size={size}" + (",ro" if read_only else "")
        done = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(where)], capture_output=True
        )
        if done.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here ({done.stderr.decode().strip() or 'mount failed'})")
        mounts.append(where)
        return where

    yield make
    for where in reversed(mounts):
        subprocess.run(["umount", "-l", str(where)], capture_output=True)
