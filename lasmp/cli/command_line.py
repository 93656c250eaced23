"""train.py's command line, read once: its arguments parsed with `hydra.main`'s own parser, each job's
config composed once with Hydra's compose API, and the job run (`run`). Hydra's app (`hydra_app`) is
left what lasmp does not do itself: `--help`, `--hydra-help`, `--info`, another config directory or
name, and a sweep its basic sweeper alone can expand (a glob, an interval).

Why lasmp composes: an override naming no config key is the one failure Hydra words against us (it
suggests appending the key with `+`, which the README rules out and validation would refuse anyway,
`lasmp.config.checks.check_known_keys`); ours names the key and the keys valid where it points. A key
that a recipe (cfg/recipe/) sets and the env lacks is worded as the recipe's: the recipes are the
moving platform's. A sweep (`-m`) is composed job by job, as Hydra's basic sweeper expands it, every
job before the first runs, so that a typo in any job is refused before any work.

Below: the keys a command line sets (what a resume takes from it) and the command that resumes a run.
"""

from __future__ import annotations

import argparse
import contextlib
import re
import shlex
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from lasmp.cli.sweep import Sweep
from lasmp.compat.hydra import args_parser, basic_sweep_jobs
from lasmp.config.base import flatten

if TYPE_CHECKING:
    from hydra.plugins.config_source import ConfigResult
    from omegaconf import DictConfig

# hydra.main's options that lasmp leaves to Hydra's app: its help and information, another config
HYDRA_OWN = (
    "help",
    "hydra_help",
    "info",
    "shell_completion",
    "config_path",
    "config_dir",
    "config_name",
    "experimental_rerun",
)


@dataclass(frozen=True)
class CommandLine:
    """train.py's arguments, parsed once: `args` as `hydra.main` reads them, and `jobs`, each job's
    overrides (one job without -m; a sweep's, in the order Hydra's basic sweeper numbers them; None:
    a sweep lasmp cannot expand)."""

    args: argparse.Namespace
    jobs: list[list[str]] | None

    @classmethod
    def parse(cls, argv: list[str]) -> CommandLine:
        args = args_parser().parse_args(argv)
        return cls(args, sweep_jobs(args.overrides) if args.multirun else [list(args.overrides)])

    @property
    def for_hydra(self) -> bool:
        """Whether Hydra's app, not lasmp, runs this command line (`HYDRA_OWN`, or a sweep lasmp cannot expand)."""
        return self.jobs is None or any(getattr(self.args, name) for name in HYDRA_OWN)


def run(
    argv: list[str],
    config_dir: Path,
    config_name: str,
    job: Callable[[DictConfig, list[str]], int],
    hydra_app: Callable[[], None],
) -> int:
    """train.py: parse `argv` once, compose each job's config once (refusing an unknown key in any job
    before the first runs, exit 2), then run each job (`job(cfg, overrides)`: its exit code), or
    print its config (`--cfg job|hydra|all`, `--package`, `--resolve`); the exit code. A sweep goes
    on past a failed job (`Sweep`). What lasmp leaves to Hydra goes to `hydra_app`."""
    line = CommandLine.parse(argv)
    if line.for_hydra:
        hydra_app()
        return 0
    multirun = bool(line.args.multirun)
    composed = []
    for num, overrides in enumerate(line.jobs):
        cfg, error = compose_job(config_dir, config_name, overrides, num if multirun else None)
        if error:
            print(f"error: {error}", file=sys.stderr)
            return 2
        composed.append((cfg, overrides))
    if line.args.cfg:
        for cfg, _ in composed:
            print(_shown(cfg, line.args.cfg, line.args.package, line.args.resolve), end="")
        return 0
    sweep = Sweep(line.jobs) if multirun else None
    for num, (cfg, overrides) in enumerate(composed):
        _set_hydra_config(cfg)
        if sweep is None:
            return job(_job_config(cfg), overrides)
        sweep.run_job(num, lambda cfg=cfg, overrides=overrides: job(_job_config(cfg), overrides))
    return sweep.report() if sweep is not None else 0


def compose_job(
    config_dir: Path, config_name: str, overrides: list[str], num: int | None = None
) -> tuple[DictConfig | None, str | None]:
    """One job's config with Hydra's own node (`hydra.*`, for `HydraConfig`: the job's overrides and,
    in a sweep, its number `num`), or the one-line error that refuses it."""
    from hydra.types import RunMode
    from omegaconf import open_dict

    try:
        cfg = _compose(config_dir, config_name, overrides, hydra_node=True)
    except Exception as err:
        return None, _unknown_key(err, overrides, config_dir, config_name) or _one_line(err)
    with open_dict(cfg):
        cfg.hydra.mode = RunMode.MULTIRUN if num is not None else RunMode.RUN
        cfg.hydra.job.num = num or 0
    return cfg, None


def _one_line(err: Exception) -> str:
    """Hydra's composition error as one line: its message (the options it lists), not its search path."""
    return " ".join(str(err).split("Config search path")[0].split())


def _set_hydra_config(cfg) -> None:
    """Make the job's Hydra node what `HydraConfig.get()` reads (as `hydra.main` does for its job)."""
    from hydra.core.hydra_config import HydraConfig

    HydraConfig.instance().set_config(cfg)


def _job_config(cfg):
    """The job's config without Hydra's node: what the training reads."""
    from omegaconf import OmegaConf

    return OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])


def _shown(cfg, which: str, package: str | None, resolve: bool) -> str:
    """`--cfg job|hydra|all` as Hydra prints it: the job's config, Hydra's node, or both, as YAML."""
    from omegaconf import OmegaConf

    node = (
        _job_config(cfg)
        if which == "job"
        else OmegaConf.masked_copy(cfg, "hydra")
        if which == "hydra"
        else cfg
    )
    if package:
        node = OmegaConf.select(node, package)
    return OmegaConf.to_yaml(node, resolve=resolve) if OmegaConf.is_config(node) else f"{node}\n"


def _compose(config_dir: Path, config_name: str, overrides: list[str], hydra_node: bool = False):
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(config_dir=str(config_dir), version_base="1.3", job_name="train"):
        return compose(config_name, overrides=overrides, return_hydra_config=hydra_node)


def sweep_jobs(overrides: list[str]) -> list[list[str]] | None:
    """The jobs of `train.py -m OVERRIDES`, each its list of overrides, in the order (and so with the
    numbers #0, #1, ...) Hydra's basic sweeper launches them; None where they cannot be expanded here
    (Hydra's app then reports why)."""
    try:
        return basic_sweep_jobs(overrides)
    except Exception:  # a sweep this parser cannot expand alone (glob over a group, an interval)
        return None


def _unknown_key(err: Exception, overrides: list[str], config_dir: Path, config_name: str) -> str | None:
    """The one-line error for a composition that failed on an override naming no config key (or a
    recipe's key the env lacks), with the keys valid where it points; None for any other failure."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from omegaconf import OmegaConf
    from omegaconf.errors import ConfigAttributeError, ConfigKeyError

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
    except Exception:  # another override fails too: said once this one is fixed
        return message
    node = OmegaConf.select(cfg, parent) if parent else cfg
    return f"{message}; valid keys{f' of {parent}' if parent else ''}: {sorted(node)}"


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
