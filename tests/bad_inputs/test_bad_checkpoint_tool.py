"""The checkpoint tool (`python -m lasmp.algo.checkpoint`: policy, info, convert): its output paths,
a bad input file, a full disk."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest
from badkit import _disk_full, _one_line_naming, _truncated, _write, call, files, refused, succeeded
from testkit import hostile_checkpoint

from lasmp.algo import checkpoint as ckpt_tool


# -- full disk -----------------------------------------------------------------------------------
def test_a_full_disk_when_writing_a_policy_checkpoint_gives_one_line_naming_it(
    base_run, tmp_path, monkeypatch
):
    monkeypatch.setattr(os, "fsync", _disk_full)
    dst = tmp_path / "policy.pt"
    out = call(ckpt_tool.main, ["policy", str(base_run), str(dst)])
    _one_line_naming(out, str(dst))
    assert not dst.exists() and not list(tmp_path.glob(".*.tmp"))


# -- the checkpoint tool's output paths ----------------------------------------------------------
def test_policy_refuses_to_overwrite_its_own_full_checkpoint(run_copy):
    before = files(run_copy)
    out = call(ckpt_tool.main, ["policy", str(run_copy / "model_1.pt"), str(run_copy / "model_1.pt")])
    refused(out, "model_1.pt", "--force")
    assert files(run_copy) == before


def test_policy_refuses_to_overwrite_another_full_checkpoint(run_copy):
    before = files(run_copy)
    out = call(ckpt_tool.main, ["policy", str(run_copy / "model_1.pt"), str(run_copy / "model_0.pt")])
    refused(out, "model_0.pt", "--force")
    assert files(run_copy) == before


def test_policy_refuses_to_overwrite_an_existing_file(run_copy, tmp_path):
    for name, content in (("notes.txt", None), ("policy.pt", "policy")):
        dst = tmp_path / name
        if content == "policy":
            ckpt_tool.policy_checkpoint(run_copy, dst)
        else:
            dst.write_text("mine")
        before = dst.read_bytes()
        out = call(ckpt_tool.main, ["policy", str(run_copy), str(dst)])
        # a .txt is refused by its extension (checked before the claim), where --force would not help
        refused(out, re.escape(name), "--force" if name.endswith(".pt") else "unknown extension")
        assert dst.read_bytes() == before


def test_policy_with_force_overwrites_the_full_checkpoint_as_asked(run_copy):
    target = run_copy / "model_1.pt"
    succeeded(call(ckpt_tool.main, ["policy", str(target), str(target), "--force"]))
    assert ckpt_tool.is_policy_only(ckpt_tool.read_checkpoint(target))


def test_policy_of_a_run_directory_writes_a_new_file(base_run, tmp_path):
    dst = tmp_path / "out" / "policy.pt"
    succeeded(call(ckpt_tool.main, ["policy", str(base_run), str(dst)]))
    data = ckpt_tool.read_checkpoint(dst)
    assert ckpt_tool.is_policy_only(data) and data["iter"] == 1


def test_policy_into_a_directory_that_is_a_file_gives_one_line(base_run, tmp_path):
    (tmp_path / "afile").write_text("a file")
    out = call(ckpt_tool.main, ["policy", str(base_run), str(tmp_path / "afile" / "policy.pt")])
    refused(out, "afile")
    assert (tmp_path / "afile").read_text() == "a file"


CHECKPOINT_TOOL_CASES = {
    "policy of a missing file": (
        lambda d: ["policy", str(d / "nope.pt"), str(d / "out.pt")],
        "does not exist",
    ),
    "info of a missing file": (lambda d: ["info", str(d / "nope.pt")], "does not exist"),
    "info of a truncated file": (
        lambda d: ["info", str(_truncated(d / "run" / "model_1.pt", d / "t.pt"))],
        "unreadable",
    ),
    "info of a text file": (lambda d: ["info", str(_write(b"text")(None, d / "t.pt"))], "unreadable"),
    "info of a hostile file": (
        lambda d: ["info", str(hostile_checkpoint(d / "h.pt", d / "marker"))],
        "pickled Python objects",
    ),
    "convert without --trust": (
        lambda d: ["convert", str(d / "run" / "model_1.pt"), str(d / "c.pt")],
        "--trust",
    ),
    "convert onto an existing file": (
        lambda d: ["convert", "--trust", str(d / "run" / "model_1.pt"), str(d / "run" / "model_0.pt")],
        "exists",
    ),
    "convert onto itself": (
        lambda d: ["convert", "--trust", str(d / "run" / "model_1.pt"), str(d / "run" / "model_1.pt")],
        "differ",
    ),
}


@pytest.mark.parametrize("case", sorted(CHECKPOINT_TOOL_CASES))
def test_the_checkpoint_tool_refuses_a_bad_input_with_one_message(run_copy, tmp_path, case):
    argv, pattern = CHECKPOINT_TOOL_CASES[case]
    argv = argv(tmp_path)
    before = files(run_copy)
    out = call(ckpt_tool.main, argv)
    refused(out, pattern)
    assert files(run_copy) == before and not (tmp_path / "marker").exists()
    assert not (tmp_path / "out.pt").exists() and not (tmp_path / "c.pt").exists()


def test_info_of_a_policy_checkpoint_says_so(base_run, tmp_path):
    ckpt_tool.policy_checkpoint(base_run, tmp_path / "p.pt")
    out = call(ckpt_tool.main, ["info", str(tmp_path / "p.pt")])
    succeeded(out)
    assert "policy checkpoint" in out.text


# -- the writers' guard: DST checked before SRC is read; real disks ------------------------------
SHIPPED = Path(__file__).resolve().parents[2] / "resources" / "policies" / "lasmp_a1.pt"


def test_policy_onto_an_unknown_extension_is_refused_before_the_source_is_read(tmp_path):
    src = tmp_path / "notes.pt"
    src.write_text("not a checkpoint: reading it first would say so")
    out = call(ckpt_tool.main, ["policy", str(src), str(tmp_path / "policy.onnx")])
    refused(out, r"unknown extension '\.onnx'; use \.pt or \.pth")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.pt"]


def test_policy_into_a_read_only_directory_is_refused_before_the_source_is_read(tmpfs, tmp_path):
    where = tmpfs(read_only=True)
    out = call(ckpt_tool.main, ["policy", str(SHIPPED), str(where / "sub" / "policy.pt")])
    refused(out, r"not writable")
    assert list(where.iterdir()) == []


def test_policy_onto_a_real_full_disk_gives_one_line_naming_the_file_and_leaves_nothing(tmpfs):
    where = tmpfs(size="64k")
    dst = where / "policy.pt"
    out = call(ckpt_tool.main, ["policy", str(SHIPPED), str(dst)])
    refused(out, r"No space left on device")
    assert [line for line in out.text.splitlines() if line.strip()] == [
        f"error: cannot write {dst}: No space left on device (the file is left as it was)"
    ]
    assert list(where.iterdir()) == []


def test_convert_replaces_an_existing_file_only_with_force(base_run, tmp_path):
    dst = tmp_path / "converted.pt"
    dst.write_text("mine")
    refused(call(ckpt_tool.main, ["convert", "--trust", str(base_run / "model_1.pt"), str(dst)]), "--force")
    assert dst.read_text() == "mine"
    succeeded(call(ckpt_tool.main, ["convert", "--trust", "--force", str(base_run / "model_1.pt"), str(dst)]))
    assert ckpt_tool.read_checkpoint(dst)["iter"] == 1


def test_convert_of_an_onnx_model_names_it_and_unpickles_nothing(tmp_path):
    onnx = tmp_path / "policy.onnx"
    onnx.write_bytes((SHIPPED.parent / "lasmp_a1.onnx").read_bytes())
    out = call(ckpt_tool.main, ["convert", "--trust", str(onnx), str(tmp_path / "c.pt")])
    refused(out, r"policy\.onnx is not a PyTorch checkpoint \(an ONNX model\?")
    assert not (tmp_path / "c.pt").exists()


def test_policy_of_a_fifo_is_refused_without_hanging(tmp_path):
    os.mkfifo(tmp_path / "model_1.pt")
    out = call(ckpt_tool.main, ["policy", str(tmp_path / "model_1.pt"), str(tmp_path / "p.pt")])
    refused(out, r"named pipe")
    assert not (tmp_path / "p.pt").exists()
