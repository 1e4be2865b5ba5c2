"""The Gymnasium environments of sdc-gym."""

from sdc_gym.envs.highway_loop import HighwayLoopEnv

__all__ = ["HighwayLoopEnv"]
