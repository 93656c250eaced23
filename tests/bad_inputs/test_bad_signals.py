"""train.py and signals at every moment: a SIGTERM in the middle of a long rollout, a second Ctrl-C
while a checkpoint is being written."""

from __future__ import annotations

import os
import shlex
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

from badkit import ROOT, tiny, train_py

from lasmp.algo.checkpoint import read_checkpoint


def _wait_for(proc: subprocess.Popen, prefix: str, count: int = 1, timeout_s: float = 300) -> list[str]:
    """The lines train.py prints until the `count`-th that starts with `prefix`."""
    seen, lines, deadline = 0, [], time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        assert line, f"train.py ended before {prefix!r}: {proc.stderr.read()[-2000:]}"
        lines.append(line)
        seen += line.startswith(prefix)
        if seen == count:
            return lines
    raise AssertionError(f"no {prefix!r} within {timeout_s} s")


def _end(proc: subprocess.Popen, timeout_s: float) -> tuple[str, str, float]:
    started = time.monotonic()
    try:
        out, err = proc.communicate(timeout=timeout_s)
    finally:
        if proc.poll() is None:
            proc.kill()
    return out, err, time.monotonic() - started


def test_a_sigterm_in_a_long_rollout_stops_within_seconds_with_a_checkpoint_and_the_resume_command(tmp_path):
    run = tmp_path / "run"
    # 2,000 env-steps an iteration: finishing it before stopping would take many seconds
    args = tiny("runner.num_steps_per_env=2000", "runner.max_iterations=50", "runner.save_interval=1000")
    proc = train_py([*args, f"runner.log_dir={run}"], tmp_path)
    try:
        lines = _wait_for(proc, "it ", count=2)  # iterations 0 and 1 done (model_0.pt by the save interval)
        time.sleep(0.5)  # into iteration 2's rollout
        proc.send_signal(signal.SIGTERM)
        out, err, waited = _end(proc, 60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 143, err[-2000:]
    # sooner than the rollout would have ended: iteration 1's rate (steps/s, on the same loaded machine)
    # gives the time of the 2,000 steps x 4 envs it stopped in
    rate = float(lines[-1].split("|")[1].split()[0].replace(",", ""))
    rollout_s = 2_000 * 4 / rate
    assert waited < rollout_s, f"{waited:.1f} s to stop, a whole rollout takes {rollout_s:.1f} s"
    assert "Traceback" not in out + err
    assert "iteration 2's rollout" in out and "not an exact resume" in out
    saved = read_checkpoint(run / "model_1.pt")  # the last completed iteration, with the envs of the stop
    assert saved["iter"] == 1 and saved["abandoned_rollout"]["iteration"] == 2
    command = out.split("resume with:")[1].strip().splitlines()[0]
    assert f"resume={run / 'model_1.pt'}" in command

    resume = [a for a in shlex.split(command)[2:] if not a.startswith("runner.max_iterations=")]
    again = subprocess.run(
        [
            sys.executable,
            str(ROOT / "train.py"),
            *resume,
            "runner.max_iterations=1",
            "runner.num_steps_per_env=5",
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=300,
    )
    assert again.returncode == 0, again.stderr[-2000:]
    assert "resume: not exact" in again.stdout and "at iteration 2" in again.stdout
    assert read_checkpoint(run / "model_2.pt")["iter"] == 2


def test_a_sigterm_in_the_first_rollout_of_a_resume_keeps_the_resumed_checkpoint(tmp_path):
    """Nothing to write: the run's newest checkpoint is the state of the last completed iteration,
    and resuming from it again is exact."""
    run = tmp_path / "run"
    first = subprocess.run(
        [sys.executable, str(ROOT / "train.py"), *tiny(f"runner.log_dir={run}")],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=300,
    )
    assert first.returncode == 0, first.stderr[-2000:]
    before = (run / "model_0.pt").read_bytes()
    args = tiny("runner.num_steps_per_env=2000", "runner.max_iterations=5", f"resume={run / 'model_0.pt'}")
    proc = train_py(args, tmp_path)
    try:
        _wait_for(proc, "training ")
        time.sleep(1.5)
        proc.send_signal(signal.SIGTERM)
        out, err, waited = _end(proc, 60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 143, err[-2000:]
    assert waited < 30 and "Traceback" not in out + err  # not the rest of 5 iterations of 2,000 steps
    assert f"its checkpoint is {run / 'model_0.pt'}" in out and "resume with:" in out
    assert (run / "model_0.pt").read_bytes() == before
    assert sorted(p.name for p in run.glob("model_*.pt")) == ["model_0.pt"]


# train.py with its binary files but model_0.pt written slowly (torch.save's zip writer calls this
# write: about 300 times for a tiny checkpoint), so that a second signal lands inside the writing of
# the checkpoint of the first one
SLOW_SAVE = textwrap.dedent("""
    import builtins, io, runpy, sys, time
    import lasmp.io.atomic

    class Slow(io.FileIO):
        said = False

        def write(self, b):
            if ".model_0.pt." in self.name:  # the save interval's: at full speed
                return super().write(b)
            if not self.said:
                print("writing", self.name, flush=True)
                self.said = True
            time.sleep(0.2)
            return super().write(b)

    lasmp.io.atomic.open = lambda path, mode="r": Slow(path, mode) if mode == "wb" else builtins.open(path, mode)
    sys.argv = sys.argv[1:]  # [train.py, overrides...]
    runpy.run_path(sys.argv[0], run_name="__main__")
""")


def test_a_second_ctrl_c_while_the_checkpoint_is_written_exits_130_in_one_line_leaving_no_partial_file(
    tmp_path,
):
    run = tmp_path / "run"
    args = tiny("runner.max_iterations=1000", "runner.save_interval=1000", f"runner.log_dir={run}")
    proc = subprocess.Popen(
        [sys.executable, "-c", SLOW_SAVE, str(ROOT / "train.py"), *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        _wait_for(proc, "it ", count=2)
        proc.send_signal(signal.SIGINT)
        lines = _wait_for(proc, "writing")  # the stop's checkpoint is being written
        assert any("SIGINT: stopping" in line for line in lines)
        time.sleep(0.3)
        proc.send_signal(signal.SIGINT)
        out, err, waited = _end(proc, 30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err[-2000:]
    assert waited < 30  # at once: the slow write would take about 60 s (300 writes of 0.2 s)
    assert "Traceback" not in out + err and "RuntimeError" not in err
    assert [line for line in err.splitlines() if line.strip()] == [
        "SIGINT again: stopped at once, without a checkpoint (the last saved one is intact)"
    ]
    assert sorted(p.name for p in run.glob("model_*.pt")) == ["model_0.pt"]  # no partial file, final name
    left = list(run.glob(".model_*.pt.*.tmp"))
    assert len(left) == 1  # os._exit left the temporary file of the write...
    again = subprocess.run(
        [sys.executable, str(ROOT / "train.py"), *tiny(f"resume={run / 'model_0.pt'}")],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=300,
    )
    assert again.returncode == 0, again.stderr[-2000:]
    assert "removed 1 temporary file(s)" in again.stdout  # ...which the next command in the run clears
    assert not list(Path(run).glob(".*.tmp"))
