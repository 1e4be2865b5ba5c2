"""The seed's planner wired as a layered agent: the shared perception and motion layers of
:mod:`sdc_gym.stack.highway` around the finite state machine of :mod:`sdc_agents.highway.fsm`."""

from __future__ import annotations

import os
from pathlib import Path

import gymnasium as gym

from sdc_agents.highway.fsm import DrivingStyle, FSMBehavior, FSMParameters
from sdc_agents.highway.fsm_rules import load_rules
from sdc_gym.stack.highway.layered import LayeredHighwayAgent
from sdc_gym.stack.highway.motion import MotionParameters, SeedMotionPlanner
from sdc_gym.stack.highway.perception import Perception, PerceptionParameters


def fsm_agent(env: gym.Env, style: DrivingStyle, *, tracking: bool = False,
              name: str | None = None,
              params: FSMParameters | None = None,
              ghosting: bool | None = None) -> LayeredHighwayAgent:
    """The seed's planner for ``env``: ghosting for the Conservative style (unless
    ``ghosting`` says otherwise), Kalman tracking on request, the motion layer timed like
    the env. ``params`` replaces the style's constants (studies of the rules, rule files;
    see ``FSMParameters.for_style``)."""
    road = env.unwrapped.road
    if ghosting is None:
        ghosting = style is DrivingStyle.CONSERVATIVE
    perception = Perception(road, PerceptionParameters(ghosting=ghosting, tracking=tracking))
    label = name or f"fsm_{style.value}{'_kf' if tracking else ''}"
    return LayeredHighwayAgent(label, road, FSMBehavior(style, params), perception,
                               SeedMotionPlanner(road, MotionParameters.for_env(env)))


def fsm_rules_agent(env: gym.Env, rule_file: str | os.PathLike[str], *,
                    tracking: bool = False, name: str | None = None) -> LayeredHighwayAgent:
    """The planner with the rules of a YAML rule file (a path, or the name of a packaged
    one: ``"bold"``, ``"alert"``; :mod:`sdc_agents.highway.fsm_rules`), named
    ``fsm:<file stem>`` unless ``name`` is given."""
    rules = load_rules(rule_file)
    label = name or f"fsm:{Path(rules.source).stem}"
    return fsm_agent(env, rules.style, tracking=tracking, name=label, params=rules.params,
                     ghosting=rules.ghosting)
