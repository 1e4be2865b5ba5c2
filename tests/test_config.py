"""Config validation: unknown keys and wrong types are errors that name the valid choices."""

from __future__ import annotations

import pytest

from sdc_gym.config import ConfigError, resolve_config

DEFAULTS = {"laps": 1, "duration": 600.0, "name": "default", "nested": {"a": 1, "b": True}}


def test_defaults_are_copied_and_overrides_applied():
    config = resolve_config(DEFAULTS, {"laps": 3, "duration": 5, "nested": {"b": False}},
                            owner="X")
    assert config == {"laps": 3, "duration": 5, "name": "default",
                      "nested": {"a": 1, "b": False}}
    config["nested"]["a"] = 99
    assert DEFAULTS["nested"]["a"] == 1


def test_unknown_key_names_the_valid_keys_and_a_suggestion():
    with pytest.raises(ConfigError) as error:
        resolve_config(DEFAULTS, {"lapz": 2}, owner="HighwayLoop-v0")
    message = str(error.value)
    assert "'lapz'" in message and "did you mean 'laps'" in message
    assert "duration, laps, name, nested" in message


def test_unknown_nested_key_and_wrong_types():
    with pytest.raises(ConfigError, match=r"X\.nested: unknown config key 'c'"):
        resolve_config(DEFAULTS, {"nested": {"c": 1}}, owner="X")
    with pytest.raises(ConfigError, match="'laps' expects int, got float"):
        resolve_config(DEFAULTS, {"laps": 1.5}, owner="X")
    with pytest.raises(ConfigError, match="'nested' expects dict"):
        resolve_config(DEFAULTS, {"nested": 3}, owner="X")
    with pytest.raises(ConfigError, match="expects bool"):
        resolve_config(DEFAULTS, {"nested": {"b": 1}}, owner="X")


def test_none_never_stands_in_for_a_value_whose_default_is_not_none():
    """Found by fuzzing the batch: ``shield.abort_gap_m: None`` reached the shield's
    ``>=`` check as a raw TypeError."""
    import gymnasium as gym

    import sdc_gym  # noqa: F401
    with pytest.raises(ConfigError, match=r"'abort_gap_m' expects float, got NoneType"):
        gym.make("sdc_gym/HighwayLoopBehavior-v0", config={"shield": {"abort_gap_m": None}})
    gym.make("sdc_gym/HighwayLoop-v0", config={"start_s": None}).close()  # None default: ok
