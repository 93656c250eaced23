"""The one place lasmp reaches below Hydra's public API.

train.py checks its command line before Hydra's app composes it (`lasmp.cli.command_line`): an override
naming no config key, in a single run or in any job of a sweep (`-m`), is worded by lasmp. For that it
must read the command line as `hydra.main` will and expand a sweep into the jobs, in the order,
Hydra's basic sweeper launches. Hydra's public API (`hydra.compose`, `initialize_config_dir`, the
`OverridesParser` of `hydra.core.override_parser`) composes one config from a list of overrides but
offers neither, so these take from `hydra._internal`, and lasmp takes from it nowhere else
(`tests/test_compat.py` greps lasmp for it):

- `hydra._internal.utils.get_args_parser`: the argparse parser `hydra.main` reads the command line
  with (its `overrides`, `multirun`, `config_path`, `config_dir`, `config_name`): `args_parser`.
- `hydra._internal.core_plugins.basic_sweeper.BasicSweeper.split_arguments`: how the basic sweeper
  (the default one, which train.py uses) expands a sweep's overrides into jobs: `basic_sweep_jobs`.

Imported lazily: only train.py's command line needs Hydra's internals. rsl_rl's and TensorBoard's
private names are read in the sibling modules `lasmp/compat/rsl_rl.py` and `lasmp/compat/tensorboard.py`.
`tests/test_hydra_compat.py` exercises both against the installed Hydra, so that an upgrade that
moves or renames them fails there, pointing here.
"""

from __future__ import annotations

import argparse


def args_parser() -> argparse.ArgumentParser:
    """The parser `hydra.main` reads its app's command line with (train.py's arguments)."""
    from hydra._internal.utils import get_args_parser

    return get_args_parser()


def basic_sweep_jobs(overrides: list[str]) -> list[list[str]]:
    """The jobs of a sweep over `overrides` (`key=a,b` lists), each its list of overrides, in the
    order Hydra's basic sweeper launches them (all in one batch). Raises Hydra's error where the basic
    sweeper cannot expand them alone (a glob over a config group, an interval)."""
    from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
    from hydra.core.override_parser.overrides_parser import OverridesParser

    (batch,) = BasicSweeper.split_arguments(OverridesParser.create().parse_overrides(overrides), None)
    return [list(job) for job in batch]
