"""How a config is checked: `check_config` walks a config tree (dataclasses) once, each section by
what its class declares (BOUNDS, RANGES, CHOICES, `check_rules`), and refuses an unknown key, a
non-finite number, or a value out of its bound, naming the key (`ConfigError`). `Bound` is a numeric
setting's limits with the reason for them."""

from __future__ import annotations

import math
import numbers
from collections.abc import Collection, Mapping
from dataclasses import dataclass, fields, is_dataclass
from typing import Any

from lasmp.io.inputs import InputError, check_seed


class ConfigError(ValueError):
    """A configuration value is out of range or inconsistent; the message names the field."""


def _text(x: float) -> str:
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e16 else repr(float(x))


@dataclass(frozen=True)
class Bound:
    """The values a numeric setting may take, and the physical or computational reason for the limits:
    [lo, hi], or open at an end (`open_lo`: a scale or a time, where 0 means nothing). Every number of
    every config has one (a [low, high] pair is checked by `check_range`, a reward weight by
    `check_named`); tests/bad_inputs/test_bad_setting_ranges.py walks them all."""

    lo: float
    hi: float
    why: str
    open_lo: bool = False
    open_hi: bool = False

    def interval(self) -> str:
        return (
            f"{'(' if self.open_lo else '['}{_text(self.lo)}, {_text(self.hi)}{')' if self.open_hi else ']'}"
        )

    def holds(self, value: Any, integer: bool = False) -> bool:
        if isinstance(value, bool) or not isinstance(value, numbers.Integral if integer else numbers.Real):
            return False
        above = self.lo < value if self.open_lo else self.lo <= value  # False for NaN
        below = value < self.hi if self.open_hi else value <= self.hi
        return above and below

    def check(self, name: str, value: Any, integer: bool = False) -> None:
        """Refuse `value` (a number, or a list of numbers: each of them) outside the bound, naming `name`."""
        many = isinstance(value, (list, tuple))
        if not all(self.holds(v, integer) for v in (value if many else [value])):
            what = ("integers" if many else "an integer") if integer else ("numbers" if many else "a number")
            raise ConfigError(
                f"{name} must {'hold' if many else 'be'} {what} in {self.interval()} ({self.why}), "
                f"got {list(value) if many else value!r}"
            )


def check_bounds(cfg: Any, p: str, bounds: Mapping[str, Bound]) -> None:
    """Each field of dataclass `cfg` that `bounds` names within its Bound (each number of a list), named
    `p.field`; a field declared `int` (or `list[int]`) must hold integers."""
    declared = {f.name: str(f.type) for f in fields(cfg)}
    for name, bound in bounds.items():
        bound.check(_key(p, name), getattr(cfg, name), declared[name] in ("int", "list[int]"))


def _key(p: str, name: str) -> str:
    return f"{p}.{name}" if p else name


def check_range(name: str, lo_hi: tuple[float, float] | list[float], bound: Bound) -> None:
    """Refuse a `[low, high]` pair that is not ordered or whose ends are not within `bound`."""
    pair = list(lo_hi)
    if not (len(pair) == 2 and bound.holds(pair[0]) and bound.holds(pair[1]) and pair[0] <= pair[1]):
        raise ConfigError(
            f"{name} must be a [low, high] pair with low <= high, both in {bound.interval()} ({bound.why}), "
            f"got {pair}"
        )


def check_seed_key(name: str, value: Any) -> None:
    """The one rule of every seed (`lasmp.io.inputs.check_seed`) as a ConfigError."""
    try:
        check_seed(value, name)
    except InputError as err:
        raise ConfigError(str(err)) from None


def check_known_keys(cfg: Any, p: str = "") -> None:
    """Refuse an attribute that `cfg`'s dataclass (or a nested one) does not declare, naming it.

    Hydra's `+key=value` appends to a config in open-dict mode, and `OmegaConf.to_object` then sets
    the extra key as a plain attribute: a `+env.trajectory.fiel=x` typo would otherwise be ignored.
    The same catches `cfg.env.num_env = 8` in code.
    """
    declared = [f.name for f in fields(cfg)]
    unknown = sorted(set(vars(cfg)) - set(declared))
    if unknown:
        keys = [f"{p}.{name}" if p else name for name in unknown]
        raise ConfigError(
            f"unknown config key(s) {keys}; valid keys{f' of {p}' if p else ''}: {sorted(declared)}"
        )
    for name in declared:
        value = getattr(cfg, name)
        if is_dataclass(value):
            check_known_keys(value, f"{p}.{name}" if p else name)


def check_finite_values(cfg: Any, p: str = "") -> None:
    """Refuse NaN or an infinity in any number of `cfg` (nested dataclasses, lists, dicts), naming its
    key: a range check such as `learning_rate <= 0` lets NaN through, and no setting here means
    anything by an infinity."""
    for f in fields(cfg):
        _check_finite(getattr(cfg, f.name), f"{p}.{f.name}" if p else f.name)


def _check_finite(value: Any, key: str) -> None:
    if is_dataclass(value):
        check_finite_values(value, key)
    elif isinstance(value, Mapping):
        for k, v in value.items():
            _check_finite(v, f"{key}.{k}")
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            _check_finite(v, f"{key}[{i}]")
    elif isinstance(value, float) and not math.isfinite(value):
        raise ConfigError(f"{key} must be a finite number, got {value}")


def check_config(cfg: Any, p: str) -> None:
    """Check the config tree `cfg` (a dataclass, named `p`) whole, each section once: its keys
    (`check_known_keys`) and numbers (`check_finite_values`), then every section's declared limits,
    then each section's own rules, in the tree's order. A section's class declares what its settings
    may be: BOUNDS (field -> Bound), RANGES (field -> the Bound of a [low, high] pair, `check_range`),
    CHOICES (field -> the words it may be), NAMED (a mapping field -> (the names its keys may be, the
    Bound of each value, what a key is), `check_named`); and `check_rules(p)` holds what relates its
    fields or needs code. This walk is the one place that checks them."""
    check_known_keys(cfg, p)
    check_finite_values(cfg, p)
    sections = list(_sections(cfg, p))
    for path, section in sections:
        kind = type(section)
        check_bounds(section, path, getattr(kind, "BOUNDS", {}))
        for name, bound in getattr(kind, "RANGES", {}).items():
            check_range(_key(path, name), getattr(section, name), bound)
        for name, words in getattr(kind, "CHOICES", {}).items():
            check_choice(_key(path, name), getattr(section, name), words)
        for name, (names, bound, what) in getattr(kind, "NAMED", {}).items():
            check_named(_key(path, name), getattr(section, name), names, bound, what)
    for path, section in sections:
        if hasattr(section, "check_rules"):
            section.check_rules(path)


def _sections(cfg: Any, p: str):
    """(name, section) of dataclass `cfg` and of every dataclass under it, depth first, fields in order."""
    yield p, cfg
    for f in fields(cfg):
        value = getattr(cfg, f.name)
        if is_dataclass(value):
            yield from _sections(value, _key(p, f.name))


def check_named(
    key: str, values: Mapping[str, float], names: Collection[str], bound: Bound, what: str
) -> None:
    """Refuse a key of mapping `values` that is not one of `names` (listing them; `what` says what a key
    is, e.g. "reward term"), or a value outside `bound`."""
    unknown = sorted(set(values) - set(names))
    if unknown:
        raise ConfigError(f"{key}: unknown {what}(s) {unknown}; valid {what}s: {sorted(names)}")
    for name, value in values.items():
        bound.check(f"{key}.{name}", value)


def check_choice(name: str, value: Any, words: tuple[str, ...]) -> None:
    """Refuse a setting that is not one of `words`, naming them."""
    if value not in words:
        raise ConfigError(f"{name} must be one of {' | '.join(words)}, got {value!r}")
