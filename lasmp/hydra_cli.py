"""train.py's command line, composed once before Hydra's app composes it, for the one failure
Hydra words against us: an override naming no config key. Hydra's message suggests appending it
with `+`, which the README rules out and validation would refuse anyway
(`lasmp.config.check_known_keys`); ours names the key and the keys valid where it points. A key
that a recipe (cfg/recipe/) sets and the env lacks is worded as the recipe's: the recipes are the
moving platform's."""

from __future__ import annotations

import re
from pathlib import Path


def _compose(config_dir: Path, config_name: str, overrides: list[str]):
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(config_dir=str(config_dir), version_base="1.3"):
        return compose(config_name, overrides=overrides)


def unknown_key_error(argv: list[str], config_dir: Path, config_name: str) -> str | None:
    """The one-line error for the override in `argv` (train.py's arguments) that names no key of
    the config `config_name` in `config_dir`, or None. Every other failure is left to Hydra's app,
    which reports it as it always has."""
    from hydra._internal.utils import get_args_parser  # hydra.main's own: the overrides it will compose
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from omegaconf import OmegaConf
    from omegaconf.errors import ConfigAttributeError, ConfigKeyError

    args = get_args_parser().parse_args(argv)
    if args.config_path or args.config_dir or args.config_name:  # another config than the one checked here
        return None
    try:
        _compose(config_dir, config_name, args.overrides)
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
        for o in OverridesParser.create().parse_overrides(args.overrides)
        if not f"{o.key_or_group}.".startswith(f"{key}.")
    ]
    try:
        cfg = _compose(config_dir, config_name, others)
    except Exception:  # another override fails too: Hydra's app reports it once this one is fixed
        return message
    node = OmegaConf.select(cfg, parent) if parent else cfg
    return f"{message}; valid keys{f' of {parent}' if parent else ''}: {sorted(node)}"
