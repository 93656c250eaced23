"""train.py's run directory (runner.log_dir, resume=): a directory that holds a run, part of one, a
file or a lock; resuming in place or branching; a stale temporary file; a working directory left
clean."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys

import pytest
from badkit import ROOT, files, latest, refused, succeeded, tiny, train, train_py


# -- run directories -----------------------------------------------------------------------------
def test_a_new_training_into_a_directory_that_holds_a_run_is_refused_naming_both(run_copy):
    before = files(run_copy)
    out = train(tiny(f"runner.log_dir={run_copy}"))
    refused(out, re.escape(str(run_copy)), "model_1.pt", "resume=")
    assert files(run_copy) == before


@pytest.mark.parametrize("name", ["config.yaml", "model_3.pt"])
def test_a_directory_holding_only_part_of_a_run_is_refused_too(tmp_path, name):
    run = tmp_path / "run"
    run.mkdir()
    (run / name).write_text("from an earlier run")
    out = train(tiny(f"runner.log_dir={run}"))
    refused(out, re.escape(str(run)), re.escape(name))
    assert files(run) == {name: b"from an earlier run"}


def test_a_directory_with_unrelated_files_trains_and_keeps_them(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / "notes.txt").write_text("mine")
    succeeded(train(tiny(f"runner.log_dir={run}")))
    assert (run / "notes.txt").read_text() == "mine" and (run / "model_0.pt").exists()


def test_a_run_directory_that_is_a_file_is_refused_naming_it(tmp_path):
    target = tmp_path / "run"
    target.write_text("a file")
    out = train(tiny(f"runner.log_dir={target}"))
    refused(out, re.escape(str(target)))
    assert target.read_text() == "a file"


def test_a_run_directory_below_a_file_is_refused_naming_it(tmp_path):
    (tmp_path / "afile").write_text("a file")
    out = train(tiny(f"runner.log_dir={tmp_path / 'afile' / 'run'}"))
    refused(out, "afile")
    assert (tmp_path / "afile").read_text() == "a file"


def test_a_second_training_into_a_locked_run_directory_names_the_first_ones_pid(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time\nfrom lasmp.io.rundir import RunLock\nRunLock(sys.argv[1]).acquire()\n"
            "print('locked', flush=True)\ntime.sleep(120)",
            str(run),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    try:
        line = holder.stdout.readline()
        assert line.strip() == "locked", holder.stderr.read()[-2000:]
        before = files(run)
        out = train(tiny(f"runner.log_dir={run}"))
        refused(out, f"PID {holder.pid}", re.escape(str(run)))
        assert files(run) == before
    finally:
        holder.kill()
        holder.wait(timeout=30)


def test_a_stale_lock_file_of_a_process_that_ended_does_not_block(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / ".lock").write_text("999999\n")
    succeeded(train(tiny(f"runner.log_dir={run}")))
    assert (run / "model_0.pt").exists()


def test_resume_of_a_run_directory_continues_in_it(run_copy, tmp_path):
    out = train(tiny(f"resume={run_copy}"))
    succeeded(out)
    assert latest(run_copy).name == "model_2.pt"
    assert not (tmp_path / "logs").exists()  # no new dated run directory


def test_resume_of_a_checkpoint_file_continues_in_its_directory(run_copy, tmp_path):
    succeeded(train(tiny(f"resume={run_copy / 'model_1.pt'}")))
    assert latest(run_copy).name == "model_2.pt"
    assert not (tmp_path / "logs").exists()


def test_resume_with_the_printed_command_continues_in_the_run_directory(run_copy):
    succeeded(train(tiny(f"resume={run_copy / 'model_1.pt'}", f"runner.log_dir={run_copy}")))
    assert latest(run_copy).name == "model_2.pt"


def test_resume_of_an_older_checkpoint_into_its_own_directory_is_refused(run_copy):
    before = files(run_copy)
    out = train(tiny(f"resume={run_copy / 'model_0.pt'}"))
    refused(out, "model_1.pt", "runner.log_dir")
    assert files(run_copy) == before


def test_resume_into_another_empty_directory_branches_there_and_keeps_the_run(run_copy, tmp_path):
    before = files(run_copy)
    branch = tmp_path / "branch"
    succeeded(train(tiny(f"resume={run_copy}", f"runner.log_dir={branch}")))
    assert latest(branch).name == "model_2.pt"
    assert files(run_copy) == before


def test_resume_into_another_directory_that_holds_a_run_is_refused(run_copy, base_run, tmp_path):
    other = tmp_path / "other"
    shutil.copytree(base_run, other)
    before, before_other = files(run_copy), files(other)
    out = train(tiny(f"resume={run_copy}", f"runner.log_dir={other}"))
    refused(out, re.escape(str(other)))
    assert files(run_copy) == before and files(other) == before_other


def test_a_stale_temporary_file_of_a_killed_save_is_removed_by_the_next_start(run_copy):
    stale = run_copy / ".model_2.pt.k1ll3d.tmp"
    stale.write_bytes(b"PK\x03\x04 half a checkpoint")
    out = train(tiny(f"resume={run_copy}"))
    succeeded(out)
    assert not stale.exists() and "removed" in out.text
    assert not list(run_copy.glob(".*.tmp"))


# -- the real CLI --------------------------------------------------------------------------------
def test_a_training_leaves_the_working_directory_clean_but_for_its_run(tmp_path):
    proc = train_py(tiny("runner.log_dir=run"), tmp_path)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err[-2000:]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]  # no train.log, no outputs/
    assert (tmp_path / "run" / "model_0.pt").exists() and not list((tmp_path / "run").glob(".*"))


# -- default run directories: one per job ----------------------------------------------------------
def test_a_default_run_directory_already_taken_in_the_same_second_gets_a_suffix(tmp_path, monkeypatch):
    """H02: the default name has one-second resolution; a second start in that second must not meet
    the first's directory (it would be refused as one that holds a run)."""
    import datetime as real

    import lasmp.cli.run_directory as lt
    from lasmp.config.train import TrainCfg

    class Frozen(real.datetime):
        @classmethod
        def now(cls, tz=None):
            return real.datetime(2026, 1, 2, 3, 4, 5)

    monkeypatch.setattr(lt.datetime, "datetime", Frozen)
    cfg = TrainCfg()
    first = lt.default_log_dir(cfg)
    (tmp_path / first).mkdir(parents=True)
    second = lt.default_log_dir(cfg)
    (tmp_path / second).mkdir(parents=True)
    third = lt.default_log_dir(cfg)
    assert first.endswith("2026-01-02_03-04-05")
    assert (second, third) == (f"{first}-2", f"{first}-3")


def test_a_multirun_with_the_default_log_dir_trains_every_job_and_leaves_no_multirun_directory(tmp_path):
    """H02 and H03: `train.py -m seed=1,2` (jobs of no iteration: they start within one second) gives
    each job its own run directory; Hydra's sweep record goes under logs/, not to ./multirun/."""
    proc = train_py(["-m", "seed=1,2", *tiny("runner.max_iterations=0")], tmp_path)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0 and "Traceback" not in out + err, (out + err)[-3000:]
    runs = sorted((tmp_path / "logs" / "moving_platform" / "lasmp_plus").iterdir())
    assert len(runs) == 2 and all((r / "config.yaml").exists() for r in runs), (out + err)[-3000:]
    seeds = sorted(re.search(r"^seed: (\d+)$", (r / "config.yaml").read_text(), re.M).group(1) for r in runs)
    assert seeds == ["1", "2"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["logs"]  # no multirun/, no outputs/
