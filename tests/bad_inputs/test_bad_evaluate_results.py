"""evaluate.py's results, whole and owned: two evaluations into one --out, a disk that
fills (a real small tmpfs), Ctrl-C, numeric options and seeds, and a record with a repeated episode."""

from __future__ import annotations

import gzip
import json
import os
import re
import signal
from pathlib import Path

import numpy as np
import pytest
from badkit import Outcome, _bench_case, call, evaluate, files, refused, stand_still, succeeded

from lasmp.eval import breakdown as bd
from lasmp.eval import cli
from lasmp.eval import episodes as ep
from lasmp.eval import outdir as od


@pytest.fixture
def bench(tmp_path) -> Path:
    return _bench_case(lambda a: None)(tmp_path / "bench.npz")


def during_the_run(monkeypatch, action) -> None:
    """`action()` once the episodes are played, before anything is written (a disk that fills, a
    second evaluation started meanwhile)."""
    played = cli.run_benchmark

    def run(*args, **kwargs):
        result = played(*args, **kwargs)
        action()
        return result

    monkeypatch.setattr(cli, "run_benchmark", run)


def leftovers(where: Path) -> list[str]:
    """Locks and staging directories of an evaluation under `where` (none may outlive it)."""
    return sorted(
        str(p.relative_to(where)) for p in where.rglob(".*") if ".lock" in p.name or "staging" in p.name
    )


def fill(disk: Path) -> None:
    """Take every free byte of `disk` (a tmpfs): a real full disk, not a patched write."""
    fd = os.open(disk / "filler", os.O_WRONLY | os.O_CREAT, 0o644)
    try:
        while True:
            os.write(fd, os.urandom(4096))
    except OSError:  # ENOSPC: full
        pass
    finally:
        os.close(fd)


# -- E06: one evaluation at a time per --out ---------------------------------------------------------
def test_a_second_evaluation_into_a_directory_another_is_writing_is_refused_and_the_first_keeps_it(
    bench, tmp_path, monkeypatch
):
    out = tmp_path / "ev"
    second: list[Outcome] = []
    during_the_run(monkeypatch, lambda: second.append(stand_still(bench, out, "--force")))
    first = stand_still(bench, out)
    succeeded(first)
    refused(second[0], "another evaluation", f"PID {os.getpid()}", re.escape(str(out)))
    assert json.loads((out / "metrics.json").read_text())["num_episodes"] == 1
    assert sorted(files(out)) == ["episodes.csv.gz", "metrics.json", "metrics.md"]
    assert leftovers(tmp_path) == []


def test_an_evaluation_refused_for_a_lock_or_an_earlier_result_leaves_nothing_behind(bench, tmp_path):
    """A refused evaluation leaves nothing behind: not --out, not the directories above it, no lock."""
    out = tmp_path / "a" / "b" / "ev"
    held = od.ResultDir(out, force=False).claim()  # another evaluation holds it
    try:
        refused(stand_still(bench, out), "another evaluation")
    finally:
        held.close()
    assert not (tmp_path / "a").exists()
    succeeded(stand_still(bench, out))
    before = files(out)
    refused(stand_still(bench, out), "already exists", "--force")
    assert files(out) == before and leftovers(tmp_path) == []


def test_force_replaces_the_earlier_result_whole_and_keeps_the_other_files_of_the_directory(bench, tmp_path):
    """A study's result directory holds the run's config and policy beside its evaluation: --force
    replaces the evaluation's files, all of them (no earlier mirror record beside the new metrics),
    and nothing else."""
    out = tmp_path / "seed0"
    out.mkdir()
    (out / "config.yaml").write_text("seed: 0\n")
    (out / "policy_449.pt").write_bytes(b"weights")
    (out / "metrics.json").write_text('{"earlier": true}')
    (out / "episodes_mirror.csv.gz").write_bytes(b"earlier twins")
    succeeded(stand_still(bench, out, "--force"))
    assert sorted(files(out)) == [
        "config.yaml",
        "episodes.csv.gz",
        "metrics.json",
        "metrics.md",
        "policy_449.pt",
    ]
    assert (out / "policy_449.pt").read_bytes() == b"weights" and "earlier" not in (
        out / "metrics.json"
    ).read_text()
    assert leftovers(tmp_path) == []


def test_metrics_json_records_the_seed_and_the_benchmark_file_s_hash(bench, tmp_path):
    import hashlib

    succeeded(stand_still(bench, tmp_path / "ev", "--seed", "7"))
    result = json.loads((tmp_path / "ev" / "metrics.json").read_text())
    assert (
        result["seed"] == 7 and result["benchmark_sha256"] == hashlib.sha256(bench.read_bytes()).hexdigest()
    )
    assert result["checkpoint"] is None and result["checkpoint_sha256"] is None  # Stand Still has none
    assert (
        f"seed 7, benchmark sha256 {result['benchmark_sha256'][:12]}"
        in (tmp_path / "ev" / "metrics.md").read_text()
    )


# -- E07: a real full disk -------------------------------------------------------------------------------
@pytest.mark.parametrize("earlier", [False, True], ids=["a new directory", "over an earlier result"])
def test_a_disk_that_fills_during_the_evaluation_gets_the_metrics_printed_and_one_line_naming_the_file(
    bench, tmpfs, monkeypatch, earlier
):
    disk = tmpfs(size="256k")
    out = disk / "ev"
    if earlier:
        out.mkdir()
        (out / "metrics.json").write_text('{"earlier": true}')
    before = files(out)
    during_the_run(monkeypatch, lambda: fill(disk))
    result = stand_still(bench, out, *(["--force"] if earlier else []))
    refused(result, "No space left on device")
    assert result.code == 1
    assert "| collision rate |" in result.text  # the work is not lost unsaid
    errors = [line for line in result.text.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and f"cannot write {out}/" in errors[0] and "not saved" in errors[0], result.text
    assert files(out) == before and leftovers(disk) == []  # the earlier result is as it was


def test_a_disk_already_full_is_refused_before_any_episode_is_played(bench, tmpfs):
    disk = tmpfs(size="64k")
    fill(disk)
    result = stand_still(bench, disk / "ev")
    refused(result, "No space left on device|KiB free", re.escape(str(disk / "ev")))
    assert result.code == 2 and "episodes/s" not in result.text  # before the work
    assert sorted(p.name for p in disk.iterdir()) == ["filler"]


def test_a_read_only_disk_is_refused_before_any_episode_is_played(bench, tmpfs):
    disk = tmpfs(read_only=True)
    result = stand_still(bench, disk / "ev")
    refused(result, "cannot write results to", "Read-only file system")
    assert "episodes/s" not in result.text and list(disk.iterdir()) == []


# -- E04: Ctrl-C -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("earlier", [False, True], ids=["a new directory", "over an earlier result"])
def test_ctrl_c_during_the_evaluation_says_in_one_line_that_nothing_was_written(
    bench, tmp_path, monkeypatch, earlier
):
    out = tmp_path / "ev"
    if earlier:
        out.mkdir()
        (out / "metrics.json").write_text('{"earlier": true}')
    before = files(out)

    def ctrl_c(*args, **kwargs):
        signal.raise_signal(signal.SIGINT)  # as the terminal sends it: Python's handler raises

    monkeypatch.setattr(cli, "run_benchmark", ctrl_c)
    try:
        result = stand_still(bench, out, *(["--force"] if earlier else []))
    except KeyboardInterrupt:
        pytest.fail("Ctrl-C escaped evaluate's main")
    assert result.code == 130 and "Traceback" not in result.text, result.text
    lines = [line for line in result.text.splitlines() if "interrupted" in line]
    assert len(lines) == 1 and f"nothing written to {out}" in lines[0] and "lock" in lines[0], result.text
    assert files(out) == before and out.exists() == earlier and leftovers(tmp_path) == []


def test_ctrl_c_while_the_result_is_put_in_place_waits_until_it_is_whole():
    with pytest.raises(KeyboardInterrupt):
        with od._signals_deferred():
            signal.raise_signal(signal.SIGINT)
            reached = True  # not cut here: the signal is held until the block ends
    assert reached


# -- numeric options and seeds ----------------------------------------------------------------------------
@pytest.mark.parametrize(
    "argv, option",
    [
        (["--num-trajectories", "0"], "--num-trajectories"),
        (["--num-trajectories", "-3"], "--num-trajectories"),
        (["--num-trajectories", "99"], "--num-trajectories"),  # more than the benchmark holds
        (["--batch-envs", "0"], "--batch-envs"),
        (["--mirror", "0"], "--mirror"),
        (["--torch-threads", "0"], "--torch-threads"),
        (["--seed", "-1"], "--seed"),
        (["--seed", str(2**32)], "--seed"),
        (["--seed", "1.5"], "--seed"),
        (["--suite", "real_motion", "--robots-per-scenario", "0"], "--robots-per-scenario"),
    ],
)
def test_evaluate_refuses_a_numeric_option_out_of_range_instead_of_a_default(bench, tmp_path, argv, option):
    """None is read by truthiness or replaced by a default: `--robots-per-scenario 0` played 64 robots."""
    out = tmp_path / "x" / "ev"
    result = evaluate("--controller", "stand_still", "--benchmark", str(bench), "--out", str(out), *argv)
    refused(result, re.escape(option))
    assert result.code == 2 and not (tmp_path / "x").exists()


@pytest.mark.parametrize(
    "argv", [["--late-s", "nan"], ["--late-s", "-1"], ["--late-s", "inf"], ["--episodes", "0"]]
)
def test_breakdown_refuses_a_numeric_option_out_of_range(tmp_path, argv):
    ep.write_csv(tmp_path / ep.EPISODES_FILE, record(3))
    result = call(bd.main, [str(tmp_path), *argv])
    refused(result, re.escape(argv[0]))
    assert result.code == 2


# -- G08: a record with a repeated episode -----------------------------------------------------------------
def record(n: int) -> dict[str, np.ndarray]:
    t = {c: np.zeros(n) for c in ep.WRITTEN_COLUMNS}
    t["episode"] = np.arange(n)
    t["collided"] = np.array([1.0] + [0.0] * (n - 1))
    t["collision_cause"] = np.array(["trunk"] + [""] * (n - 1), dtype=object)
    return t


def test_breakdown_refuses_a_record_with_an_episode_in_two_rows_naming_the_file_and_the_episode(tmp_path):
    """Before: the pasted row counted episode 0's collision twice (2 of 4 instead of 1 of 3)."""
    path = tmp_path / ep.EPISODES_FILE
    ep.write_csv(path, record(3))
    lines = gzip.decompress(path.read_bytes()).decode().splitlines()
    path.write_bytes(gzip.compress(("\n".join([*lines, lines[1]]) + "\n").encode()))
    result = call(bd.main, [str(tmp_path)])
    refused(result, re.escape(str(path)), "episode 0 appears 2 times", "rows 2, 5")
    assert result.code == 2 and len(result.text.strip().splitlines()) == 1


def test_breakdown_does_not_replace_an_existing_plot_without_force(tmp_path):
    ep.write_csv(tmp_path / ep.EPISODES_FILE, record(3))
    plot = tmp_path / "mine.png"
    plot.write_bytes(b"my figure")
    refused(call(bd.main, [str(tmp_path), "--plot", str(plot)]), "already exists", "--force")
    assert plot.read_bytes() == b"my figure"
    refused(call(bd.main, [str(tmp_path), "--plot", str(tmp_path / "b.pdf")]), "unknown extension")
    assert not (tmp_path / "b.pdf").exists()
