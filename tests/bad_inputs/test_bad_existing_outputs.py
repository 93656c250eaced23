"""Files the user already has: every converted writer claims its output file
before the work (create-exclusive, `lasmp.io.atomic.claim_output`) and refuses one that is already there
without --force: exit code != 0, one line naming it, no traceback, its bytes unchanged; with --force it
is replaced; a run that fails after its claim leaves no empty file. Writers covered:
`lasmp.eval.results_table --json`, `lasmp.eval.benchmark generate`, `lasmp.envs.trajectories generate`
and `plot`, play.py (--video, --snapshots, --export onnx --out), `lasmp.algo.checkpoint policy` and
`convert`, `lasmp.algo.checkpoint.light SRC DST`, `lasmp.eval.breakdown --plot`, `lasmp.eval.curves --out`
and `lasmp.eval.real_motion generate`; the scripts' outputs are
in test_bad_existing_script_outputs.py."""

from __future__ import annotations

import json
import threading
from pathlib import Path

import numpy as np
import pytest
from badkit import ROOT, call, refused, succeeded

import lasmp.algo.checkpoint.light as light_tool
import lasmp.cli.play as play
from lasmp.algo import checkpoint as ckpt_tool
from lasmp.envs.trajectories import cli as trj_cli
from lasmp.eval import benchmark as bm
from lasmp.eval import benchmark_file
from lasmp.eval import breakdown as bd
from lasmp.eval import curves as curves_tool
from lasmp.eval import episodes as ep
from lasmp.eval import results_table as rt
from lasmp.eval.metrics import ALL_METRICS
from lasmp.eval.real_motion import __main__ as rm_tool
from lasmp.eval.real_motion import suite as rm_suite
from lasmp.io.atomic import OutputExistsError, claim_output

USER_DATA = b"user data\n"
POLICY = ROOT / "resources" / "policies" / "lasmp_a1.pt"  # the shipped policy checkpoint


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


def _play_export(root: Path, out: Path, *force: str):
    """play.py --export onnx --out DIR: `out` is DIR/policy.onnx (DIR/policy.json is claimed as well)."""
    return call(
        play.main,
        ["--checkpoint", str(POLICY), "--steps", "0", "--export", "onnx", "--out", str(out.parent), *force],
    )


def _policy_checkpoint(root: Path, out: Path, *force: str):
    return call(ckpt_tool.main, ["policy", str(POLICY), str(out), *force])


def _convert(root: Path, out: Path, *force: str):
    return call(ckpt_tool.main, ["convert", "--trust", str(POLICY), str(out), *force])


def _light(root: Path, out: Path, *force: str):
    return call(light_tool.main, [str(POLICY), str(out), *force])


def _breakdown(root: Path, out: Path, *force: str):
    """breakdown --plot of a constructed evaluation: three episodes, one a collision."""
    pytest.importorskip("matplotlib")
    d = root / "evaluation"
    d.mkdir()
    t = {c: np.zeros(3) for c in ep.COLUMNS}
    t["episode"], t["collided"] = np.arange(3), np.array([0.0, 1.0, 0.0])
    t["collision_time_s"] = np.array([np.nan, 2.0, np.nan])
    t["collision_cause"] = np.array(["", "trunk", ""], dtype=object)
    ep.write_csv(d / "episodes.csv", t)
    return call(bd.main, [str(d), "--plot", str(out), *force])


def _curves(root: Path, out: Path, *force: str):
    """curves --out of a run of two logged iterations."""
    from torch.utils.tensorboard import SummaryWriter

    run = root / "run"
    writer = SummaryWriter(str(run))
    for it in range(2):  # the main tags and a reward term: every panel has a curve
        for tag in ("Episode/success_rate", "Curriculum/level", "Train/mean_reward", "Episode_Reward/task1"):
            writer.add_scalar(tag, float(it), it)
    writer.close()
    return call(curves_tool.main, [str(run), "--out", str(out), *force])


def _real_motion(root: Path, out: Path, *force: str):
    return call(rm_tool.main, ["generate", "--scenarios", "lift_up", "--out", str(out), *force])


WRITERS = {
    "results_table --json": (_results_table, "summary.json", "--json"),
    "benchmark generate": (_benchmark, "xi.npz", "--out"),
    "trajectories generate": (_trajectories, "set.npz", "--out"),
    "trajectories plot": (_trajectory_plot, "paths.png", "--out"),
    "play --export onnx": (_play_export, "policy.onnx", "--out"),
    "checkpoint policy": (_policy_checkpoint, "policy.pt", "OUT"),
    "checkpoint convert": (_convert, "converted.pt", "OUT"),
    "light_checkpoint": (_light, "light.pt", "DST"),
    "breakdown --plot": (_breakdown, "breakdown.png", "--plot"),
    "curves --out": (_curves, "curve.png", "--out"),
    "real_motion generate": (_real_motion, "motions.npz", "--out"),
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


def _unreadable(tmp_path: Path) -> Path:
    """A checkpoint file the tools find only after their claim to be no checkpoint."""
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a checkpoint")
    return bad


# a run of each writer that fails after its claim (a missing or unreadable input, too large a request)
FAILING = {
    "results_table --json": lambda d, out: call(
        rt.main, ["--method", "A", str(d / "missing"), "--json", str(out)]
    ),
    "benchmark generate": lambda d, out: call(
        bm.main, ["generate", "--set", "validation", "--seed", str(bm.XI_EVAL.seed), "--out", str(out)]
    ),
    # more trajectories than memory holds: refused after the claim
    "trajectories generate": lambda d, out: call(
        trj_cli.main, ["generate", "--num", str(10**13), "--out", str(out)]
    ),
    "trajectories plot": lambda d, out: call(
        trj_cli.main, ["plot", "--file", str(d / "none.npz"), "--out", str(out)]
    ),
    "play --export onnx": lambda d, out: call(
        play.main, ["--checkpoint", str(_unreadable(d)), "--export", "onnx", "--out", str(out.parent)]
    ),
    "checkpoint policy": lambda d, out: call(ckpt_tool.main, ["policy", str(_unreadable(d)), str(out)]),
    "checkpoint convert": lambda d, out: call(
        ckpt_tool.main, ["convert", "--trust", str(_unreadable(d)), str(out)]
    ),
    "light_checkpoint": lambda d, out: call(light_tool.main, [str(_unreadable(d)), str(out)]),
    "breakdown --plot": lambda d, out: call(bd.main, [str(d / "no-evaluation"), "--plot", str(out)]),
    "curves --out": lambda d, out: call(curves_tool.main, [str(d / "no-run"), "--out", str(out)]),
    "real_motion generate": lambda d, out: call(
        rm_tool.main, ["generate", "--scenarios", "no_such_scenario", "--out", str(out)]
    ),
}


@pytest.mark.parametrize("writer", list(WRITERS))
def test_a_writer_that_fails_after_claiming_its_file_leaves_no_empty_file_behind(writer, tmp_path):
    run, name, _ = WRITERS[writer]
    out = tmp_path / "new" / name
    failed = FAILING[writer](tmp_path, out)
    assert failed.code != 0 and "Traceback" not in failed.text, failed.text
    assert not out.exists() and not out.parent.exists()


# what each writer does between claiming its file and writing it: patched to run a second writer there
WORK = {
    "results_table --json": (rt, "summary"),
    "benchmark generate": (bm, "generate"),
    "trajectories generate": (trj_cli, "_traj_from_args"),
    "trajectories plot": (trj_cli, "_traj_from_args"),
    "play --export onnx": (play, "load_deploy_env"),
    "checkpoint policy": (ckpt_tool.forms, "read_checkpoint"),
    "checkpoint convert": (ckpt_tool.format, "_check_format"),
    "light_checkpoint": (light_tool, "read_checkpoint"),
    "breakdown --plot": (bd, "read_csv"),
    "curves --out": (curves_tool, "read_scalars"),
    "real_motion generate": (rm_suite, "build_motions"),
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


def test_results_table_json_refuses_to_replace_an_existing_file(tmp_path):
    """Unclaimed, `python -m lasmp.eval.results_table --json FILE` would replace FILE silently."""
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


# -- the default benchmark, drawn on first use (`lasmp.eval.benchmark.load_or_make`) -------------------
def _draw_with(monkeypatch, meanwhile):
    """generate_set running `meanwhile()` (what another process does) before it returns its draw."""
    draw, calls = bm.generate_set, []

    def drawing(which):
        calls.append(which)
        if len(calls) == 1:
            meanwhile()
        return draw(which)

    monkeypatch.setattr(bm, "generate_set", drawing)


def _arrays_equal(a: bm.Benchmark, b: bm.Benchmark) -> bool:
    x, y = benchmark_file._arrays(a), benchmark_file._arrays(b)
    same = (np.array_equal(x[k], y[k], equal_nan=x[k].dtype.kind == "f") for k in x)  # NaN: padding
    return x.keys() == y.keys() and all(same)


def test_two_processes_drawing_the_default_benchmark_at_once_both_get_it_whole(tmp_path, monkeypatch):
    tiny = bm.BenchmarkSet("tiny", str(tmp_path / "benchmarks" / "tiny.npz"), 3, 2, 2)
    second = []
    _draw_with(monkeypatch, lambda: second.append(bm.load_or_make(tiny)))
    first = bm.load_or_make(tiny)
    assert _arrays_equal(first, second[0]) and _arrays_equal(first, bm.load(tiny.path))
    assert sorted(p.name for p in (tmp_path / "benchmarks").iterdir()) == ["tiny.npz"]  # no temporary


def test_a_file_that_appears_while_the_default_benchmark_is_drawn_is_not_replaced(tmp_path, monkeypatch):
    """The existence check at the start found nothing; the write must still not replace the file."""
    tiny = bm.BenchmarkSet("tiny", str(tmp_path / "tiny.npz"), 3, 2, 2)
    _draw_with(monkeypatch, lambda: Path(tiny.path).write_bytes(USER_DATA))
    with pytest.raises(bm.BenchmarkFileError, match="tiny.npz"):  # it reads the file it found
        bm.load_or_make(tiny)
    assert Path(tiny.path).read_bytes() == USER_DATA
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tiny.npz"]
