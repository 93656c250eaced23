"""train.py while it trains: every env faulting, a diverging loss, signals (SIGTERM, Ctrl-C), a save
that fails, a full disk."""

from __future__ import annotations

import os
import signal

import torch
from badkit import (
    _disk_full,
    _one_line_naming,
    call,
    progress_lines,
    refused,
    succeeded,
    tiny,
    train,
)

from lasmp.algo.runner import LasmpRunner

# -- faults --------------------------------------------------------------------------------------
ALL_FAULT = "env.termination.max_joint_vel_rad_s=1e-9"  # every joint moves faster: every env-step faults


def test_a_run_in_which_every_env_faults_stops_naming_the_cause(tmp_path):
    run = tmp_path / "run"
    out = train(tiny(ALL_FAULT, "runner.max_iterations=3", f"runner.log_dir={run}"))
    refused(out, "fault", "runner.max_fault_fraction")
    assert not list(run.glob("model_*.pt"))  # no checkpoint of the faulting state


def test_a_faulting_run_trains_on_when_the_threshold_allows_it_and_the_progress_line_counts_the_faults(
    tmp_path,
):
    out = train(tiny(ALL_FAULT, "runner.max_fault_fraction=1", f"runner.log_dir={tmp_path / 'run'}"))
    succeeded(out)
    assert "faults 20" in progress_lines(out)[0]  # 4 envs x 5 steps, all faulted


def test_the_progress_line_shows_the_fault_count(tmp_path):
    out = train(tiny(f"runner.log_dir={tmp_path / 'run'}"))
    succeeded(out)
    assert progress_lines(out) and "faults 0" in progress_lines(out)[0]


def test_a_diverging_loss_stops_with_one_message_naming_it(tmp_path, monkeypatch):
    from rsl_rl.algorithms import PPO

    real = PPO.update  # PPO's own update diverges; PPOROA's update, around it, guards it
    monkeypatch.setattr(PPO, "update", lambda self: {**real(self), "value": float("nan")})
    run = tmp_path / "run"
    out = train(tiny(f"runner.log_dir={run}"))
    refused(out, "non-finite loss", "value")
    assert not list(run.glob("model_*.pt"))


# -- interruption --------------------------------------------------------------------------------
# a second signal during a save (train.py): tests/bad_inputs/test_bad_signals.py
def _exiting(monkeypatch):
    """The handler's `os._exit` as SystemExit, so that these tests call it in this process."""

    def exit_now(code):
        raise SystemExit(code)

    monkeypatch.setattr(LasmpRunner, "_exit_now", staticmethod(exit_now))


def test_a_quick_second_ctrl_c_exits_with_130_and_no_checkpoint(tmp_path, monkeypatch):
    """The same handler as SIGTERM's (test above), called as Python calls it on two Ctrl-C half a
    second apart: alone, a process takes every second signal as one."""
    _exiting(monkeypatch)
    runner = LasmpRunner.__new__(LasmpRunner)  # the handler reads nothing but the signal state
    runner._signal, runner.is_distributed = None, False

    def twice():
        runner._on_signal(signal.SIGINT, None)
        runner._on_signal(signal.SIGINT, None)

    out = call(twice)
    assert out.code == 130 and "Traceback" not in out.text and "SIGINT again" in out.text


def test_a_torchrun_rank_takes_a_signal_at_once_after_the_first_as_its_echo(tmp_path, monkeypatch):
    _exiting(monkeypatch)
    runner = LasmpRunner.__new__(LasmpRunner)
    runner._signal, runner.is_distributed = None, True

    def twice():
        runner._on_signal(signal.SIGTERM, None)
        runner._on_signal(signal.SIGINT, None)  # an echo at once (torchrun forwards): ignored
        assert runner._signal == signal.SIGTERM
        runner._signal_time_s -= LasmpRunner.REPEAT_WINDOW_S + 1.0  # a second signal, later
        runner._on_signal(signal.SIGTERM, None)

    out = call(twice)
    assert out.code == 143 and "Traceback" not in out.text and "SIGTERM again" in out.text


def test_a_save_that_fails_leaves_no_temporary_file(tmp_path, monkeypatch):
    def broken(obj, f):
        f.write(b"PK\x03\x04 partial")
        raise RuntimeError("the writer broke")

    monkeypatch.setattr(torch, "save", broken)
    run = tmp_path / "run"
    out = train(tiny(f"runner.log_dir={run}"))
    assert out.code != 0
    assert not list(run.glob(".*.tmp")) and not list(run.glob("model_*.pt"))


# -- full disk -----------------------------------------------------------------------------------
def test_a_full_disk_when_training_starts_gives_one_line_naming_the_file(tmp_path, monkeypatch):
    monkeypatch.setattr(os, "fsync", _disk_full)
    run = tmp_path / "run"
    out = train(tiny(f"runner.log_dir={run}"))
    _one_line_naming(out, str(run))
    assert not list(run.glob(".*.tmp")) and not list(run.glob("model_*.pt"))


def test_a_full_disk_at_a_checkpoint_gives_one_line_naming_it_and_leaves_no_temporary_file(
    tmp_path, monkeypatch
):
    def full(obj, f):
        f.write(b"PK\x03\x04 partial")
        _disk_full()

    monkeypatch.setattr(torch, "save", full)
    run = tmp_path / "run"
    out = train(tiny(f"runner.log_dir={run}"))
    _one_line_naming(out, "model_0.pt")
    assert not list(run.glob(".*.tmp")) and not list(run.glob("model_*.pt"))
