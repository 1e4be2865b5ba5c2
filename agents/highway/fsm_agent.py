"""The seed's planner wired as a layered agent: the shared perception and motion layers of
:mod:`sdc_gym.stack.highway` around the finite state machine of :mod:`sdc_agents.highway.fsm`."""

from __future__ import annotations

import gymnasium as gym

from sdc_agents.highway.fsm import DrivingStyle, FSMBehavior, FSMParameters
from sdc_gym.stack.highway.layered import LayeredHighwayAgent
from sdc_gym.stack.highway.motion import MotionParameters, SeedMotionPlanner
from sdc_gym.stack.highway.perception import Perception, PerceptionParameters


def fsm_agent(env: gym.Env, style: DrivingStyle, *, tracking: bool = False,
              name: str | None = None,
              params: FSMParameters | None = None) -> LayeredHighwayAgent:
    """The seed's planner for ``env``: ghosting for the Conservative style, Kalman
    tracking on request, the motion layer timed like the env. ``params`` replaces the
    style's constants (studies of the rules; see ``FSMParameters.for_style``)."""
    road = env.unwrapped.road
    perception = Perception(road, PerceptionParameters(
        ghosting=style is DrivingStyle.CONSERVATIVE, tracking=tracking))
    label = name or f"fsm_{style.value}{'_kf' if tracking else ''}"
    return LayeredHighwayAgent(label, road, FSMBehavior(style, params), perception,
                               SeedMotionPlanner(road, MotionParameters.for_env(env)))
