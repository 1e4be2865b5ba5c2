"""Config dictionaries for the environments: defaults merged with user overrides, checked.

``gym.make(id, config={...})`` overrides an env's documented defaults. A key that is not a
default is an error naming the valid keys (a typo must never be silently ignored, unlike
highway-env's unchecked ``configure``), and a value of the wrong type is an error naming
the key and the expected type.
"""

from __future__ import annotations

import copy
import difflib
import reprlib
from collections.abc import Mapping
from typing import Any, Final


class ConfigError(ValueError):
    """An unknown config key or a value of the wrong type."""


EXCERPT_CHARS: Final = 200
"""The most characters of a bad value an error message quotes."""

_EXCERPT = reprlib.Repr()  # Python 3.11's Repr takes no keyword arguments
_EXCERPT.maxlevel = 3
_EXCERPT.maxtuple = _EXCERPT.maxlist = _EXCERPT.maxarray = _EXCERPT.maxdict = 6
_EXCERPT.maxset = _EXCERPT.maxfrozenset = _EXCERPT.maxdeque = 6
_EXCERPT.maxstring, _EXCERPT.maxlong, _EXCERPT.maxother = 60, 40, 60


def excerpt(value: Any, limit: int = EXCERPT_CHARS) -> str:
    """A bounded ``repr`` of ``value`` for an error message: a few items of each
    collection, a few levels, at most ``limit`` characters (a 10,000-car list gave a
    370,105-character message, a list of aliased leaves 5.8 MB). Built without the full
    repr, so that the message costs no time or memory whatever the value."""
    text = _EXCERPT.repr(value)
    if isinstance(value, list | tuple | dict | set) and len(value) > _EXCERPT.maxlist:
        text += f" ({len(value):,} items)"
    return shorten(text, limit)


def shorten(text: str, limit: int = EXCERPT_CHARS) -> str:
    """``text`` cut to at most ``limit`` characters (the cut said)."""
    if len(text) <= limit:
        return text
    return f"{text[:limit - 30]}... ({len(text):,} characters)"


def _type_name(value: Any) -> str:
    return type(value).__name__


def _compatible(default: Any, value: Any) -> bool:
    """Whether ``value`` may replace ``default`` (numbers widen, None defaults take any)."""
    if default is None:  # an optional key (e.g. start_s): its rule checks the value
        return True
    if value is None:  # None never stands in for a number, a name or a flag
        return False
    if isinstance(default, bool):
        return isinstance(value, bool)
    if isinstance(default, int):
        return isinstance(value, int) and not isinstance(value, bool)
    if isinstance(default, float):
        return isinstance(value, int | float) and not isinstance(value, bool)
    if isinstance(default, str):
        return isinstance(value, str)
    if isinstance(default, list | tuple):
        return isinstance(value, list | tuple)
    if isinstance(default, Mapping):
        return isinstance(value, Mapping)
    return isinstance(value, type(default))


def resolve_config(
    defaults: Mapping[str, Any], overrides: Mapping[str, Any] | None, *, owner: str
) -> dict[str, Any]:
    """Return ``defaults`` updated with ``overrides`` after checking every key and type.

    Nested mappings (a default that is itself a dict) are resolved recursively, with their
    own valid keys. ``owner`` names the env in error messages.
    """
    resolved = copy.deepcopy(dict(defaults))
    if overrides is None:
        return resolved
    if not isinstance(overrides, Mapping):
        raise ConfigError(f"{owner}: config must be a mapping, got {_type_name(overrides)}")
    for key, value in overrides.items():
        if key not in defaults:
            close = difflib.get_close_matches(str(key), list(defaults), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ConfigError(
                f"{owner}: unknown config key {key!r}{hint}. "
                f"Valid keys: {', '.join(sorted(defaults))}"
            )
        default = defaults[key]
        if not _compatible(default, value):
            raise ConfigError(
                f"{owner}: config key {key!r} expects {_type_name(default)}, "
                f"got {_type_name(value)} ({excerpt(value)})"
            )
        if isinstance(default, Mapping) and default:
            resolved[key] = resolve_config(default, value, owner=f"{owner}.{key}")
        else:
            resolved[key] = copy.deepcopy(value)
    return resolved


def require(condition: bool, owner: str, key: str, expectation: str, value: Any) -> None:
    """Raise :class:`ConfigError` unless ``condition``: ``key`` must satisfy ``expectation``."""
    if not condition:
        raise ConfigError(f"{owner}: config key {key!r} must be {expectation}, "
                          f"got {excerpt(value)}")
