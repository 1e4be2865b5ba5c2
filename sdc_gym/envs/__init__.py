"""The Gymnasium environments of sdc-gym: the path-level loops and their behavior-level
variants (an RL policy in the place of the rule-based behavior layer)."""

from sdc_gym.envs.highway_behavior import HighwayLoopBehaviorEnv
from sdc_gym.envs.highway_loop import HighwayLoopEnv
from sdc_gym.envs.track_behavior import TrackLoopBehaviorEnv
from sdc_gym.envs.track_loop import TrackLoopEnv

__all__ = ["HighwayLoopBehaviorEnv", "HighwayLoopEnv", "TrackLoopBehaviorEnv", "TrackLoopEnv"]
