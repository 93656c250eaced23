"""Which recipe a training config follows, named in one place: the start line of a training, its run
directory (`logs/<task>/<recipe>[-<policy>]/...`) and an evaluation's metrics.md say it.

Why: LAS-MP+ (ours, the default) and the paper's literal recipe train the same networks on the same
task, so the task and the policy name (`lasmp`) cannot tell them apart; a user who trains the default
must read "LAS-MP+", and one who trains `recipe=paper` "the paper's recipe".

A recipe is a file `cfg/recipe/<key>.yaml`: a handful of config keys (the reward's air-time charge, the
support-margin bonus, the mirror augmentation). A config follows a recipe when it holds every key of
the file at the file's value. The names are derived from those files, never from a copy of their keys,
so a recipe edited in cfg/ is still named right. A config that follows neither (a recipe key overridden
by hand) is a custom mix and is named so; a task whose config lacks one of the keys (R-S's
rough_static) has no recipe, and its policy names it.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from omegaconf import OmegaConf

RECIPE_DIR = Path(__file__).resolve().parents[2] / "cfg" / "recipe"
# recipe file -> (the name a user reads, the run directory's name); the paper's method is LAS-MP
RECIPES = {
    "lasmp_plus": ("LAS-MP+", "lasmp_plus"),
    "paper": ("LAS-MP (the paper's recipe)", "lasmp_paper"),
}
CUSTOM = ("LAS-MP (a custom recipe: neither LAS-MP+ nor the paper's)", "lasmp_custom")
DEFAULT_POLICY = "lasmp"  # the full method; any other policy is an ablation, named after the recipe


def recipe_keys(key: str) -> dict[str, object]:
    """The dotted config keys of cfg/recipe/<key>.yaml with their values."""
    tree = OmegaConf.to_container(OmegaConf.load(RECIPE_DIR / f"{key}.yaml"))
    flat: dict[str, object] = {}

    def walk(node, prefix):
        for name, value in node.items():
            if isinstance(value, dict):
                walk(value, f"{prefix}{name}.")
            else:
                flat[prefix + name] = value

    walk(tree, "")
    return flat


def _plain(cfg) -> dict:
    if isinstance(cfg, dict):
        return cfg
    if dataclasses.is_dataclass(cfg):
        return OmegaConf.to_container(OmegaConf.structured(cfg))
    return OmegaConf.to_container(cfg)


def _select(plain: dict, dotted: str):
    node = plain
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            return _MISSING
        node = node[part]
    return node


_MISSING = object()


def recipe_of(cfg) -> str | None:
    """The key of the recipe `cfg` (TrainCfg, or its plain dict) follows: "lasmp_plus", "paper", "custom"
    (it holds the recipes' keys at values of neither), or None (its task lacks a recipe key: R-S's
    rough_static has no air-time charge)."""
    plain = _plain(cfg)
    files = {key: recipe_keys(key) for key in RECIPES}
    if any(_select(plain, k) is _MISSING for keys in files.values() for k in keys):
        return None
    for key, keys in files.items():
        if all(_select(plain, k) == v for k, v in keys.items()):
            return key
    return "custom"


def _names(cfg) -> tuple[str, str, str] | None:
    key = recipe_of(cfg)
    if key is None:
        return None
    name, slug = CUSTOM if key == "custom" else RECIPES[key]
    policy = _select(_plain(cfg), "policy.name")
    return name, slug, "" if policy in (DEFAULT_POLICY, _MISSING) else str(policy)


def recipe_name(cfg, default: str = "LAS-MP") -> str:
    """The recipe's name alone ("LAS-MP+", "LAS-MP (the paper's recipe)"); `default` for a task
    without a recipe. metrics.md's header names the policy after it."""
    names = _names(cfg)
    return default if names is None else names[0]


def run_label(cfg) -> str:
    """What a user reads: "LAS-MP+", "LAS-MP (the paper's recipe)", an ablation as "LAS-MP+, policy
    no_alignment_command"; a task without a recipe: its policy's name."""
    names = _names(cfg)
    if names is None:
        return str(_select(_plain(cfg), "policy.name"))
    name, _, policy = names
    return f"{name}, policy {policy}" if policy else name


def run_slug(cfg) -> str:
    """The run directory's name under logs/<task>/: "lasmp_plus", "lasmp_paper", an ablation as
    "lasmp_plus-no_alignment_command"; a task without a recipe: its policy's name."""
    names = _names(cfg)
    if names is None:
        return str(_select(_plain(cfg), "policy.name"))
    _, slug, policy = names
    return f"{slug}-{policy}" if policy else slug
