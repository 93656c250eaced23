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


MAX_TRACKED_BYTES = 80 * 10**6  # a light clone: code, docs, the shipped policy, each study run's records
LADDER = "results/ladder"  # the ladder's runs (scripts/ladder.py): a budget per run, not in the 80 MB
MAX_LADDER_RUN_BYTES = 10**6  # a collected run: its light policy_best.pt, curve, config and commands
MAX_SNAPSHOT_BYTES = 2 * 10**6  # a run still training: its newest policy checkpoint (with the critic)


def test_the_tracked_tree_outside_the_ladder_weighs_at_most_80_mb():
    """`git ls-files | xargs du -cb`: what a clone's work tree holds. A run adds its light policy (under
    1 MB); per-episode records are derived data (`python -m lasmp.eval.regenerate`)."""
    total = sum(p.stat().st_size for p in tracked(".") if LADDER not in p.relative_to(ROOT).as_posix())
    assert total <= MAX_TRACKED_BYTES, (
        f"the tracked tree outside {LADDER} weighs {total / 1e6:.1f} MB, over 80 MB"
    )


def test_each_ladder_run_adds_at_most_1_mb_and_only_planned_runs_are_tracked():
    """The ladder's budget: a collected run adds at most 1 MB, a snapshot of one still training at most
    2 MB (`python scripts/ladder.py snapshot`), and only the runs its plan names (scripts/ladderlib/rungs.py)
    are there, so that the ladder adds at most 1 MB per planned run to the clone."""
    from testkit import load_script

    rungs = load_script("scripts/ladder.py").RUNGS
    planned = {f"{name}/seed{seed}" for name, rung in rungs.items() for seed in rung.seeds}
    runs: dict[str, dict[str, int]] = {}
    for path in tracked(LADDER):
        parts = path.relative_to(ROOT / LADDER).parts
        if len(parts) < 3 or not parts[1].startswith("seed"):
            continue  # the ladder's own notes and side experiments (warm_start_shock/)
        part = "snapshot" if parts[2] == "in_progress" else "collected"
        run = runs.setdefault(f"{parts[0]}/{parts[1]}", {"collected": 0, "snapshot": 0})
        run[part] += path.stat().st_size
    assert runs, f"git tracks no run under {LADDER}/"
    assert set(runs) <= planned, f"runs the ladder does not plan: {sorted(set(runs) - planned)}"
    over = [
        f"{run} ({sizes[part]:,} bytes {part})"
        for run, sizes in sorted(runs.items())
        for part, cap in (("collected", MAX_LADDER_RUN_BYTES), ("snapshot", MAX_SNAPSHOT_BYTES))
        if sizes[part] > cap
    ]
    assert not over, "ladder runs over their budget: " + ", ".join(over)


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
