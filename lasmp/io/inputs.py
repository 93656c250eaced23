"""What every command checks the same way, once: seeds, numeric options, and the file it will write.

Why one module: the same value (a seed, a count, an output path) reaches the tools through the Hydra
config and through seven argparse CLIs. Checked in each place by hand, the rules drift (a seed of -1
was refused by one command and crashed numpy in another; `--steps 0` meant "the default" where it
was tested by truthiness). Here each rule is written once and every command uses it:

- `check_seed` / `seed_arg`: a seed is an integer in [0, 2**32 - 1], the range every random source
  here accepts (numpy's legacy generators are the narrowest).
- `int_arg(lo)` / `float_arg(lo, hi)`: argparse types for a bounded number; a float must be finite.
- `check_out_file`: the path a command will write, checked before any work: its extension, that it
  does not replace an existing file without --force, and that its directory exists (or can be made)
  and is writable. It creates nothing, so a refused command leaves nothing behind.
- `missing_dirs`, `file_sha256`: what the writers record about a path: the directories writing it
  creates (removed again when the command fails), and a file's hash (results name their inputs).
- `read_json`: a JSON file another command wrote (metrics.json, summary.json), or one line naming
  the file when it is missing, cut short or not JSON (json's own error names no file).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
from pathlib import Path

SEED_MAX = 2**32 - 1


class InputError(ValueError):
    """A command-line value or output path that a command refuses; str() is one line naming it."""


def check_seed(value, name: str = "seed") -> int:
    """`value` as a seed, or InputError naming `name`. Booleans and non-integral floats are refused."""
    if isinstance(value, bool) or not isinstance(value, int):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise InputError(f"{name} must be an integer in [0, 2**32 - 1], got {value!r}")
    if not 0 <= value <= SEED_MAX:
        raise InputError(f"{name} must be an integer in [0, 2**32 - 1], got {value}")
    return value


def _parse(text: str, kind: type, what: str):
    try:
        return kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{what}, got {text!r}") from None


def seed_arg(text: str) -> int:
    """argparse type of a --seed option."""
    value = _parse(text, int, "must be an integer in [0, 2**32 - 1]")
    try:
        return check_seed(value, "the seed")
    except InputError:
        raise argparse.ArgumentTypeError(f"must be an integer in [0, 2**32 - 1], got {text!r}") from None


def int_arg(lo: int = 0, hi: int | None = None):
    """argparse type of an integer in [lo, hi] (hi: no bound when None)."""
    what = f"must be an integer >= {lo}" if hi is None else f"must be an integer in [{lo}, {hi}]"

    def parse(text: str) -> int:
        value = _parse(text, int, what)
        if value < lo or (hi is not None and value > hi):
            raise argparse.ArgumentTypeError(f"{what}, got {text!r}")
        return value

    parse.__name__ = "integer"  # argparse names the type in its own messages
    return parse


def float_arg(lo: float = -math.inf, hi: float = math.inf, *, open_lo: bool = False):
    """argparse type of a finite float in [lo, hi] ((lo, hi] with open_lo)."""
    what = f"must be a finite number {'>' if open_lo else '>='} {lo}" + (
        f" and <= {hi}" if hi < math.inf else ""
    )

    def parse(text: str) -> float:
        value = _parse(text, float, what)
        if not math.isfinite(value) or value < lo or (open_lo and value == lo) or value > hi:
            raise argparse.ArgumentTypeError(f"{what}, got {text!r}")
        return value

    parse.__name__ = "number"
    return parse


def _writable_dir(path: Path) -> Path:
    """The nearest existing ancestor of `path`, checked to be a writable directory."""
    parent = path.parent.absolute()
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise InputError(f"cannot write {path}: {parent} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"cannot write {path}: {parent} is not writable")
    return parent


def check_out_file(path: str | os.PathLike, *, suffixes: tuple[str, ...], force: bool, option: str) -> Path:
    """`path` as a file the command may write, checked before any work; InputError otherwise.

    `suffixes` are the extensions the writer knows (".mp4", ...); `option` names the flag in the
    message. An existing file is refused unless `force`; a directory in its place always is."""
    path = Path(path)
    if path.suffix.lower() not in suffixes:
        raise InputError(
            f"{option} {path}: unknown extension {path.suffix or '(none)'!r}; use {' or '.join(suffixes)}"
        )
    if path.is_dir():
        raise InputError(f"{option} {path} is a directory; give a file name")
    if (path.exists() or path.is_symlink()) and not force:
        raise InputError(f"{path} already exists: choose another {option}, or pass --force to overwrite it")
    _writable_dir(path)
    return path


def missing_dirs(path: str | os.PathLike) -> list[Path]:
    """The directories of `path` and its parents that do not exist yet, outermost first: what
    `path.mkdir(parents=True)` creates (a dangling symlink counts as existing)."""
    missing = []
    for p in (Path(path), *Path(path).parents):
        if p.exists() or p.is_symlink():
            break
        missing.append(p)
    return missing[::-1]


def file_sha256(path: str | os.PathLike) -> str:
    """The hex sha256 of the file at `path`, read in 1 MiB blocks."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def size_in_words(n: int) -> str:
    """Bytes in words, to three digits: 1.5 GiB, 320 KiB, 8.78 KiB."""
    for unit, scale in (("TiB", 1 << 40), ("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}" if n < 1000 * scale else f"{n / scale:.0f} {unit}"
    return f"{n} B"


def read_json(path: str | os.PathLike) -> dict:
    """The JSON object in the file at `path`; InputError "PATH: why" for a file that is missing,
    unreadable, empty, truncated (a copy or a write cut short) or anything but a JSON object."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except OSError as err:  # a directory, no permission
        raise InputError(f"{path}: cannot be read ({err.strerror or err})") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not JSON (not UTF-8 text)") from None
    try:
        value = json.loads(text)
    except json.JSONDecodeError as err:
        if not text.strip():
            raise InputError(f"{path}: empty, not JSON") from None
        # the parser ran into the end of the text (inside a string, it reports where the string began)
        if err.pos >= len(text.rstrip()) or err.msg.startswith("Unterminated string"):
            raise InputError(f"{path}: truncated: the file ends before its JSON does") from None
        raise InputError(
            f"{path}: not valid JSON: {err.msg} at line {err.lineno}, column {err.colno}"
        ) from None
    if not isinstance(value, dict):
        kind = {list: "an array", str: "a string", bool: "a boolean", type(None): "null"}.get(
            type(value), "a number"
        )
        raise InputError(f"{path}: holds {kind}, not the JSON object expected")
    return value
