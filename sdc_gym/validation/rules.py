"""Declarative value rules for configs: types, ranges, finiteness, choices, pairs.

:func:`~sdc_gym.config.resolve_config` checks each key against the env's documented
defaults (no unknown key, no value of another type). The rules here check what types
cannot: ranges and finiteness. A rule table maps a key path (``"traffic.idm.a_max"``) to
a rule, and :func:`check_rules` applies it to a resolved config, raising
:class:`~sdc_gym.config.ConfigError` with the message every config error has::

    HighwayLoop-v0: config key 'traffic.idm.a_max' must be a finite number > 0 (m/s^2),
    got -1

On top of the table, :func:`check_finite` refuses NaN and infinity anywhere in a config
(nested mappings and lists too) unless a rule allows infinity for that key: a NaN reward
weight or size must never reach the simulation.

Why rules and not pydantic models: the env's ``DEFAULT_CONFIG`` (with a unit comment per
key) stays the one source of keys, defaults and types, and ``resolve_config`` already
refuses unknown keys and wrong types without coercing anything (pydantic's default mode
turns ``"5"`` into ``5``); the checks that remain are ranges, one line per key here, and
cross-key or data-dependent checks (a step bounded by the episode, a start on the loaded
map's road, a map's geometry), which are code in either case. The messages keep the one
format of every config error (key, value, valid range) without translating pydantic's.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from sdc_gym.config import ConfigError, excerpt


def is_real(value: Any) -> bool:
    """An int or float (a bool is not a number here), NumPy's too."""
    return (isinstance(value, int | float | np.integer | np.floating)
            and not isinstance(value, bool | np.bool_))


def number_text(value: float) -> str:
    """A bound as people write it: ints exactly (``4294967295``), floats short (``0.5``)."""
    if isinstance(value, int) or (float(value).is_integer() and abs(value) < 1e16):
        return str(int(value))
    return f"{value:g}"


def _interval(low: float | None, high: float | None, low_open: bool, high_open: bool) -> str:
    if low is None and high is None:
        return ""
    if high is None:
        return f"{'>' if low_open else '>='} {number_text(low)}"
    if low is None:
        return f"{'<' if high_open else '<='} {number_text(high)}"
    return (f"in {'(' if low_open else '['}{number_text(low)}, {number_text(high)}"
            f"{')' if high_open else ']'}")


class Rule(Protocol):
    """Checks one value: :meth:`problem` is ``None`` when it is good."""

    def problem(self, value: Any) -> str | None: ...


@dataclass(frozen=True)
class Number:
    """A real number (or an int with ``integer``) in an interval, finite unless
    ``allow_inf``; ``None`` too when ``optional``. ``unit`` and ``why`` go in the message."""

    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    integer: bool = False
    optional: bool = False
    allow_inf: bool = False
    unit: str = ""
    why: str = ""

    @property
    def expectation(self) -> str:
        kind = "an int" if self.integer else (
            "a number (inf allowed)" if self.allow_inf else "a finite number")
        text = " ".join(part for part in (kind, _interval(
            self.low, self.high, self.low_open, self.high_open)) if part)
        if self.unit:
            text += f" ({self.unit})"
        if self.optional:
            text = f"None or {text}"
        if self.why:
            text += f": {self.why}"
        return text

    def problem(self, value: Any) -> str | None:
        if value is None and self.optional:
            return None
        good = is_real(value) and (not self.integer or isinstance(value, int | np.integer))
        if good and isinstance(value, float | np.floating):
            good = not math.isnan(value) and (self.allow_inf or not math.isinf(value))
        if good and self.low is not None:
            good = value > self.low if self.low_open else value >= self.low
        if good and self.high is not None:
            good = value < self.high if self.high_open else value <= self.high
        return None if good else self.expectation


@dataclass(frozen=True)
class Pair:
    """A ``[low, high]`` pair of :class:`Number` ``each`` with ``low <= high`` (``<`` with
    ``strict``)."""

    each: Number
    strict: bool = False

    def problem(self, value: Any) -> str | None:
        order = "<" if self.strict else "<="
        expectation = f"a [min, max] pair with min {order} max, each {self.each.expectation}"
        if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != 2:
            return expectation
        if any(self.each.problem(item) is not None for item in value):
            return expectation
        low, high = value
        return None if (low < high if self.strict else low <= high) else expectation


@dataclass(frozen=True)
class Choice:
    """One of ``choices`` (compared with ``==``, types exactly: ``True`` is not ``1``)."""

    choices: tuple[Any, ...]

    def problem(self, value: Any) -> str | None:
        if any(type(value) is type(choice) and value == choice for choice in self.choices):
            return None
        return f"one of {list(self.choices)}"


@dataclass(frozen=True)
class NumberList:
    """A list of :class:`Number` ``each``, of ``min_length`` .. ``max_length`` items
    (``None`` too when ``optional``)."""

    each: Number
    min_length: int = 0
    max_length: int | None = None
    optional: bool = False

    def problem(self, value: Any) -> str | None:
        if value is None and self.optional:
            return None
        size = f"{self.min_length}.." + ("" if self.max_length is None else str(self.max_length))
        expectation = (f"{'None or ' if self.optional else ''}a list of {size} items, each "
                       f"{self.each.expectation}")
        if not isinstance(value, Sequence) or isinstance(value, str):
            return expectation
        if len(value) < self.min_length or (self.max_length is not None
                                            and len(value) > self.max_length):
            return expectation
        return expectation if any(self.each.problem(item) for item in value) else None


def lookup(config: Mapping[str, Any], path: str) -> tuple[bool, Any]:
    """``(found, value)`` of a dotted key path in nested mappings."""
    node: Any = config
    for part in path.split("."):
        if not isinstance(node, Mapping) or part not in node:
            return False, None
        node = node[part]
    return True, node


def fail(owner: str, key: str, expectation: str, value: Any) -> ConfigError:
    """The one format of a bad value: owner, key, what it must be, what it is."""
    return ConfigError(f"{owner}: config key {key!r} must be {expectation}, got {excerpt(value)}")


def check_value(rule: Rule, value: Any, owner: str, key: str) -> None:
    """Raise :class:`~sdc_gym.config.ConfigError` unless ``rule`` accepts ``value``."""
    expectation = rule.problem(value)
    if expectation is not None:
        raise fail(owner, key, expectation, value)


def check_rules(rules: Mapping[str, Rule], config: Mapping[str, Any], owner: str) -> None:
    """Apply every rule whose key is in ``config`` (table order), then :func:`check_finite`
    for the keys no rule covers."""
    for key, rule in rules.items():
        found, value = lookup(config, key)
        if found:
            check_value(rule, value, owner, key)
    allowed = {key for key, rule in rules.items()
               if getattr(rule, "allow_inf", False)}
    check_finite(config, owner, skip=set(rules) - allowed, allow_inf=allowed)


def check_finite(config: Any, owner: str, *, prefix: str = "", skip: set[str] | None = None,
                 allow_inf: set[str] | None = None) -> None:
    """Refuse NaN and infinity anywhere below ``config`` (but in ``skip``; infinity in
    ``allow_inf``), naming the key path (list items as ``key[i]``)."""
    skip = skip or set()
    allow_inf = allow_inf or set()
    if prefix in skip:
        return
    if isinstance(config, Mapping):
        for key, value in config.items():
            check_finite(value, owner, prefix=f"{prefix}.{key}" if prefix else str(key),
                         skip=skip, allow_inf=allow_inf)
    elif isinstance(config, list | tuple):
        for index, value in enumerate(config):
            check_finite(value, owner, prefix=f"{prefix}[{index}]", skip=skip,
                         allow_inf=allow_inf)
    elif isinstance(config, float) and not math.isfinite(config):
        base = prefix.split("[", 1)[0]
        if not (math.isinf(config) and base in allow_inf):
            raise fail(owner, prefix, "a finite number (NaN and infinity are never valid "
                       "here)", config)
