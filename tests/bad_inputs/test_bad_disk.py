"""train.py on a real disk that is full or turns read-only: small tmpfs mounts (the `tmpfs` fixture,
conftest.py), not a patched `torch.save`, since a real disk fails where a patch does not (inside
torch's zip writer, in TensorBoard's writer thread, in the run lock's release). Each case: one line
naming the file, no traceback, and nothing left that would block the rerun."""

from __future__ import annotations

import errno
import os
import subprocess
import time
from pathlib import Path

import pytest
from badkit import refused, succeeded, tiny, train, train_py

from lasmp.algo.runner import LasmpRunner


def _fill(disk: Path, leave: int = 0) -> Path:
    """Fill `disk` with one file until at most `leave` bytes are free; return the file."""
    filler = disk / "filler"
    with open(filler, "wb") as f:
        try:
            while os.statvfs(disk).f_bavail * os.statvfs(disk).f_frsize > leave:
                f.write(b"\0" * 4096)
                f.flush()
        except OSError as err:
            assert err.errno == errno.ENOSPC
    return filler


def test_a_disk_too_small_for_the_runs_checkpoints_is_refused_before_anything_is_written(tmpfs):
    disk = tmpfs("256k")
    run = disk / "run"
    out = train(tiny(f"runner.log_dir={run}"))
    refused(out, f"runner.log_dir={run}", "free", "checkpoints of")
    assert not out.text.count("error:") > 1
    assert os.listdir(disk) == []  # not even the run directory


def test_a_disk_that_fills_up_at_a_save_gives_one_line_naming_the_checkpoint(tmpfs, monkeypatch):
    """F01: torch's zip writer raises `RuntimeError: [enforce fail at inline_container.cc]` after the
    OSError of a full disk: it must still be one write error naming the file."""
    disk = tmpfs("8m")
    run = disk / "run"
    save = LasmpRunner.save

    def on_a_full_disk(self, path, infos=None):
        _fill(disk, leave=32 << 10)  # room for the zip's first records, not for the weights
        return save(self, path, infos)

    monkeypatch.setattr(LasmpRunner, "save", on_a_full_disk)
    out = train(tiny(f"runner.log_dir={run}"))
    refused(out, "No space left on device")
    lines = [line for line in out.text.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and "model_0.pt" in lines[0] and "inline_container" not in out.text, out.text[
        -2000:
    ]
    assert not list(run.glob(".*.tmp")) and not list(run.glob("model_*.pt"))


def test_a_disk_full_when_training_starts_names_the_file_and_leaves_nothing_that_blocks_the_rerun(
    tmpfs, monkeypatch
):
    """F03: the disk fills between the checks and rsl_rl's first writes (its git diff, TensorBoard's
    events file): one line naming a file of the run, no thread traceback, and no config.yaml left
    (else the rerun is refused as a directory that holds a run)."""
    disk = tmpfs("8m")
    run = disk / "run"
    learn = LasmpRunner.learn
    filler = []

    def on_a_full_disk(self, *args, **kwargs):
        filler.append(_fill(disk))
        return learn(self, *args, **kwargs)

    monkeypatch.setattr(LasmpRunner, "learn", on_a_full_disk)
    out = train(tiny(f"runner.log_dir={run}"))
    refused(out, "No space left on device", f"cannot write {run}")
    assert "Exception in thread" not in out.text
    assert not run.exists() or not {"config.yaml", "git"} & set(os.listdir(run)), os.listdir(run)

    monkeypatch.setattr(LasmpRunner, "learn", learn)
    filler[0].unlink()
    succeeded(train(tiny(f"runner.log_dir={run}")))  # the rerun into the same directory trains


def _read_only_bind(where: Path) -> None:
    """Make `where` read-only under a running process: a read-only bind mount over it. (A remount of
    the tmpfs itself is refused while the training holds files open for writing: its lock, its
    TensorBoard events.) Its open files stay writable; every new file (a save) fails with EROFS. The
    remount is refused (busy) while a file is open for writing through the bind mount itself, as
    TensorBoard's events file is for an instant at each flush: it is tried again a few times."""
    subprocess.run(["mount", "--bind", str(where), str(where)], check=True)
    for _ in range(40):
        done = subprocess.run(["mount", "-o", "remount,bind,ro", str(where)], capture_output=True)
        if done.returncode == 0:
            return
        time.sleep(0.05)
    subprocess.run(["umount", "-l", str(where)], capture_output=True)
    pytest.skip(f"cannot make a read-only bind mount here ({done.stderr.decode().strip()})")


def test_a_run_directory_turned_read_only_mid_run_reports_the_failed_save_not_the_lock(tmpfs):
    """F02: train.py in a process, its run directory turned read-only while it trains: the error is
    the first failed write's, not the lock's release (it cannot remove `.lock`) after it. That write
    is a save (a checkpoint) or TensorBoard's next flush (it reopens its events file for each append),
    whichever the timing brings first."""
    disk = tmpfs("64m")
    run = disk / "run"
    proc = train_py(tiny("runner.max_iterations=200", f"runner.log_dir={run}"), disk.parent)
    bound = False
    try:
        deadline = time.monotonic() + 300
        for line in proc.stdout:
            if line.startswith("it 1/"):
                break
            assert time.monotonic() < deadline, "no second iteration in time"
        _read_only_bind(run)
        bound = True
        out, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
        if bound:
            subprocess.run(["umount", "-l", str(run)], capture_output=True)
    assert proc.returncode == 1, err[-3000:]
    assert "Traceback" not in out + err and "Exception in thread" not in err, err[-3000:]
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "Read-only file system" in lines[0], err[-3000:]
    assert lines[0].startswith(
        (f"error: cannot write {run}/model_", f"error: cannot write {run}/events.out.")
    ), lines[0]
    assert list(run.glob("model_*.pt"))  # the checkpoints saved before are kept


def test_tensorboards_failed_append_names_its_events_file_as_text(tmp_path, monkeypatch):
    """TensorBoard reopens its events file for each append, so a disk turned read-only fails there
    with an OSError that names the file in bytes: one line naming it as a path, as a save's would."""
    from tensorboard.compat.tensorflow_stub.io import gfile

    def read_only(self, filename, file_content, binary_mode=False):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), os.fsencode(filename))

    monkeypatch.setattr(gfile.LocalFileSystem, "append", read_only)
    run = tmp_path / "run"
    out = train(tiny(f"runner.log_dir={run}"))
    refused(out, "Read-only file system")
    lines = [line for line in out.text.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and lines[0].startswith(f"error: cannot write {run}/events.out.tfevents."), (
        out.text[-2000:]
    )
    assert "b'" not in lines[0] and "Exception in thread" not in out.text


def test_a_disk_with_no_byte_left_names_the_run_lock_it_cannot_write_and_leaves_nothing(tmpfs):
    """The careless rerun of F03: a disk already full to the last byte fails at the run's lock file
    (its PID), before any check of the space; the line names that file, and the run directory made for
    it is removed again."""
    disk = tmpfs("64k")
    _fill(disk)
    run = disk / "run"
    out = train(tiny(f"runner.log_dir={run}"))
    refused(out, f"cannot write {run / '.lock'}", "No space left on device")
    assert sorted(os.listdir(disk)) == ["filler"]
