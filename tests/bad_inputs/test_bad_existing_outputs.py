"""Files the user already has (issue 58, class 2): every converted writer claims its output file
before the work (create-exclusive, `lasmp.atomic.claim_output`) and refuses one that is already there
without --force: exit code != 0, one line naming it, no traceback, its bytes unchanged; with --force it
is replaced. Writers covered: `lasmp.eval.results_table --json`, `lasmp.eval.benchmark generate`,
`lasmp.envs.trajectories generate` and `plot`."""

from __future__ import annotations

import json
import threading
from pathlib import Path

import pytest
from badkit import call, refused, succeeded

from lasmp.atomic import OutputExistsError, claim_output
from lasmp.envs.trajectories import cli as trj_cli
from lasmp.eval import benchmark as bm
from lasmp.eval import results_table as rt
from lasmp.eval.metrics import ALL_METRICS

USER_DATA = b"user data\n"


def _evaluation(root: Path) -> Path:
    """A minimal evaluation directory: the metrics.json results_table reads."""
    d = root / "eval"
    d.mkdir()
    metrics = {k: {"mean": 0.5, "std": 0.01} for k in ALL_METRICS}
    result = {"method": "m", "benchmark": "b.npz", "num_episodes": 10, "metrics": metrics}
    (d / "metrics.json").write_text(json.dumps(result))
    return d


def _results_table(root: Path, out: Path, *force: str):
    return call(rt.main, ["--method", "A", str(_evaluation(root)), "--json", str(out), *force])


def _benchmark(root: Path, out: Path, *force: str):
    return call(
        bm.main, ["generate", "--out", str(out), "--num-trajectories", "2", "--num-robots", "2", *force]
    )


def _trajectories(root: Path, out: Path, *force: str):
    return call(trj_cli.main, ["generate", "--num", "3", "--out", str(out), *force])


def _trajectory_plot(root: Path, out: Path, *force: str):
    return call(trj_cli.main, ["plot", "--num", "3", "--out", str(out), *force])


WRITERS = {
    "results_table --json": (_results_table, "summary.json", "--json"),
    "benchmark generate": (_benchmark, "xi.npz", "--out"),
    "trajectories generate": (_trajectories, "set.npz", "--out"),
    "trajectories plot": (_trajectory_plot, "paths.png", "--out"),
}


@pytest.mark.parametrize("writer", list(WRITERS))
def test_a_writer_keeps_a_file_the_user_already_has_unless_forced(writer, tmp_path):
    run, name, option = WRITERS[writer]
    out = tmp_path / name
    out.write_bytes(USER_DATA)
    refused_run = run(tmp_path, out)
    refused(refused_run, "already exists", "--force")
    naming = [line for line in refused_run.text.splitlines() if str(out) in line]
    assert len(naming) == 1 and option in naming[0], refused_run.text
    assert out.read_bytes() == USER_DATA
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temporary left
    succeeded(_forced(run, tmp_path, out))
    assert out.read_bytes() != USER_DATA and out.stat().st_size > 0


def _forced(run, tmp_path: Path, out: Path):
    root = tmp_path / "forced"
    root.mkdir()
    return run(root, out, "--force")


@pytest.mark.parametrize("writer", list(WRITERS))
def test_a_writer_that_fails_after_claiming_its_file_leaves_no_empty_file_behind(writer, tmp_path):
    run, name, _ = WRITERS[writer]
    out = tmp_path / "new" / name
    if writer == "results_table --json":
        failed = call(rt.main, ["--method", "A", str(tmp_path / "missing"), "--json", str(out)])
    elif writer == "benchmark generate":
        failed = call(
            bm.main, ["generate", "--set", "validation", "--seed", str(bm.XI_EVAL.seed), "--out", str(out)]
        )
    elif writer == "trajectories generate":  # more trajectories than memory holds: refused after the claim
        failed = call(trj_cli.main, ["generate", "--num", str(10**13), "--out", str(out)])
    else:
        failed = call(trj_cli.main, ["plot", "--file", str(tmp_path / "none.npz"), "--out", str(out)])
    assert failed.code != 0 and "Traceback" not in failed.text, failed.text
    assert not out.exists() and not out.parent.exists()


# what each writer does between claiming its file and writing it: patched to run a second writer there
WORK = {
    "results_table --json": (rt, "summary"),
    "benchmark generate": (bm, "generate"),
    "trajectories generate": (trj_cli, "_traj_from_args"),
    "trajectories plot": (trj_cli, "_traj_from_args"),
}


@pytest.mark.parametrize("writer", list(WRITERS))
def test_a_second_writer_started_while_the_first_works_is_refused_not_overwritten(
    writer, tmp_path, monkeypatch
):
    """A check at the start would let both pass it and the last one replace the other's file; the
    claim (create-exclusive, before the work) refuses the second."""
    run, name, _ = WRITERS[writer]
    out, second = tmp_path / name, []
    module, attr = WORK[writer]
    work = getattr(module, attr)

    def work_with_a_second_writer(*args, **kwargs):
        if not second:
            second.append(None)
            root = tmp_path / "second"
            root.mkdir()
            second[0] = run(root, out)
        return work(*args, **kwargs)

    monkeypatch.setattr(module, attr, work_with_a_second_writer)
    succeeded(run(tmp_path, out))
    refused(second[0], "already exists", "--force")
    assert out.stat().st_size > 0


def test_results_table_json_refuses_to_replace_the_users_file_as_in_the_issue(tmp_path):
    """The issue's example: `python -m lasmp.eval.results_table --json FILE` replaced FILE silently."""
    out = tmp_path / "FILE.json"
    out.write_bytes(USER_DATA)
    refused(
        _results_table(tmp_path, out), r"FILE\.json already exists: choose another --json, or pass --force"
    )
    assert out.read_bytes() == USER_DATA
    succeeded(_forced(_results_table, tmp_path, out))
    assert list(json.loads(out.read_text())["methods"]) == ["A"]


def test_the_claim_is_taken_before_the_work_so_a_second_writer_is_refused_while_the_first_works(tmp_path):
    out = tmp_path / "out.json"
    inside, release, seen = threading.Event(), threading.Event(), []

    def first():
        with claim_output(out, force=False, option="--json") as path:
            inside.set()
            release.wait(5)
            path.write_text("first")  # the writers use an atomic write here

    t = threading.Thread(target=first)
    t.start()
    assert inside.wait(5)
    try:
        with (
            pytest.raises(OutputExistsError, match="out.json already exists"),
            claim_output(out, force=False),
        ):
            seen.append("second ran")
    finally:
        release.set()
        t.join(5)
    assert seen == [] and out.read_text() == "first"
