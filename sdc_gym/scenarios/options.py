"""A scenario given in ``reset(options=...)``: one for a single env, one (or one per env)
for a batch."""

from __future__ import annotations

from typing import Any

from sdc_gym.scenarios.episode import CONFIG

OPTION = "scenario"
"""The reset option's key: ``env.reset(options={"scenario": PATH_OR_MAPPING_OR_NONE})``."""


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


__all__ = ["CONFIG", "OPTION", "batch_scenarios", "scenario_option"]
