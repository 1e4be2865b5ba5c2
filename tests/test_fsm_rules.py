"""The FSM's rule files: the packaged styles are the built-in ones to the bit (parameters
and whole episodes), bad files name the file, line, key, value and choices, and rule files
are agents by name (``fsm:PATH``, ``fsm:bold``, ``fsm_alert``...)."""

from __future__ import annotations

import dataclasses
import re

import gymnasium as gym
import numpy as np
import pytest

import sdc_gym  # noqa: F401  (registers the envs)
from sdc_agents.highway.fsm_parameters import DrivingStyle, FSMParameters
from sdc_agents.highway.fsm_rules import (
    RULES_FOLDER,
    RuleFileError,
    load_rules,
    packaged_rule_files,
    rules_text,
)
from sdc_agents.registry import check_agent_env, make_agent

HIGHWAY = "sdc_gym/HighwayLoop-v0"


@pytest.mark.parametrize("style", list(DrivingStyle))
def test_the_packaged_style_files_are_the_built_in_styles(style):
    rules = load_rules(style.value)
    assert rules.style is style
    assert rules.ghosting is (style is DrivingStyle.CONSERVATIVE)
    assert rules.params == FSMParameters.for_style(style)
    # Every key is in the file (nothing left to the defaults), at the bits it has.
    written = (RULES_FOLDER / f"{style.value}.yaml").read_text(encoding="utf-8")
    keys = {line.split(":")[0].strip() for line in written.splitlines()
            if line.strip() and not line.lstrip().startswith("#")}
    wanted = {field.name for field in dataclasses.fields(FSMParameters)}
    assert wanted <= keys
    body = "".join(line for line in written.splitlines(keepends=True)
                   if not line.lstrip().startswith("#"))
    assert body == rules_text(rules.params, style, rules.ghosting)


MODES = ("alert", "caution", "reverse", "hyper")
OPTIONS = ("straight_braking", "reroute", "easing")


def test_the_packaged_mode_and_option_files_are_bold_with_one_of_them():
    assert set(packaged_rule_files()) == {"conservative", "bold", *MODES, *OPTIONS}
    bold = FSMParameters.for_style(DrivingStyle.BOLD)
    for name in (*MODES, *OPTIONS):
        rules = load_rules(name)
        on = dataclasses.replace(getattr(bold, name), enabled=True)
        assert rules.params == dataclasses.replace(bold, **{name: on})
        assert rules.params.extra_modes is (name in MODES) and not bold.extra_modes


def paths(agent_name: str, seed: int, steps: int) -> list[np.ndarray]:
    env = gym.make(HIGHWAY)
    agent = make_agent(agent_name, env)
    observation, _ = env.reset(seed=seed)
    agent.reset()
    sent = []
    for _ in range(steps):
        action = agent.act(observation)
        sent.append(np.array(action))
        observation, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            break
    env.close()
    return sent


@pytest.mark.parametrize(("built_in", "from_file", "seed"), [
    ("fsm_conservative", "fsm:conservative", 3), ("fsm_bold", "fsm:bold", 4)])
def test_a_packaged_file_drives_the_built_in_styles_episode_bit_for_bit(built_in, from_file,
                                                                        seed):
    # 500 steps of 3 frames: 30 s of traffic, lane changes included.
    expected, got = paths(built_in, seed, 500), paths(from_file, seed, 500)
    assert len(expected) == len(got) == 500
    for a, b in zip(expected, got, strict=True):
        assert a.tobytes() == b.tobytes()


def write(tmp_path, text: str):
    path = tmp_path / "rules.yaml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize(("text", "message"), [
    ("style: bold\ncalm:\n  brake_range_m: -3\n",
     r"rules.yaml:3: FSM rule key 'calm.brake_range_m' must be a finite number >= 0 \(m\), "
     r"got -3"),
    ("style: bold\ncalm:\n  brake_rang_m: 30\n",
     r"rules.yaml:3: unknown FSM rule key 'calm.brake_rang_m' \(did you mean "
     r"'brake_range_m'\?\); valid keys of calm: brake_range_m, mid_range_m,"),
    ("style: reckless\n", r"rules.yaml:1: FSM rule key 'style' must be one of \['bold', "
                          r"'conservative'\], got 'reckless'"),
    ("patience_s: 3\n", r"rules.yaml:1: FSM rule key 'style' is required: one of "
                        r"\['bold', 'conservative'\]"),
    ("style: bold\n\nhyper:\n  enabled: yes please\n",
     r"rules.yaml:4: FSM rule key 'hyper.enabled' must be true or false, got 'yes please'"),
    ("style: bold\nopen_lane_m: .nan\n",
     r"rules.yaml:2: FSM rule key 'open_lane_m' must be a number \(inf allowed\) >= 0 "
     r"\(m\), got nan"),
    ("style: bold\npatience_s: .inf\n",
     r"rules.yaml:2: FSM rule key 'patience_s' must be a finite number >= 0 \(s\), got inf"),
    ("style: bold\nhard_braking_fraction: 1.5\n",
     r"rules.yaml:2: FSM rule key 'hard_braking_fraction' must be a finite number in "
     r"\[0, 1\], got 1.5"),
    ("style: bold\nalert: true\n", r"rules.yaml:2: FSM rule key 'alert' must be a mapping "
                                   r"of enabled, watch_ahead_m"),
    ("style: bold\nmax_speed_mps: 30\n", r"rules.yaml:2: FSM rules: max_speed_mps must be "
                                         r"in \(0, 22.352\] m/s"),
    ("style: bold\npatience_s: 3\npatience_s: 4\n",
     r"rules.yaml:3: the FSM rule file is refused: duplicate key 'patience_s'"),
    ("style: [bold\n", r"rules.yaml:2: the FSM rule file is not valid YAML"),
    ("- style: bold\n", r"rules.yaml:1: an FSM rule file is a mapping of keys"),
])
def test_bad_rule_files_name_the_file_line_key_value_and_choices(tmp_path, text, message):
    with pytest.raises(RuleFileError, match=message):
        load_rules(write(tmp_path, text))


def test_a_partial_file_keeps_its_styles_other_values(tmp_path):
    rules = load_rules(write(tmp_path, "style: conservative\nghosting: false\npatience_s: 5\n"
                                       "calm: {tactical_cooldown_s: 7}\n"))
    base = FSMParameters.for_style(DrivingStyle.CONSERVATIVE)
    assert rules.ghosting is False
    assert rules.params == dataclasses.replace(
        base, patience_s=5.0, calm=dataclasses.replace(base.calm, tactical_cooldown_s=7.0))


def test_rule_files_are_agents_by_name_and_checked_before_any_episode(tmp_path):
    env = gym.make(HIGHWAY)
    path = write(tmp_path, "style: bold\npatience_s: 5\n")
    agent = make_agent(f"fsm:{path}", env)
    assert agent.name == "fsm:rules" and agent.behavior.params.patience_s == 5.0
    assert make_agent("fsm_hyper", env).behavior.params.hyper.enabled
    with pytest.raises(RuleFileError, match=re.escape("no packaged FSM rule file 'bolt'; "
                                                      "packaged: alert, bold,")):
        check_agent_env("fsm:bolt", HIGHWAY)
    bad = write(tmp_path, "style: bold\npatience_s: -1\n")
    with pytest.raises(ValueError, match=r"rules\.yaml:2: FSM rule key 'patience_s'"):
        check_agent_env(f"fsm:{bad}", HIGHWAY)
    with pytest.raises(ValueError, match="drives sdc_gym/HighwayLoop-v0, not sdc_gym/Track"):
        check_agent_env("fsm:bold", "sdc_gym/TrackLoop-v0")
    env.close()
