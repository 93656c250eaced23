"""train.py's command line, composed once before Hydra's app composes it, for the one failure
Hydra words against us: an override naming no config key. Hydra's message suggests appending it
with `+`, which the README rules out and validation would refuse anyway
(`lasmp.config.base.check_known_keys`); ours names the key and the keys valid where it points. A key
that a recipe (cfg/recipe/) sets and the env lacks is worded as the recipe's: the recipes are the
moving platform's. A sweep (`-m`) is checked job by job, as Hydra's basic sweeper expands it.

`Sweep` keeps a sweep's jobs going past one that fails (docs/usage.md): a failed job is said when it
ends and again, with every other failed job, when the sweep ends; an interrupted job stops the sweep,
naming the jobs that did not run."""

from __future__ import annotations

import contextlib
import re
import shlex
import sys
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from lasmp.compat.hydra import args_parser, basic_sweep_jobs
from lasmp.config.base import flatten

if TYPE_CHECKING:
    from hydra.plugins.config_source import ConfigResult


def _compose(config_dir: Path, config_name: str, overrides: list[str]):
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(config_dir=str(config_dir), version_base="1.3"):
        return compose(config_name, overrides=overrides)


def unknown_key_error(argv: list[str], config_dir: Path, config_name: str) -> str | None:
    """The one-line error for the override in `argv` (train.py's arguments) that names no key of
    the config `config_name` in `config_dir`, or None. With `-m`, each job of the sweep is checked
    (a sweep's comma lists do not compose as one config). Every other failure is left to Hydra's app,
    which reports it as it always has."""
    args = _parse_args(argv)
    if args.config_path or args.config_dir or args.config_name:  # another config than the one checked here
        return None
    if not args.multirun:
        return _unknown_key(args.overrides, config_dir, config_name)
    for job in sweep_jobs(args.overrides) or []:
        error = _unknown_key(job, config_dir, config_name)
        if error:
            return error
    return None


def _parse_args(argv: list[str]):
    return args_parser().parse_args(argv)  # hydra.main's own: the overrides it will compose


def sweep_jobs(overrides: list[str]) -> list[list[str]] | None:
    """The jobs of `train.py -m OVERRIDES`, each its list of overrides, in the order (and so with the
    numbers #0, #1, ...) Hydra's basic sweeper launches them; None where they cannot be expanded here
    (Hydra's app then reports why)."""
    try:
        return basic_sweep_jobs(overrides)
    except Exception:  # a sweep this parser cannot expand alone (glob over a group, an interval)
        return None


def _unknown_key(overrides: list[str], config_dir: Path, config_name: str) -> str | None:
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from omegaconf import OmegaConf
    from omegaconf.errors import ConfigAttributeError, ConfigKeyError

    try:
        _compose(config_dir, config_name, overrides)
        return None
    except Exception as err:  # only the unknown key is ours to word; Hydra reports the rest
        recipe = re.match(r"In 'recipe/(\w+)': ConfigKeyError.*full_key: (\S+)", str(err), re.DOTALL)
        if recipe:
            return (
                f"recipe={recipe[1]} sets '{recipe[2]}', a key this command's env has not: the recipes "
                "are the moving platform's (task=moving_platform, env=moving_platform); other tasks take none"
            )
        if not isinstance(err.__cause__, (ConfigAttributeError, ConfigKeyError)):
            return None
        key = err.__cause__.full_key  # the first level that does not exist
    parent = key.rpartition(".")[0]
    message = f"unknown config key '{key}'"
    # the keys at its level: in the config the other overrides compose (a group choice such as
    # task=rough_static changes env's keys)
    others = [
        o.input_line
        for o in OverridesParser.create().parse_overrides(overrides)
        if not f"{o.key_or_group}.".startswith(f"{key}.")
    ]
    try:
        cfg = _compose(config_dir, config_name, others)
    except Exception:  # another override fails too: Hydra's app reports it once this one is fixed
        return message
    node = OmegaConf.select(cfg, parent) if parent else cfg
    return f"{message}; valid keys{f' of {parent}' if parent else ''}: {sorted(node)}"


class Sweep:
    """A sweep's (`train.py -m ...`) jobs and how each ended. A job that fails (bad input, exit 2; a
    run that could not go on, exit 1; an unexpected exception, its traceback and exit 1) is said when it
    ends, and the sweep goes on with the next job; `report` then lists every failed job. A job stopped
    by Ctrl-C or SIGTERM (exit 128 + the signal) stops the sweep, naming the jobs that did not run."""

    def __init__(self, jobs: list[list[str]] | None):
        self.jobs = jobs  # None: not expanded here (the labels are then the job numbers alone)
        self.failed: dict[int, int] = {}  # job number -> exit code
        self.ran = 0

    @classmethod
    def of(cls, argv: list[str]) -> Sweep | None:
        """The sweep `argv` (train.py's arguments) asks for; None without -m."""
        args = _parse_args(argv)
        return cls(sweep_jobs(args.overrides)) if args.multirun else None

    def label(self, num: int) -> str:
        """Job #num with the overrides that tell it from the sweep's other jobs."""
        if not self.jobs or num >= len(self.jobs):
            return f"#{num}"
        own = self.jobs[num]
        varying = [o for o in own if not all(o in job for job in self.jobs)] or own
        return f"#{num} ({' '.join(varying)})"

    def run_job(self, job: Callable[[], int]) -> None:
        """Run one job (in Hydra's task function) and keep its exit code; SystemExit if it was interrupted."""
        from hydra.core.hydra_config import HydraConfig

        num = HydraConfig.get().job.num
        try:
            code = job()
        except Exception:  # a bug, not a user's mistake: its traceback, and the other jobs still run
            traceback.print_exc()
            code = 1
        self.ran += 1
        if code >= 128:  # Ctrl-C or SIGTERM: the user wants the sweep to stop, not to skip one job
            rest = self.jobs[num + 1 :] if self.jobs is not None else None
            if rest is None:
                not_run = f"the jobs after #{num} did not run"
            elif rest:
                not_run = f"did not run: {', '.join(self.label(n) for n in range(num + 1, len(self.jobs)))}"
            else:
                not_run = "it was the last job"
            failed = f"; failed before: {self._listed()}" if self.failed else ""
            print(
                f"the sweep stopped at job {self.label(num)}: {not_run}{failed}", file=sys.stderr, flush=True
            )
            raise SystemExit(code)
        if code:
            self.failed[num] = code
            print(
                f"sweep: job {self.label(num)} failed (exit {code}); going on with the next job",
                file=sys.stderr,
                flush=True,
            )

    def _listed(self) -> str:
        return ", ".join(f"{self.label(n)} exit {code}" for n, code in self.failed.items())

    def report(self) -> int:
        """After the sweep: the failed jobs in one line (their own errors were said as each ended); the
        exit code, the first failed job's (0 if none failed)."""
        if not self.failed:
            return 0
        total = len(self.jobs) if self.jobs is not None else self.ran
        print(
            f"error: {len(self.failed)} of {total} jobs of the sweep failed: {self._listed()} (each job's error "
            "is above); the other jobs ran to their end",
            file=sys.stderr,
            flush=True,
        )
        return next(iter(self.failed.values()))


# -- what a command line sets, and the command that continues a run -------------------------------
CFG_DIR = Path(__file__).resolve().parents[2] / "cfg"


def explicit_keys(overrides: list[str]) -> set[str]:
    """The config keys a command line sets, read from its overrides as Hydra parsed them: `key=value`
    (`+key=`, `~key`) names its key; a group option (`task=`, `policy=`, `preset=`, `env=`) stands
    for the keys its own config sets, under its package (preset=paper: device, env.num_envs and
    runner.max_iterations; task=rough_static: task). Nothing is composed: each option's config is
    read alone, from the config sources Hydra composed with."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    keys: set[str] = set()
    with _config_sources() as sources:
        for override in OverridesParser.create().parse_overrides(overrides):
            name, option = override.key_or_group, override.value()
            path = f"{name}/{option}"
            source = next((s for s in sources if isinstance(option, str) and s.is_config(path)), None)
            keys |= _option_keys(source.load_config(path), name) if source else {name}
    return keys


def _option_keys(option: ConfigResult, group: str) -> set[str]:
    """The keys a group option's config sets, under its package (Hydra's default: the group's node)."""
    package = option.header.get("package")
    if package in (None, "_group_"):
        package = group.replace("/", ".")
    package = package.removeprefix("_global_").lstrip(".")
    from omegaconf import OmegaConf

    content = OmegaConf.to_container(option.config)
    content.pop("defaults", None)  # the other options it selects, not keys it sets
    return {f"{package}.{key}" if package else key for key in flatten(content)}


@contextlib.contextmanager
def _config_sources():
    """Hydra's config sources: those of the app (or the caller's `initialize`) that composed the
    config, else cfg/'s."""
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    if GlobalHydra.instance().is_initialized():
        yield GlobalHydra.instance().config_loader().get_sources()
        return
    with initialize_config_dir(config_dir=str(CFG_DIR), version_base="1.3"):
        yield GlobalHydra.instance().config_loader().get_sources()


def hydra_overrides() -> list[str] | None:
    """The overrides Hydra parsed from train.py's command line; None outside its app."""
    from hydra.core.hydra_config import HydraConfig

    return list(HydraConfig.get().overrides.task) if HydraConfig.initialized() else None


def resume_command(checkpoint: str, log_dir: str, iterations_left: int | None = None) -> str:
    """The train.py command line that continues a run: this run's own overrides (from Hydra, when
    it composed the config) with resume= and runner.log_dir= set, and runner.max_iterations= the
    iterations left to the end the interrupted command set (a resume runs that many more)."""
    overrides = hydra_overrides() or []
    # a `+key=` that composed names a key of the schema (validation refuses others), and Hydra now
    # refuses `+` on an existing key: repeat it without the `+`
    drop = ("resume=", "warm_start=", "runner.log_dir=") + (
        ("runner.max_iterations=",) if iterations_left is not None else ()
    )
    keep = [o.removeprefix("+") for o in overrides if not o.lstrip("+~").startswith(drop)]
    if iterations_left is not None:
        keep.append(f"runner.max_iterations={max(iterations_left, 1)}")
    keep += [f"resume={hydra_quote(checkpoint)}", f"runner.log_dir={hydra_quote(log_dir)}"]
    # quoted for the shell, so that it can be pasted: a path with a space, brackets of a list
    return " ".join(["python train.py", *map(shlex.quote, keep)])


def hydra_quote(value: str) -> str:
    """`value` as a Hydra override's value: as it is where Hydra reads it whole, else in Hydra's
    double quotes (a path with a comma would be a sweep, one with brackets or quotes a parse error).
    In them a quote is escaped, and so are the backslashes before a quote or at the end (Hydra's rule)."""
    if re.fullmatch(r"[\w./@:+-]+", value):
        return value
    escaped = re.sub(r'(\\*)"', lambda m: m.group(1) * 2 + '\\"', value)
    escaped = re.sub(r"(\\+)$", lambda m: m.group(1) * 2, escaped)
    return f'"{escaped}"'
