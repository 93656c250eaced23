"""Checkpoint files that are not what a command expects, through the one loader every command uses
(`lasmp.algo.checkpoint.read_checkpoint`): a file that is no PyTorch checkpoint at all is named for
what it is (P23: an ONNX model was told to `convert --trust`, which then failed), only regular files
are read (a FIFO or /dev/zero hung or misled), and a checkpoint of a newer format says so
(C_future_format: it was "not a lasmp checkpoint")."""

from __future__ import annotations

import os
import pickle
import re
import shutil
import signal
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch
from badkit import call, files, refused, tiny, train

from lasmp.algo import checkpoint as ckpt_tool
from lasmp.algo.checkpoint import CheckpointError, read_checkpoint

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ROOT / "resources" / "policies" / "lasmp_a1.pt"
SHIPPED_ONNX = ROOT / "resources" / "policies" / "lasmp_a1.onnx"


@pytest.fixture
def no_hang():
    """Fail a test that blocks (opening a FIFO waits for a writer for ever) instead of hanging the suite."""

    def stop(signum, frame):
        raise TimeoutError("blocked for 20 s")

    old = signal.signal(signal.SIGALRM, stop)
    signal.alarm(20)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, old)


def _copy(src: Path):
    def make(d: Path) -> Path:
        return Path(shutil.copy(src, d / src.name))

    return make


def _bytes(name: str, content: bytes):
    def make(d: Path) -> Path:
        (d / name).write_bytes(content)
        return d / name

    return make


def _npz(d: Path) -> Path:
    np.savez(d / "traj.npz", waypoints=np.zeros((2, 3, 6)))
    return d / "traj.npz"


def _npy(d: Path) -> Path:
    np.save(d / "a.npy", np.zeros(3))
    return d / "a.npy"


def _pickle(d: Path) -> Path:
    (d / "state.pt").write_bytes(pickle.dumps({"format": "lasmp-checkpoint-v1"}))
    return d / "state.pt"


def _zip(d: Path) -> Path:
    with zipfile.ZipFile(d / "notes.pt", "w") as z:
        z.writestr("notes.txt", "not a checkpoint")
    return d / "notes.pt"


# what a user may give as a checkpoint that is no PyTorch checkpoint at all -> what it is named
NOT_A_CHECKPOINT = {
    "the shipped ONNX export": (_copy(SHIPPED_ONNX), r"ONNX model"),
    "an ONNX model renamed .pt": (
        lambda d: Path(shutil.copy(SHIPPED_ONNX, d / "policy.pt")),
        r"ONNX model",
    ),
    "a text file": (_bytes("notes.pt", b"iteration 449, reward 31.2\n" * 20), r"a text file"),
    "random bytes": (_bytes("noise.pt", np.random.default_rng(0).bytes(4096)), r"neither a zip"),
    "an empty file": (_bytes("model_3.pt", b""), r"empty file, 0 bytes"),
    "a trajectory .npz": (_npz, r"NumPy \.npz archive"),
    "a NumPy .npy array": (_npy, r"NumPy \.npy array"),
    "a plain Python pickle": (_pickle, r"Python pickle"),
    "a zip archive of other files": (_zip, r"zip archive without the data\.pkl"),
}


@pytest.mark.parametrize("case", sorted(NOT_A_CHECKPOINT))
def test_a_file_that_is_no_pytorch_checkpoint_is_named_as_such_not_sent_to_convert(tmp_path, case):
    make, what = NOT_A_CHECKPOINT[case]
    path = make(tmp_path)
    out = call(ckpt_tool.main, ["info", str(path)])
    refused(out, re.escape(str(path)) + r" is not a PyTorch checkpoint", what)
    assert "--trust" not in out.text and "pickled Python objects" not in out.text, out.text
    assert len(out.text.strip().splitlines()) == 1, out.text


def _fifo(d: Path) -> Path:
    os.mkfifo(d / "model_5.pt")
    return d / "model_5.pt"


def _link(target):
    def make(d: Path) -> Path:
        (d / "policy.pt").symlink_to(target(d) if callable(target) else target)
        return d / "policy.pt"

    return make


def _run_with_fifo_latest(d: Path) -> Path:
    run = d / "run"
    run.mkdir()
    shutil.copy(SHIPPED, run / "policy_1.pt")
    os.mkfifo(run / "model_2.pt")  # the newest checkpoint of the run
    return run


def _empty_dir(d: Path) -> Path:
    (d / "run").mkdir()
    return d / "run"


NOT_REGULAR = {
    "a FIFO": (_fifo, r"named pipe \(FIFO\), not a regular file"),
    "/dev/zero": (lambda d: Path("/dev/zero"), r"character device, not a regular file"),
    "a symlink to /dev/zero": (_link(Path("/dev/zero")), r"character device.*links to /dev/zero"),
    "a symlink to a FIFO": (_link(_fifo), r"named pipe"),
    "a run directory whose newest checkpoint is a FIFO": (
        _run_with_fifo_latest,
        r"model_2\.pt is a named pipe",
    ),
    "a directory without checkpoints": (_empty_dir, r"no checkpoint model_<N>\.pt or policy_<N>\.pt"),
    "a symlink to a directory without checkpoints": (_link(_empty_dir), r"no checkpoint"),
    "a broken symlink": (_link(Path("/nonexistent/model_1.pt")), r"does not exist"),
}


@pytest.mark.parametrize("case", sorted(NOT_REGULAR))
def test_only_a_regular_file_is_read_as_a_checkpoint_and_nothing_hangs(tmp_path, no_hang, case):
    make, pattern = NOT_REGULAR[case]
    path = make(tmp_path)
    with pytest.raises(CheckpointError, match=pattern):
        read_checkpoint(path)
    out = call(ckpt_tool.main, ["info", str(path)])
    refused(out, pattern)


# -- a checkpoint of a newer format --------------------------------------------------------------
def _future(tmp_path: Path, version: int = 2) -> Path:
    data = torch.load(SHIPPED, weights_only=True)
    data["format"] = f"lasmp-checkpoint-v{version}"
    torch.save(data, tmp_path / "model_7.pt")
    return tmp_path / "model_7.pt"


def test_a_checkpoint_of_a_newer_format_says_it_is_newer_than_this_code(tmp_path):
    path = _future(tmp_path, 12)
    out = call(ckpt_tool.main, ["info", str(path)])
    refused(out, r"'lasmp-checkpoint-v12', newer than this code", r"'lasmp-checkpoint-v1'", r"update lasmp")
    assert "not a lasmp checkpoint" not in out.text


def test_a_resume_from_a_checkpoint_of_a_newer_format_says_so_and_writes_nothing(tmp_path):
    path = _future(tmp_path)
    before = files(tmp_path)
    out = train(tiny(f"resume={path}", f"runner.log_dir={tmp_path / 'run'}"))
    refused(out, r"newer than this code", r"update lasmp")
    assert files(tmp_path) == before


def test_an_older_or_foreign_format_is_still_not_a_lasmp_checkpoint(tmp_path):
    data = torch.load(SHIPPED, weights_only=True)
    for fmt in ("lasmp-checkpoint-v0", "rsl-rl", None):
        data["format"] = fmt
        torch.save(data, tmp_path / "m.pt")
        with pytest.raises(CheckpointError, match="not a lasmp checkpoint") as err:
            read_checkpoint(tmp_path / "m.pt")
        assert "newer" not in str(err.value)


# -- the commands that load a checkpoint ---------------------------------------------------------
def test_play_given_an_onnx_model_names_it_and_does_not_advise_convert(tmp_path):
    from lasmp.cli.play import main as play

    onnx = Path(shutil.copy(SHIPPED_ONNX, tmp_path / "policy.onnx"))
    out = call(play, ["--checkpoint", str(onnx), "--steps", "1"])
    refused(out, r"policy\.onnx is not a PyTorch checkpoint \(an ONNX model\?")
    assert "convert" not in out.text


def test_evaluate_given_a_fifo_as_checkpoint_refuses_it_without_hanging(tmp_path, no_hang):
    from lasmp.eval.cli import main as evaluate

    fifo = _fifo(tmp_path)
    out = call(evaluate, ["--checkpoint", str(fifo), "--num-trajectories", "1", "--out", str(tmp_path / "e")])
    refused(out, r"model_5\.pt is a named pipe")
    assert not (tmp_path / "e").exists()


def test_the_shipped_checkpoint_still_loads(tmp_path):
    data = read_checkpoint(_copy(SHIPPED)(tmp_path))
    assert data["format"] == "lasmp-checkpoint-v1" and data["iter"] >= 0
