"""Ctrl-C in the seconds a command spends loading torch, MuJoCo and Hydra: one line, no traceback of
whichever module was importing (lasmp/io/ctrl_c.py), for the three scripts and `python -m lasmp.<tool>`."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from lasmp.io.ctrl_c import MESSAGE

ROOT = Path(__file__).resolve().parents[2]


def _torch_loading(pid: int) -> bool:
    """Whether the process has begun to load torch's library (then lasmp's hook is in place)."""
    try:
        return "libtorch_cpu" in Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return False


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="needs /proc to see torch loading")
@pytest.mark.parametrize(
    "command",
    [
        ["train.py", "runner.max_iterations=1"],
        ["play.py", "--checkpoint", "resources/policies/lasmp_a1.pt", "--steps", "1"],
        ["evaluate.py", "--checkpoint", "resources/policies/lasmp_a1.pt", "--num-trajectories", "1"],
        ["-m", "lasmp.eval.results_table", "--help"],
    ],
    ids=["train", "play", "evaluate", "python -m lasmp.eval.results_table"],
)
def test_ctrl_c_while_a_command_loads_ends_it_in_one_line(tmp_path, command):
    proc = subprocess.Popen(
        [sys.executable, *command], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        deadline = time.monotonic() + 60
        while not _torch_loading(proc.pid) and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.005)
        assert proc.poll() is None, "the command ended before torch loaded"
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    # Python's own exit for an interrupt (killed by SIGINT), or a command's own 130 where it was
    # already in its main, which reports the interrupt itself
    assert proc.returncode in (-signal.SIGINT, 130), (proc.returncode, err[-2000:])
    assert "Traceback" not in out + err, err[-2000:]
    assert "interrupted" in err, err[-2000:]


def test_an_uncaught_ctrl_c_in_a_program_that_imports_lasmp_keeps_pythons_own_report():
    code = "import lasmp.io.ctrl_c, lasmp.config.train; raise KeyboardInterrupt"
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert "Traceback" in proc.stderr and MESSAGE not in proc.stderr
