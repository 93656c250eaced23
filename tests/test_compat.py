"""lasmp reads rsl_rl's, TensorBoard's and Hydra's private names in one module per library and
nowhere else: lasmp/compat/rsl_rl.py, lasmp/compat/tensorboard.py, lasmp/compat/hydra.py (each says why, and
tests/test_*_compat.py checks that the installed library still has them). A private name read
anywhere else in lasmp fails here: move the read into the library's compat module, or use a public
API."""

from __future__ import annotations

import ast
import functools
import importlib.util
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "lasmp"
COMPAT = PACKAGE / "compat"  # its modules: rsl_rl.py, tensorboard.py, hydra.py
LIBRARIES = ("rsl_rl", "tensorboard", "torch.utils.tensorboard", "hydra", "omegaconf")
# a private module or name of a library, spelt out: an import, or a string such as a logger's name
SPELT_OUT = re.compile(r"\b(?:rsl_rl|tensorboard|hydra|omegaconf)(?:\.\w+)*\._[A-Za-z]\w*")
PRIVATE = re.compile(r"_[A-Za-z]\w*")


@functools.cache
def private_names(library: str) -> frozenset[str]:
    """The private names `library`'s source defines: its functions and methods, the attributes it
    assigns, the buffers it registers (not dunders)."""
    root = Path(importlib.util.find_spec(library).origin).parent
    names = set()
    for path in root.rglob("*.py"):
        try:
            tree = ast.parse(path.read_text(encoding="utf-8"))
        except (SyntaxError, UnicodeDecodeError, ValueError):
            continue
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                names.add(node.name)
            elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
                names.add(node.attr)
            elif (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Attribute)
                and node.func.attr in ("register_buffer", "register_parameter")
                and node.args
                and isinstance(node.args[0], ast.Constant)
            ):
                names.add(node.args[0].value)
    return frozenset(n for n in names if isinstance(n, str) and PRIVATE.fullmatch(n) and not n.endswith("__"))


def _own(node: ast.expr) -> bool:
    """`self`, `cls` or `super()`: the object whose class the module defines."""
    if isinstance(node, ast.Name):
        return node.id in ("self", "cls")
    return isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "super"


def private_reads(
    source: str, libraries: frozenset[str], subclassed: frozenset[str]
) -> list[tuple[int, str]]:
    """(line, what) for each private name of the libraries `source` reads: a private module or name
    spelt out; an attribute of another object, or a string, that is one of `libraries`' private names;
    a method defined, or an attribute read on self, that is one of `subclassed`'s (the library lasmp's
    classes derive from)."""
    found = [(source.count("\n", 0, m.start()) + 1, m.group()) for m in SPELT_OUT.finditer(source)]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] in {
            lib.split(".")[0] for lib in LIBRARIES
        }:
            found += [(node.lineno, f"import {a.name}") for a in node.names if PRIVATE.fullmatch(a.name)]
        elif isinstance(node, ast.Attribute) and node.attr in (subclassed if _own(node.value) else libraries):
            found.append((node.lineno, ast.unparse(node)))
        elif isinstance(node, ast.Constant) and node.value in libraries:
            found.append((node.lineno, repr(node.value)))
        elif isinstance(node, ast.ClassDef):
            found += [
                (f.lineno, f"def {f.name}")
                for f in node.body
                if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef)) and f.name in subclassed
            ]
    return sorted(found)


def test_the_check_finds_each_kind_of_private_read():
    libraries = frozenset({"_file_name", "_store_code_state", "_get_obs_dim", "_mean"})
    subclassed = frozenset({"_get_obs_dim", "_mean"})
    source = (
        "from hydra._internal.utils import get_args_parser\n"
        "name = getattr(writer, '_file_name', None)\n"
        "hit = any(f.name == '_store_code_state' for f in frames)\n"
        "class Actor(MLPModel):\n"
        "    def _get_obs_dim(self, obs):\n"
        "        return self._mean, norm._mean\n"
        "    def _own(self):\n"
        "        return self._lock, other._lock\n"
    )
    assert [line for line, _ in private_reads(source, libraries, subclassed)] == [1, 2, 3, 5, 6, 6]


def test_no_module_but_the_compat_modules_reads_a_private_name_of_rsl_rl_tensorboard_or_hydra():
    libraries = frozenset().union(*(private_names(lib) for lib in LIBRARIES))
    subclassed = private_names("rsl_rl")
    assert {"_file_name", "_async_writer", "_worker", "_store_code_state", "_mean"} <= libraries
    reads = [
        f"{path.relative_to(PACKAGE.parent)}:{line}: {what}"
        for path in sorted(PACKAGE.rglob("*.py"))
        if path.parent != COMPAT
        for line, what in private_reads(path.read_text(), libraries, subclassed)
    ]
    assert not reads, "private names read outside lasmp/*_compat.py:\n" + "\n".join(reads)
