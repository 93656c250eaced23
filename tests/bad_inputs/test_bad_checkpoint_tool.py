"""The checkpoint tool (`python -m lasmp.algo.checkpoint`: policy, info, convert): its output paths,
a bad input file, a full disk."""

from __future__ import annotations

import os
import re

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
        refused(out, re.escape(name), "--force")
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
