"""The repository stays light to clone: what git tracks under results/ and resources/ is
records and policies, never a training run's state, and evaluate.py's default output stays out of git.

These read the git checkout the tests run in; from an unpacked archive (no git) they skip.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from lasmp.algo.checkpoint import OPTIMIZER_KEYS, read_checkpoint
from lasmp.algo.checkpoint.light import LIGHT_KIND

ROOT = Path(__file__).resolve().parents[1]
MAX_RESULT_FILE_BYTES = 5 * 1024**2  # 5 MiB: a 10,000-episode record compressed is about 2.5


def git(*args: str) -> subprocess.CompletedProcess:
    """`git args` in the repository; skips the test where there is no git checkout to ask."""
    if shutil.which("git") is None:
        pytest.skip("git is not installed: the tracked files cannot be listed")
    out = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True)
    if out.returncode not in (0, 1) or "not a git repository" in out.stderr:
        pytest.skip(f"{ROOT} is not a usable git checkout: {out.stderr.strip()}")
    return out


def tracked(*folders: str) -> list[Path]:
    """The files git tracks under `folders` that the working tree holds."""
    names = git("ls-files", "-z", "--", *folders).stdout.split("\0")
    return [ROOT / n for n in names if n and (ROOT / n).is_file()]


MAX_TRACKED_BYTES = 80 * 10**6  # a light clone: code, docs, the shipped policy, each run's records


def test_the_tracked_tree_weighs_at_most_80_mb():
    """`git ls-files | xargs du -cb`: what a clone's work tree holds. A run adds its light policy (under
    1 MB); per-episode records are derived data (`python -m lasmp.eval.regenerate`)."""
    total = sum(p.stat().st_size for p in tracked("."))
    assert total <= MAX_TRACKED_BYTES, f"the tracked tree weighs {total / 1e6:.1f} MB, over 80 MB"


def test_no_tracked_file_under_results_exceeds_5_mib():
    files = tracked("results")
    assert files, "git tracks nothing under results/"
    big = [p for p in files if p.stat().st_size > MAX_RESULT_FILE_BYTES]
    assert not big, (
        f"tracked files over {MAX_RESULT_FILE_BYTES / 1024**2:.0f} MiB under results/ (gzip a record: "
        "gzip -n -9; keep a checkpoint's policy only: python -m lasmp.algo.checkpoint policy): "
        + ", ".join(f"{p.relative_to(ROOT)} ({p.stat().st_size / 1024**2:.1f} MiB)" for p in big)
    )


def test_every_tracked_checkpoint_is_a_policy_checkpoint_not_a_training_state():
    """A policy checkpoint (`python -m lasmp.algo.checkpoint policy`) is marked kind "policy" and
    holds no optimizer states and no envs' running state: a few MB that play and evaluate; its light
    form (`python -m lasmp.algo.checkpoint.light`, kind "actor") holds the actor alone. A full
    checkpoint (24-29 MB) belongs in the run directory it resumes, not in git. Read with
    weights_only, as every checkpoint is: a tracked file that is not plain tensors fails here too."""
    checkpoints = [p for p in tracked("results", "resources") if p.suffix == ".pt"]
    assert checkpoints, "git tracks no .pt under results/ or resources/ (the shipped policy is one)"
    full = []
    for path in checkpoints:
        data = read_checkpoint(path)
        training_state = [k for k in OPTIMIZER_KEYS if k in data]
        if "run" in (data.get("env_state") or {}):
            training_state.append("env_state.run")
        if data.get("kind") not in ("policy", LIGHT_KIND) or training_state:
            full.append(f"{path.relative_to(ROOT)} (kind {data.get('kind')!r}, {training_state})")
    assert not full, (
        f"full training checkpoints tracked (convert: python -m lasmp.algo.checkpoint policy): {full}"
    )


def test_git_ignores_evaluate_s_default_output_and_not_the_eval_packages():
    def ignored(path: str) -> bool:
        return git("check-ignore", "--no-index", "-q", path).returncode == 0

    assert ignored("eval/stand_still/metrics.json")  # evaluate.py's default --out, from the root
    assert ignored("eval/real_motion/stand_still/episodes.csv.gz")
    assert not ignored("lasmp/eval/new_module.py") and not ignored("tests/eval/test_new.py")
