"""What lasmp reads of TensorBoard below its public API (lasmp/compat/tensorboard.py says why) still reads
what it means in the installed torch and TensorBoard: an upgrade that renames one fails here."""

from __future__ import annotations

import shutil
import threading
from pathlib import Path

import pytest
from testkit import tensorboard_logger
from torch.utils.tensorboard import SummaryWriter

from lasmp.compat.tensorboard import events_file, is_writer_thread, raised_in_tensorboard, writer_thread_error


def test_the_events_file_is_the_one_the_writer_appends_to(tmp_path):
    writer = SummaryWriter(log_dir=str(tmp_path / "run"))
    try:
        events = Path(events_file(writer))
        assert events.parent == tmp_path / "run" and events.name.startswith("events.out.tfevents.")
        assert list((tmp_path / "run").iterdir()) == [events]
        size = events.stat().st_size
        writer.add_scalar("x", 1.0, 0)
        writer.flush()
        assert events.stat().st_size > size
        assert writer_thread_error(writer) is None
    finally:
        writer.close()
    assert events_file(None) is None and events_file(object()) is None
    assert writer_thread_error(None) is None


def test_rsl_rl_s_tensorboard_writer_has_its_events_file_in_the_run(tmp_path):
    logger = tensorboard_logger(tmp_path)
    logger.init_logging_writer()
    try:
        assert Path(events_file(logger.writer)).parent == tmp_path
        assert Path(events_file(logger.writer)).is_file()
    finally:
        logger.writer.close()


def test_a_failed_append_is_the_writer_thread_s_error_raised_in_tensorboard(tmp_path, monkeypatch):
    stopped: list[threading.Thread] = []
    done = threading.Event()

    def hook(args):
        stopped.append(args.thread)
        done.set()

    monkeypatch.setattr(threading, "excepthook", hook)
    writer = SummaryWriter(log_dir=str(tmp_path / "run"))
    shutil.rmtree(tmp_path / "run")  # TensorBoard reopens its events file for each append
    writer.add_scalar("x", 1.0, 0)
    with pytest.raises(OSError) as raised:
        writer.flush()
    assert done.wait(timeout=30)
    assert writer_thread_error(writer) is raised.value
    assert raised_in_tensorboard(raised.value)
    assert len(stopped) == 1 and is_writer_thread(stopped[0])
    assert not is_writer_thread(threading.current_thread())
    try:
        raise OSError("elsewhere")
    except OSError as err:
        assert not raised_in_tensorboard(err)
