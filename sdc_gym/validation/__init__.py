"""The validation layer: every bad input a clear error, before it reaches the simulation.

* :mod:`~sdc_gym.validation.rules`: value rules (ranges, finiteness, choices, pairs) and
  :func:`~sdc_gym.validation.rules.check_rules`, on top of the key and type checks of
  :func:`sdc_gym.config.resolve_config`;
* :mod:`~sdc_gym.validation.bounds`: the sizes bounded by memory and time (points, cars,
  frames per step, loop length), each stated in its error;
* :mod:`~sdc_gym.validation.env_configs`: the rule tables and cross-key checks of each
  env's config, called where the config is resolved;
* :mod:`~sdc_gym.validation.actions`: one check of an action's type, dtype and shape,
  shared by every env's ``step`` (before any state changes);
* :mod:`~sdc_gym.validation.text_files`: map, track and light files read as UTF-8 text
  of bounded size, with a clear error for binary or other encodings;
* :mod:`~sdc_gym.validation.road_geometry`: a loop must be closed, simple (not
  self-intersecting), of sane radius and length.

Every error is a :class:`~sdc_gym.config.ConfigError` (a ``ValueError``) naming the key,
the value and the valid range; a bad action is a ``ValueError`` naming the expected shape
and dtype. ``docs/guarantees.md`` lists what is checked.
"""

from sdc_gym.config import ConfigError
from sdc_gym.validation.rules import Choice, Number, NumberList, Pair, check_rules, check_value

__all__ = ["Choice", "ConfigError", "Number", "NumberList", "Pair", "check_rules",
           "check_value"]
