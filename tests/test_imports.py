"""lasmp's imports point down its layers (docs/layout.md) and form no cycle, counting imports
inside functions and the package `__init__` files an import runs."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "lasmp"
# docs/layout.md's layers, top first: a module imports only from the layers below its own, never
# from another package of its layer (the learner and the envs do not know each other)
# the packages that group modules by what they are for; their __init__ holds a docstring only
GROUPS = ("lasmp.cli", "lasmp.config", "lasmp.io", "lasmp.compat")
LAYERS = (
    ("lasmp.cli.train", "lasmp.cli.play"),
    ("lasmp.cli.train_failures", "lasmp.cli.run_directory"),
    ("lasmp.cli.command_line",),
    ("lasmp.cli.sweep",),
    ("lasmp.cli.warm_start",),
    ("lasmp.cli.build",),
    ("lasmp.cli.resume", "lasmp.cli.resources"),
    ("lasmp.eval", "lasmp.render"),
    ("lasmp.deploy",),
    ("lasmp.config.checkpoint",),
    ("lasmp.config.train", "lasmp.config.recipe"),
    ("lasmp.motions",),
    ("lasmp.algo", "lasmp.envs"),
    ("lasmp.modules",),
    ("lasmp.config.bounds",),
    ("lasmp.robots", "lasmp.config.base", "lasmp.io.plainstate", "lasmp.io.rundir", "lasmp.io.memory"),
    ("lasmp.config.checks",),
    ("lasmp.io.atomic", "lasmp.io.inputs", "lasmp.io.ctrl_c", "lasmp.cli.preflight", "lasmp.io.errors"),
    ("lasmp.compat.rsl_rl", "lasmp.compat.tensorboard", "lasmp.compat.hydra"),
    GROUPS,
)


def module_name(path: Path, package: Path) -> str:
    parts = path.relative_to(package.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(package: Path = PACKAGE) -> dict[str, set[str]]:
    """module -> the package's modules it imports anywhere in its file, with the packages above them."""
    root = package.name
    files = {module_name(p, package): p for p in package.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in files.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join(up + ([base] if base else []))
                targets.add(base)
                targets.update(f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in files)
        edges = set()
        for target in targets:
            if target.split(".")[0] != root:
                continue
            parts = target.split(".")
            edges.update(
                ".".join(parts[:i]) for i in range(2, len(parts) + 1) if ".".join(parts[:i]) in files
            )
        edges.discard(name)
        # a module's own package __init__ runs before it: that is not an import the module makes
        graph[name] = {e for e in edges if not name.startswith(e + ".")}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt) :] + [nxt]
            if nxt not in state and (cycle := visit(nxt)):
                return cycle
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)):
            return cycle
    return None


def test_the_checker_finds_a_cycle_it_is_given():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def test_the_graph_counts_imports_inside_functions_relative_imports_and_packages(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("from pkg import top\n")
    (pkg / "sub" / "leaf.py").write_text("from . import other\n")
    (pkg / "sub" / "other.py").write_text("")
    (pkg / "top.py").write_text("def f():\n    import pkg.sub.leaf\n")
    graph = import_graph(pkg)
    assert graph["pkg.top"] == {"pkg.sub", "pkg.sub.leaf"}
    assert graph["pkg.sub.leaf"] == {"pkg.sub.other"}
    assert find_cycle(graph) == ["pkg.sub", "pkg.top", "pkg.sub"]


def test_lasmp_has_no_import_cycle():
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def _top(module: str) -> str:
    """The unit of the layers a module belongs to: its package below lasmp (lasmp.algo for
    lasmp.algo.runner), or, in a package that groups modules by what they are for (`GROUPS`: the
    command line, the configuration, safe files, the libraries' private names), the module itself:
    those packages hold modules of several layers."""
    parts = module.split(".")
    return ".".join(parts[:3] if ".".join(parts[:2]) in GROUPS and len(parts) > 2 else parts[:2])


def test_every_import_points_down_the_layers():
    graph = {m: targets for m, targets in import_graph().items() if m != "lasmp"}
    rank = {top: i for i, layer in enumerate(LAYERS) for top in layer}
    unplaced = sorted({_top(m) for m in graph} - set(rank))
    assert not unplaced, f"modules in no layer of LAYERS (docs/layout.md): {unplaced}"
    upward = [
        f"{a} -> {b}"
        for a, targets in graph.items()
        for b in targets
        if _top(a) != _top(b) and rank[_top(b)] <= rank[_top(a)]
    ]
    assert not upward, "imports that do not point down the layers: " + ", ".join(sorted(upward))


def test_the_learner_loads_neither_the_envs_nor_the_training_config():
    """A fresh interpreter: importing the learner brings in no physics, no Hydra, no env, no config."""
    out = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys, lasmp.algo.ppo_roa, lasmp.algo.runner; "
            "print(' '.join(m for m in ('mujoco', 'hydra', 'lasmp.envs', 'lasmp.config.train') if m in sys.modules))",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == [], f"importing lasmp.algo loaded {out.stdout.split()}"
