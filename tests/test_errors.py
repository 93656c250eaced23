"""The commands' one error boundary (lasmp/io/errors.py): a table of exception types says which
failures end a command in one line and with which exit code; anything else keeps its traceback."""

from __future__ import annotations

import signal
import traceback

import pytest

from lasmp.io.errors import BadInput, ErrorTable, bad_input_from, run


class Refused(ValueError):
    pass


class Both(Refused, OSError):
    """An exception that both rows of a table match."""


class Stopped(Exception):
    def __init__(self, signum: int):
        super().__init__(f"stopped by signal {signum}")
        self.signum = signum


TABLE = ErrorTable(
    bad_input=(Refused,),
    cannot_go_on=(OSError,),
    stopped=(Stopped,),
    interrupted="interrupted: nothing saved here",
)


def raising(err: BaseException):
    def work():
        raise err

    return work


def test_work_that_ends_well_exits_with_its_own_code_and_none_is_0(capsys):
    assert run(lambda: None, TABLE) == 0
    assert run(lambda: 3, TABLE) == 3
    assert capsys.readouterr().err == ""


def test_a_failure_in_the_table_is_one_error_line_and_its_rows_exit_code(capsys):
    assert run(raising(Refused("the checkpoint is truncated")), TABLE) == 2
    assert capsys.readouterr().err == "error: the checkpoint is truncated\n"
    assert run(raising(OSError(28, "No space left on device")), TABLE) == 1
    assert capsys.readouterr().err == "error: [Errno 28] No space left on device\n"


def test_the_first_matching_row_wins_bad_input_before_cannot_go_on(capsys):
    assert run(raising(Both("both")), TABLE) == 2
    swapped = ErrorTable(bad_input=(OSError,), cannot_go_on=(ValueError,))
    assert run(raising(Both("both")), swapped) == 2
    assert capsys.readouterr().err == "error: both\nerror: both\n"


def test_an_exception_not_in_the_table_propagates_with_its_traceback(capsys):
    def work():
        raise KeyError("a bug")

    with pytest.raises(KeyError) as info:
        run(work, TABLE)
    frames = [frame.name for frame in traceback.extract_tb(info.value.__traceback__)]
    assert frames[-1] == "work"  # the traceback still reaches where it was raised
    assert capsys.readouterr().err == ""


def test_a_stopped_exception_exits_128_plus_its_signal_and_prints_nothing(capsys):
    assert run(raising(Stopped(signal.SIGTERM)), TABLE) == 128 + signal.SIGTERM
    assert run(raising(Stopped(signal.SIGINT)), TABLE) == 130
    assert capsys.readouterr().err == ""


def test_a_ctrl_c_prints_the_tables_interrupted_text_and_exits_130(capsys):
    assert run(raising(KeyboardInterrupt()), TABLE) == 130
    assert capsys.readouterr().err == "interrupted: nothing saved here\n"


def test_an_interrupted_text_given_as_a_function_is_said_as_it_is_when_the_ctrl_c_comes(capsys):
    written: list[str] = []

    def work():
        written.append("video.mp4")
        raise KeyboardInterrupt

    table = ErrorTable(bad_input=(), interrupted=lambda: f"interrupted: wrote {', '.join(written)}")
    assert run(work, table) == 130
    assert capsys.readouterr().err == "interrupted: wrote video.mp4\n"


@pytest.mark.parametrize(
    "work, code",
    [
        (lambda: None, 0),
        (raising(Refused("bad")), 2),
        (raising(OSError("full")), 1),
        (raising(KeyboardInterrupt()), 130),
    ],
    ids=["success", "bad input", "cannot go on", "ctrl-c"],
)
def test_on_exit_runs_however_the_work_ends(work, code):
    calls = []
    assert run(work, TABLE, on_exit=lambda: calls.append("on_exit")) == code
    assert calls == ["on_exit"]


def test_on_exit_also_runs_when_an_exception_not_in_the_table_propagates():
    calls = []
    with pytest.raises(KeyError):
        run(raising(KeyError("a bug")), TABLE, on_exit=lambda: calls.append("on_exit"))
    assert calls == ["on_exit"]


def test_a_failing_on_exit_never_replaces_the_error_said(capsys):
    def on_exit():
        raise RuntimeError("the teardown failed too")

    assert run(raising(Refused("the checkpoint is truncated")), TABLE, on_exit=on_exit) == 2
    assert capsys.readouterr().err == "error: the checkpoint is truncated\n"
    with pytest.raises(KeyError):  # nor the traceback of a bug
        run(raising(KeyError("a bug")), TABLE, on_exit=on_exit)
    assert run(lambda: None, TABLE, on_exit=on_exit) == 0


def test_a_phase_that_says_a_type_is_bad_input_makes_it_exit_2_with_its_prefix_and_cause(capsys):
    cause = OSError(13, "Permission denied", "out/video.mp4")

    def work():
        with bad_input_from(OSError, prefix="--video: "):
            raise cause

    assert run(work, TABLE) == 2  # the table's own row for OSError says 1
    assert capsys.readouterr().err == "error: --video: [Errno 13] Permission denied: 'out/video.mp4'\n"
    with pytest.raises(BadInput) as info, bad_input_from(OSError):
        raise cause
    assert info.value.__cause__ is cause


def test_a_phase_that_says_a_type_is_bad_input_lets_every_other_type_through():
    with pytest.raises(KeyError), bad_input_from(ValueError):
        raise KeyError("a bug")
    with pytest.raises(KeyboardInterrupt), bad_input_from(ValueError):
        raise KeyboardInterrupt
    inner = BadInput("--export: no command input")
    with pytest.raises(BadInput) as info, bad_input_from(Exception, prefix="outer: "):
        raise inner
    assert info.value is inner  # said once, not prefixed again
