"""Hydra sweeps (`python train.py -m ...`, lasmp/cli/command_line.py) as a careless user runs them: a config-key
typo, a job that fails in the middle, a Ctrl-C. A typo was worded by Hydra (its misleading `+key`
hint) instead of the project's "unknown config key" line; a failing job (`-m seed=1,-1,2`) ended the
sweep there, and the jobs after it never ran without a word. Now a typo is refused as in a single
run, before any job; a failed job is said and the sweep goes on, listing the failed jobs at its end;
a Ctrl-C stops the sweep, naming the jobs that did not run. The real CLI runs at tiny sizes."""

from __future__ import annotations

import re
import signal
import subprocess
import time
from pathlib import Path

import pytest
from badkit import Outcome, refused, tiny, train_py


def sweep(args: list[str], cwd: Path) -> Outcome:
    proc = train_py(["-m", *args], cwd)
    out, err = proc.communicate(timeout=300)
    return Outcome(proc.returncode, out + err)


def job_runs(cwd: Path) -> dict[int, Path]:
    """The run directories of the sweep's jobs (default directories: <date_time>_job<N>), by job number."""
    runs = (cwd / "logs" / "moving_platform").glob("*/*_job*")
    return {int(re.search(r"_job(\d+)", p.name)[1]): p for p in runs}


@pytest.mark.parametrize(
    "typo", [["runner.max_iteration=1", "seed=1,2"], ["runner.max_iteration=1,2"]], ids=["fixed", "swept"]
)
def test_a_config_key_typo_in_a_sweep_is_named_as_in_a_single_run_before_any_job(tmp_path, typo):
    out = sweep(typo, tmp_path)
    refused(
        out, r"error: unknown config key 'runner\.max_iteration'; valid keys of runner: .*'max_iterations'"
    )
    assert "+runner" not in out.text and "Launching" not in out.text, out.text[-3000:]
    assert not job_runs(tmp_path)


def test_a_sweep_runs_the_jobs_after_a_failed_one_and_lists_the_failed_ones_at_its_end(tmp_path):
    out = sweep([*tiny(), "seed=1,-1,2"], tmp_path)
    assert out.code == 2, out.text[-3000:]  # the failed job's own exit code
    assert "Traceback" not in out.text, out.text[-3000:]
    assert "error: seed must be an integer" in out.text
    assert "sweep: job #1 (seed=-1) failed (exit 2); going on with the next job" in out.text
    last = out.text.strip().splitlines()[-1]
    assert last.startswith("error: 1 of 3 jobs of the sweep failed: #1 (seed=-1) exit 2"), out.text[-3000:]
    runs = job_runs(tmp_path)
    assert sorted(runs) == [0, 2], out.text[-3000:]  # the job after the failed one ran too
    assert all((run / "model_0.pt").exists() for run in runs.values())


def test_a_ctrl_c_stops_the_sweep_and_names_the_jobs_that_did_not_run(tmp_path):
    long = tiny("runner.max_iterations=1000", "runner.save_interval=1000")
    proc = train_py(["-m", *long, "seed=1,2,3"], tmp_path)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:  # job #0 is training
            line = proc.stdout.readline()
            assert line, f"train.py ended before training: {proc.stderr.read()[-2000:]}"
            if line.startswith("it "):
                break
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err[-3000:]
    assert "Traceback" not in out + err, err[-3000:]
    assert "the sweep stopped at job #0 (seed=1): did not run: #1 (seed=2), #2 (seed=3)" in err, err[-3000:]
    assert sorted(job_runs(tmp_path)) == [0]
