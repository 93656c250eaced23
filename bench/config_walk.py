"""The config walk of a training: how far the training config travels through lasmp's modules on its
way from `lasmp.cli.train.main`'s `cfg` to the start of learning, counted in stays, rooms and climbs
back.

What runs: a tiny training in this process. The config is composed with Hydra's compose API from
cfg/ (after `lasmp.config.train.register_configs()`) with the tiny sizes of tests/testkit.py's
TINY_CLI (repeated here as TINY_CLI), `runner.max_iterations=1`, `seed=0` and
`runner.log_dir=<a temporary directory>`; the command line's overrides replace the entries with the
same key (the log directory is always the temporary one). Then `lasmp.cli.train.main(cfg, overrides)`
runs under `sys.settrace`; the training's own output goes to stderr.

What counts as the config (an identity set, grown as the walk goes):
  - the composed DictConfig and every DictConfig node reached from it (walked through ListConfigs);
  - every object returned by a call (any function, in lasmp or not: `dataclasses.replace`, OmegaConf's
    own accessors) that received a config object as an argument, when that object is a dataclass
    instance or a DictConfig: so the TrainCfg that `lasmp.config.train.to_train_cfg` returns, a
    resume's `Resume` (and its `.cfg`), a `dataclasses.replace(cfg, ...)` copy;
  - every dataclass instance and DictConfig reachable from the fields of one that enters the set,
    recursively (walked through lists, tuples and dicts): the TrainCfg's env, policy, algo and
    runner configs and theirs.
Plain values taken out of the config (an int, a str, a list of ints, rsl_rl's dict from `rsl_rl_cfg`)
are not the config. Only returns of plain functions count, not of generators (their `return` events
are yields).

The return rule lets in any dataclass a config-carrying call returns, derived values included: at the
default config the sampled robot and platform intrinsics, `PlatformGains`, `MemoryNeed`.
`--config-classes` narrows it: a returned dataclass counts only if its class is one of the config's, the classes of the dataclass
instances in the TrainCfg tree that `to_train_cfg` builds from the composed config (built once before
the walk, untraced); DictConfigs count as before. `dataclasses.replace` copies, OmegaConf's
`to_object` and a resume's TrainCfg (`resumed_cfg`) still count.

What counts as a step of the walk: a call (a `call` event, a generator's resumption not counted again)
into a function whose code file is under lasmp/ and one of whose parameters, as bound at the call, is
in the set: the names `code.co_varnames[:co_argcount + co_kwonlyargcount]`, so `self` counts when
`self` is a config object but the attributes of a `self` are not followed, and `*args` / `**kwargs`
are not looked into. Only the main thread is traced.

The cut: the walk stops following when `LasmpRunner.learn` is entered (tracing ends there): the walk
is the config's way to the start of learning, the build of the env, the runner and the learner
included, not the env's per-step calls. The training still runs its iteration, untraced.

The counts, over the walk's calls in order, each named by its room:
  - a room is a module file, by its path from the repository root (lasmp/cli/train.py);
  - a stay is a maximal run of consecutive calls in one room;
  - a climb back is a stay in a room that an earlier stay already visited and left (a re-entry),
    so climbs back = stays - rooms.

    python bench/config_walk.py [--json] [--config-classes] [override ...]
    python bench/config_walk.py task=rough_static
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import inspect
import json
import os
import sys
import tempfile
from collections.abc import Iterable, Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "lasmp"

# tests/testkit.py's TINY_CLI: 4 envs, 15-step episodes, small networks, the float32 learner
TINY_CLI = (
    "env.num_envs=4",
    "env.trajectory.duration_s=0.3",
    "torch_threads=1",
    "algo.precision=float32",
    "algo.num_mini_batches=2",
    "algo.num_learning_epochs=1",
    "policy.actor_hidden_dims=[32,32,32]",
    "policy.critic_hidden_dims=[32,32]",
    "runner.save_interval=1",
)
WALK_CLI = (*TINY_CLI, "runner.max_iterations=1", "seed=0")
LEARN = ("lasmp/algo/runner.py", "LasmpRunner.learn")  # where the walk stops following

_MISSING = object()  # a parameter not bound yet (never in the set)
_GENERATOR_FLAGS = inspect.CO_GENERATOR | inspect.CO_COROUTINE | inspect.CO_ASYNC_GENERATOR


# ---- the counts -------------------------------------------------------------------------------------


def stays_of(calls: Sequence[tuple[str, str]]) -> list[dict]:
    """The stays of `calls` ((room, function) in order): one dict per maximal run of consecutive calls
    in one room, {room, function (its first), calls, climb_back}."""
    stays: list[dict] = []
    for room, function in calls:
        if stays and stays[-1]["room"] == room:
            stays[-1]["calls"] += 1
            continue
        climb = any(s["room"] == room for s in stays)
        stays.append({"room": room, "function": function, "calls": 1, "climb_back": climb})
    return stays


def count_walk(rooms: Iterable[str]) -> dict[str, int]:
    """Stays, rooms and climbs back of a walk given as the room of each call, in order."""
    stays = stays_of([(room, "") for room in rooms])
    return {
        "calls": sum(s["calls"] for s in stays),
        "stays": len(stays),
        "rooms": len({s["room"] for s in stays}),
        "climbs_back": sum(s["climb_back"] for s in stays),
    }


# ---- the trace --------------------------------------------------------------------------------------


class ConfigWalk:
    """A `sys.settrace` tracer that records the calls into lasmp that carry the config (module docstring)."""

    def __init__(self, root: Path = ROOT, config_classes: Iterable[type] | None = None):
        from omegaconf import DictConfig, ListConfig

        self._dict, self._list = DictConfig, ListConfig
        self.root = root
        # returned dataclasses count only of these classes (None: any)
        self.config_classes = None if config_classes is None else frozenset(config_classes)
        self.package = str(root / "lasmp") + os.sep
        self.known: dict[int, object] = {}  # id -> the object, kept alive so that its id stays its own
        self.calls: list[tuple[str, str, tuple[str, ...]]] = []  # (room, function, config parameters)
        self.stopped = False  # LasmpRunner.learn was entered
        self._rooms: dict[object, str | None] = {}  # code -> its room (None: outside lasmp/)
        self._started: set = set()  # generator frames seen: a later `call` is a resumption

    # the identity set

    def add(self, obj) -> None:
        """`obj` and every config object reachable from it into the set."""
        stack = [obj]
        while stack:
            o = stack.pop()
            if isinstance(o, self._dict):
                if id(o) in self.known:
                    continue
                self.known[id(o)] = o
                content = o.__dict__.get("_content")  # the child nodes, unresolved (None when missing)
                stack.extend(content.values() if isinstance(content, dict) else ())
            elif isinstance(o, self._list):
                content = o.__dict__.get("_content")
                stack.extend(content if isinstance(content, list) else ())
            elif dataclasses.is_dataclass(o) and not isinstance(o, type):
                if id(o) in self.known:
                    continue
                self.known[id(o)] = o
                stack.extend(getattr(o, f.name, None) for f in dataclasses.fields(o))
            elif isinstance(o, list | tuple):
                stack.extend(o)
            elif isinstance(o, dict):
                stack.extend(o.values())

    def _is_candidate(self, obj) -> bool:
        return isinstance(obj, self._dict) or (dataclasses.is_dataclass(obj) and not isinstance(obj, type))

    # the tracer

    def room(self, code) -> str | None:
        if code not in self._rooms:
            path = code.co_filename
            inside = path.startswith(self.package)
            self._rooms[code] = Path(path).relative_to(self.root).as_posix() if inside else None
        return self._rooms[code]

    def trace(self, frame, event, arg):
        if event != "call":
            return None
        code = frame.f_code
        room = self.room(code)
        if room is not None and (room, code.co_qualname) == LEARN:
            self.stopped = True
            sys.settrace(None)  # the cut: nothing after learn's start is followed
            return None
        generator = code.co_flags & _GENERATOR_FLAGS
        if generator:
            if frame in self._started:
                return None
            self._started.add(frame)
        n = code.co_argcount + code.co_kwonlyargcount
        if not n:
            return None
        local = frame.f_locals
        carried = tuple(name for name in code.co_varnames[:n] if id(local.get(name, _MISSING)) in self.known)
        if not carried:
            return None
        if room is not None:
            self.calls.append((room, code.co_qualname, carried))
        if generator:
            return None
        frame.f_trace_lines = False
        return self._on_return

    def _on_return(self, frame, event, arg):
        if event == "return" and self._is_candidate(arg) and self._admits(arg):
            self.add(arg)
        return self._on_return

    def _admits(self, returned) -> bool:
        """Whether the return rule lets `returned` (a dataclass or a DictConfig) in (`--config-classes`)."""
        return (
            self.config_classes is None
            or isinstance(returned, self._dict)
            or type(returned) in self.config_classes
        )

    @contextlib.contextmanager
    def tracing(self):
        previous = sys.gettrace()
        sys.settrace(self.trace)
        try:
            yield self
        finally:
            sys.settrace(previous)
            self._started.clear()  # the generator frames, no longer kept alive

    def report(self) -> dict:
        stays = stays_of([(room, function) for room, function, _ in self.calls])
        counts = count_walk(room for room, _, _ in self.calls)
        return {**counts, "reached_learn": self.stopped, "stays_sequence": stays}


# ---- the training -----------------------------------------------------------------------------------


def _key(override: str) -> str:
    return override.split("=", 1)[0].lstrip("+~")


def walk_overrides(overrides: Sequence[str], log_dir: str) -> list[str]:
    """WALK_CLI with `overrides` replacing the entries of the same key, then the log directory."""
    given = {_key(o) for o in overrides}
    kept = [o for o in WALK_CLI if _key(o) not in given]
    return [*kept, *(o for o in overrides if _key(o) != "runner.log_dir"), f"runner.log_dir={log_dir}"]


def config_walk(overrides: Sequence[str] = (), config_classes: bool = False) -> dict:
    """The walk of a tiny training composed with `overrides` (module docstring): its counts and stays;
    `config_classes`: returned dataclasses count only of the config's classes."""
    from hydra import compose, initialize_config_dir

    from lasmp.cli.train import main as train_main
    from lasmp.config.train import register_configs, to_train_cfg

    register_configs()
    with tempfile.TemporaryDirectory(prefix="config_walk-") as tmp:
        composed = walk_overrides(overrides, str(Path(tmp) / "run"))
        with initialize_config_dir(config_dir=str(ROOT / "cfg"), version_base="1.3"):
            cfg = compose("config", overrides=composed)
        classes = None
        if config_classes:  # the classes of the dataclasses of the TrainCfg tree (cfg is left as it is)
            tree = ConfigWalk()
            tree.add(to_train_cfg(cfg))
            classes = {type(o) for o in tree.known.values() if dataclasses.is_dataclass(o)}
        walk = ConfigWalk(config_classes=classes)
        walk.add(cfg)
        with contextlib.redirect_stdout(sys.stderr), walk.tracing():
            code = train_main(cfg, composed)
    if code:
        raise SystemExit(f"config_walk: the training failed (exit code {code}), see its error above")
    rule = "config classes" if config_classes else "any dataclass"
    return {"overrides": composed[:-1], "returned_dataclasses": rule, **walk.report()}


def render(report: dict) -> str:
    lines = [
        f"config walk: {report['stays']} stays in {report['rooms']} rooms, {report['climbs_back']} climbs back "
        f"({report['calls']} config-carrying calls, followed until LasmpRunner.learn: "
        f"{'reached' if report['reached_learn'] else 'NOT reached'}; returned dataclasses counted: "
        f"{report['returned_dataclasses']})",
        f"overrides: {' '.join(report['overrides'])}",
        "",
        f"{'#':>3}  {'room':<42} {'first function':<34} {'calls':>5}",
    ]
    for i, s in enumerate(report["stays_sequence"], 1):
        mark = "  climb back" if s["climb_back"] else ""
        lines.append(f"{i:>3}  {s['room']:<42} {s['function']:<34} {s['calls']:>5}{mark}")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> dict:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--json", action="store_true", help="print the report as one JSON object")
    p.add_argument(
        "--config-classes",
        action="store_true",
        help="count a returned dataclass only if its class is one of the config's (module docstring)",
    )
    p.add_argument("overrides", nargs="*", help="train.py's key=value overrides, on top of the tiny sizes")
    args = p.parse_args(argv)
    report = config_walk(args.overrides, args.config_classes)
    print(json.dumps(report, indent=1) if args.json else render(report), flush=True)
    return report


if __name__ == "__main__":
    main()
