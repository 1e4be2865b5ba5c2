"""The FSM's rules and thresholds read from a YAML rule file (the seed's "build a simplified
rule system and read parameters from a file").

A rule file names a ``style`` and may set any field of
:class:`~sdc_agents.highway.fsm_parameters.FSMParameters` by its name; the nested ones
(``calm``, ``active``: the range profiles; ``alert``, ``caution``, ``reverse``, ``hyper``:
the optional modes) are mappings of their own fields. A key left out keeps the style's
value, so ``{style: bold, hyper: {enabled: true}}`` is Bold with Hyper. ``ghosting``
(perception's, default: on for the Conservative style) completes it. The project ships the
seed's two styles as complete files, ``rules/conservative.yaml`` and ``rules/bold.yaml``
(every key, at the built-in values to the bit: ``tests/test_fsm_rules.py``), and one per
optional mode.

The file goes through the project's one YAML loader
(:func:`sdc_gym.validation.yaml_files.read_yaml_lines`: bounded size, nesting and aliases,
no duplicate keys, YAML 1.2 numbers), and every problem is a :class:`RuleFileError` naming
the file, the line, the key, the value and what it may be::

    bold.yaml:7: FSM rule key 'calm.brake_range_m' must be a finite number >= 0 (m), got -3
    bold.yaml:3: unknown FSM rule key 'calm.brake_rang_m' (did you mean 'brake_range_m'?);
    valid keys of calm: brake_range_m, mid_range_m, ...
"""

from __future__ import annotations

import dataclasses
import difflib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from sdc_agents.highway.fsm_parameters import DrivingStyle, FSMParameters
from sdc_gym.config import excerpt
from sdc_gym.validation.rules import Number, is_real

RULES_FOLDER: Final = Path(__file__).parent / "rules"
"""The packaged rule files (``<name>.yaml``)."""

_STYLES: Final = {style.value: style for style in DrivingStyle}
# Fields that may be infinite (a lane open only when nobody is sensed).
_MAY_BE_INFINITE: Final = frozenset({"open_lane_m"})
# Fields with a bound other than ">= 0" (the rest are distances, times, speeds, rates).
_BOUNDS: Final[dict[str, Number]] = {
    "brake_curve_decay_per_m": Number(low=0.0, low_open=True, unit="1/m"),
    "hard_braking_fraction": Number(low=0.0, high=1.0),
    "advance_speed_factor": Number(low=0.0, low_open=True),
    "max_speed_mps": Number(low=0.0, low_open=True, unit="m/s"),
    "cruise_speed_mps": Number(low=0.0, low_open=True, unit="m/s"),
    "brake_curve_offset_pct": Number(unit="%"),
}
_UNITS: Final = (("_mps2", "m/s^2"), ("_mps", "m/s"), ("_per_s", "1/s"), ("_pct_per_m", "%/m"),
                 ("_per_m", "1/m"), ("_m", "m"), ("_s", "s"))


class RuleFileError(ValueError):
    """A rule file that cannot be used; the message names the file, line, key and value."""


@dataclass(frozen=True)
class FSMRules:
    """A rule file's content: the style (the agent's label and the defaults), perception's
    ghosting and every threshold."""

    style: DrivingStyle
    ghosting: bool
    params: FSMParameters
    source: str


def rule_file(name_or_path: str | os.PathLike[str]) -> Path:
    """A packaged rule file by name (``"bold"``) or any path to one."""
    text = os.fspath(name_or_path)
    packaged = RULES_FOLDER / f"{text}.yaml"
    if os.sep not in text and "/" not in text and not text.endswith((".yaml", ".yml")):
        if packaged.is_file():
            return packaged
        raise RuleFileError(f"no packaged FSM rule file {text!r}; packaged: "
                            f"{', '.join(packaged_rule_files())} (or give a path to a .yaml)")
    return Path(text)


def packaged_rule_files() -> list[str]:
    """The names of the packaged rule files."""
    return sorted(path.stem for path in RULES_FOLDER.glob("*.yaml"))


def load_rules(name_or_path: str | os.PathLike[str]) -> FSMRules:
    """Read and check a rule file (see the module docstring)."""
    # Imported here: the validation package's loader pulls in the config machinery.
    from sdc_gym.validation.yaml_files import read_yaml_lines

    path = rule_file(name_or_path)
    data, lines = read_yaml_lines(path, "FSM rule file", RuleFileError)
    source = str(path)

    def fail(key: str, message: str) -> RuleFileError:
        line = lines.get(key, lines.get("", 1))
        return RuleFileError(f"{source}:{line}: {message}")

    if not isinstance(data, dict):
        raise fail("", f"an FSM rule file is a mapping of keys (style, ...), got "
                       f"{excerpt(data)}")
    if "style" not in data:
        raise fail("", f"FSM rule key 'style' is required: one of {sorted(_STYLES)}")
    style_name = data["style"]
    if not isinstance(style_name, str) or style_name not in _STYLES:
        raise fail("style", f"FSM rule key 'style' must be one of {sorted(_STYLES)}, got "
                            f"{excerpt(style_name)}")
    style = _STYLES[style_name]
    ghosting = data.get("ghosting", style is DrivingStyle.CONSERVATIVE)
    if not isinstance(ghosting, bool):
        raise fail("ghosting", f"FSM rule key 'ghosting' must be true or false, got "
                               f"{excerpt(ghosting)}")
    fields = {key: value for key, value in data.items() if key not in ("style", "ghosting")}
    base = FSMParameters.for_style(style)
    try:
        params = _replaced(base, fields, "", fail, extra=("style", "ghosting"))
    except RuleFileError:
        raise
    except ValueError as problem:
        # FSMParameters' own cross-field checks (the max speed within the limit, the
        # cruise speed within the max speed): the line of the first key they name.
        named = next((key for key in fields if str(key) in str(problem)), "")
        raise fail(named, f"FSM rules: {problem} (with the style's values for the keys "
                          "left out)") from None
    return FSMRules(style, ghosting, params, source)


def _replaced(base: Any, values: dict[Any, Any], prefix: str, fail: Any,
              extra: tuple[str, ...] = ()) -> Any:
    """``base`` (a frozen dataclass) with ``values`` checked and put in, recursively."""
    fields = {field.name: field for field in dataclasses.fields(base)}
    changes: dict[str, Any] = {}
    for key, value in values.items():
        path = f"{prefix}{key}"
        if key not in fields:
            valid = [*extra, *fields]
            close = difflib.get_close_matches(str(key), valid, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            owner = prefix[:-1] or "the rule file"
            raise fail(path, f"unknown FSM rule key {excerpt(path)}{hint}; valid keys of "
                             f"{owner}: {', '.join(valid)}")
        current = getattr(base, key)
        if dataclasses.is_dataclass(current):
            if not isinstance(value, dict):
                raise fail(path, f"FSM rule key {path!r} must be a mapping of "
                                 f"{', '.join(f.name for f in dataclasses.fields(current))}, "
                                 f"got {excerpt(value)}")
            changes[key] = _replaced(current, value, f"{path}.", fail)
        elif isinstance(current, bool):
            if not isinstance(value, bool):
                raise fail(path, f"FSM rule key {path!r} must be true or false, got "
                                 f"{excerpt(value)}")
            changes[key] = value
        else:
            rule = _BOUNDS.get(key) or Number(low=0.0, allow_inf=key in _MAY_BE_INFINITE,
                                              unit=_unit(key))
            problem = rule.problem(value)
            if problem is not None:
                raise fail(path, f"FSM rule key {path!r} must be {problem}, got "
                                 f"{excerpt(value)}")
            changes[key] = float(value) if is_real(value) else value
    return dataclasses.replace(base, **changes) if changes else base


def _unit(key: str) -> str:
    return next((unit for suffix, unit in _UNITS if key.endswith(suffix)), "")


def rules_text(rules: FSMParameters, style: DrivingStyle, ghosting: bool) -> str:
    """Every key of ``rules`` as YAML a rule file can hold (floats as ``repr`` writes them,
    so that reading it back gives the same bits): how the packaged files were written."""
    out = [f"style: {style.value}", f"ghosting: {'true' if ghosting else 'false'}"]

    def value_text(value: Any) -> str:
        if isinstance(value, bool):
            return "true" if value else "false"
        if value == float("inf"):
            return ".inf"
        return repr(float(value))

    for field in dataclasses.fields(rules):
        value = getattr(rules, field.name)
        if dataclasses.is_dataclass(value):
            out.append(f"{field.name}:")
            out.extend(f"  {inner.name}: {value_text(getattr(value, inner.name))}"
                       for inner in dataclasses.fields(value))
        else:
            out.append(f"{field.name}: {value_text(value)}")
    return "\n".join(out) + "\n"
