"""The Gymnasium environments of sdc-gym."""

from sdc_gym.envs.highway_loop import HighwayLoopEnv
from sdc_gym.envs.track_loop import TrackLoopEnv

__all__ = ["HighwayLoopEnv", "TrackLoopEnv"]
