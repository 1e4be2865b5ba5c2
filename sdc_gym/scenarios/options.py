"""A scenario given in ``reset(options=...)``: one for a single env, one (or one per env)
for a batch."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from sdc_gym.config import excerpt
from sdc_gym.scenarios.episode import CONFIG

OPTION = "scenario"
"""The reset option's key: ``env.reset(options={"scenario": PATH_OR_MAPPING_OR_NONE})``."""


RESET_MASK = "reset_mask"
"""A batch's reset option: which envs to reset (``DISABLED`` autoreset)."""


def check_reset_options(options: Any, owner: str, keys: tuple[str, ...]) -> None:
    """``ValueError`` unless ``options`` is ``None`` or a mapping of ``keys`` only: a
    reset option nobody reads (``options="x"``, a typo, ``{"scenario": ...}`` on a track
    env) was silently dropped."""
    valid = ", ".join(repr(key) for key in keys) if keys else "none (it takes no options)"
    if options is None:
        return
    if not isinstance(options, Mapping):
        raise ValueError(f"{owner}.reset: options must be a mapping or None, got "
                         f"{type(options).__name__} ({excerpt(options)}); valid keys: {valid}")
    unknown = [key for key in options if key not in keys]
    if unknown:
        raise ValueError(f"{owner}.reset: unknown reset option {excerpt(unknown[0])}; valid "
                         f"keys: {valid}")


def reset_mask(options: Mapping[str, Any] | None, envs: int) -> np.ndarray | None:
    """The batch's ``reset_mask`` option: ``None``, or ``envs`` bools (a bool array or a
    list of Python bools; strings, ints and floats are refused, not coerced)."""
    if options is None or options.get(RESET_MASK) is None:
        return None
    value = options[RESET_MASK]
    try:
        mask = np.asarray(value)
    except ValueError:  # ragged
        mask = np.asarray([None])
    if mask.dtype != np.bool_ or mask.shape != (envs,):
        raise ValueError(f"options['reset_mask'] must be {envs} bools (shape ({envs},), "
                         f"dtype bool), got {excerpt(value)} (dtype {mask.dtype}, shape "
                         f"{mask.shape})")
    return mask


def scenario_option(options: dict[str, Any] | None, current: Any = CONFIG) -> Any:
    """The scenario of an env's reset: the options' (``None``: random traffic), else the
    one it ran before (:data:`CONFIG` at first: the config's). A scenario given in reset
    options stays until other options replace it, as a batch env's does through its
    autoresets."""
    if options is None or OPTION not in options:
        return current
    return options[OPTION]


def batch_scenarios(options: dict[str, Any] | None, envs: int) -> list[Any] | None:
    """Per env the scenario of a batch's reset options: one value for every env, or a
    list of one per env; ``None`` when the options give none (each env keeps its own)."""
    if options is None or OPTION not in options:
        return None
    value = options[OPTION]
    if isinstance(value, list | tuple):
        if len(value) != envs:
            raise ValueError(f"options['scenario'] must be one scenario or a list of "
                             f"{envs} (one per env, None for random traffic), got "
                             f"{len(value)}")
        return list(value)
    return [value] * envs


__all__ = ["CONFIG", "OPTION", "RESET_MASK", "batch_scenarios", "check_reset_options",
           "reset_mask", "scenario_option"]
