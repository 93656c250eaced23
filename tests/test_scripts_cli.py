"""Every script under scripts/ is a tool as the entry points are: `--help` prints its usage,
an unknown option is refused by argparse in one line, and a JSON file it reads that is missing or cut
short is named in one line (lasmp.io.inputs.read_json), never a traceback. Each script runs as a user
runs it: a subprocess of the venv's python, from the repository root."""

from __future__ import annotations

import functools
import json
import subprocess
import sys
from pathlib import Path

import pytest

from lasmp.io.inputs import InputError, read_json

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "scripts").glob("*.py"))


@functools.cache
def run(script: str, *args: str) -> subprocess.CompletedProcess:
    """`python SCRIPT ARGS` from the repository root, its output captured (cached: --help is asked twice)."""
    return subprocess.run(
        [sys.executable, script, *args], cwd=ROOT, capture_output=True, text=True, timeout=120
    )


def arguments_required_by(usage: str) -> list[str]:
    """Arguments that give a usage line what it requires, so that argparse goes on to the options it
    does not know (it reports a missing argument first): each optional [...] part left out, a choice
    {a,b} its first (a subcommand, whose own usage follows `...`), any other value 1 (a path, a count
    and a name alike)."""
    text = usage.split("\n\n", 1)[0].split(maxsplit=2)[2]  # after "usage: PROG"
    depth, required = 0, []
    for char in text:
        depth += (char == "[") - (char == "]")
        if depth == 0 and char != "]":
            required.append(char)
    args = []
    for token in "".join(required).split():
        if token == "...":
            break
        args.append(token if token.startswith("-") else token[1:-1].split(",")[0] if "{" in token else "1")
    return args


def test_the_scripts_are_found():
    assert "scripts/study.py" in SCRIPTS and "scripts/screen_table.py" in SCRIPTS


@pytest.mark.parametrize("script", SCRIPTS)
def test_every_script_answers_help_with_its_usage_and_does_nothing_else(script):
    done = run(script, "--help")
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("usage: ") and "Traceback" not in done.stderr
    assert "|---" not in done.stdout  # a table printed instead of the usage (screen_table.py did)


@pytest.mark.parametrize("script", SCRIPTS)
def test_every_script_refuses_an_unknown_option_in_one_line_naming_it(script):
    required = arguments_required_by(run(script, "--help").stdout)
    done = run(script, *required, "--no-such-option")
    assert done.returncode == 2, done.stderr
    errors = [line for line in done.stderr.splitlines() if "error:" in line]
    assert errors == [f"{Path(script).name}: error: unrecognized arguments: --no-such-option"]
    assert "Traceback" not in done.stderr and not done.stdout


def test_the_arguments_a_usage_line_requires_are_its_unbracketed_parts():
    usage = (
        "usage: tool.py [-h] --at AT [AT ...] [--std-scales [STD_SCALES ...]]\n"
        "               --kind {a,b} run_dir\n\ndescription"
    )
    assert arguments_required_by(usage) == ["--at", "1", "--kind", "a", "1"]
    assert arguments_required_by("usage: study.py [-h] {plan,next} ...\n") == ["plan"]


@pytest.mark.parametrize(
    ("text", "says"),
    [
        (None, "no such file"),
        ("", "empty, not JSON"),
        ('{"methods": {"LAS-MP": [1, 2', "truncated: the file ends before its JSON does"),
        ('{"methods": "LAS-', "truncated: the file ends before its JSON does"),
        ('{"methods": 1}}', "not valid JSON: Extra data at line 1, column 15"),
        ("[1, 2]", "holds an array, not the JSON object expected"),
    ],
)
def test_a_json_file_that_is_missing_cut_short_or_not_an_object_is_named_in_one_line(tmp_path, text, says):
    path = tmp_path / "summary.json"
    if text is not None:
        path.write_text(text)
    with pytest.raises(InputError) as err:
        read_json(path)
    assert str(err.value) == f"{path}: {says}"


def test_a_json_object_is_read_as_it_was_written(tmp_path):
    path = tmp_path / "metrics.json"
    path.write_text(json.dumps({"metrics": {"collision_rate": {"mean": 0.1}}}))
    assert read_json(path) == {"metrics": {"collision_rate": {"mean": 0.1}}}
