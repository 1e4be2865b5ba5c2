"""Rendering of sdc-gym environments (pygame-ce, imported lazily)."""

from sdc_gym.render.highway_renderer import (
    EGO_COLOR,
    PATH_COLOR,
    HighwayRenderer,
    HighwayScene,
)

__all__ = ["EGO_COLOR", "PATH_COLOR", "HighwayRenderer", "HighwayScene"]
