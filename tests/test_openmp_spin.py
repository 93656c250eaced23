"""lasmp sets a short OpenMP spin (GOMP_SPINCOUNT) before torch loads, unless the user set one: torch's
spinning threads otherwise take cores from the physics threads (lasmp/__init__.py)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(args, spin: str | None) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "GOMP_SPINCOUNT"}
    if spin is not None:
        env["GOMP_SPINCOUNT"] = spin
    return subprocess.run(
        [sys.executable, *args], env=env, cwd=ROOT, capture_output=True, text=True, check=True
    )


@pytest.mark.parametrize(("user", "expected"), [(None, "10000"), ("123", "123")])
def test_importing_lasmp_sets_the_spin_unless_the_user_did(user, expected):
    out = _run(["-c", "import lasmp, os; print(os.environ['GOMP_SPINCOUNT'])"], user)
    assert out.stdout.strip() == expected


@pytest.mark.parametrize("script", ["train.py", "evaluate.py", "play.py", "bench/env_throughput.py"])
def test_the_entry_points_import_lasmp_before_torch(script):
    """libgomp reads the variable when torch loads it: an entry point that imports torch first loses it."""
    log = _run(["-X", "importtime", script, "--help"], None).stderr
    order = [m.group(1) for m in re.finditer(r"\|\s+(lasmp|torch)$", log, re.MULTILINE)]
    assert order and order[0] == "lasmp", f"{script} imports {order[:1]} first"
