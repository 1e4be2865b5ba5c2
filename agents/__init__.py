"""Decision makers that drive the sdc-gym environments (sdc_gym never imports this package)."""

from sdc_agents.lane_keeping import LaneKeepingDriver, LaneKeepingParameters

__all__ = ["LaneKeepingDriver", "LaneKeepingParameters"]
