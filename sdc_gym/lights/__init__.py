"""Traffic lights of the track loop: state codes, phase timing, the lights' clock."""

from sdc_gym.lights.traffic_lights import (
    GREEN,
    LIGHTS_DEFAULTS,
    RED,
    UNKNOWN,
    YELLOW,
    LightState,
    LightTiming,
    TrafficLights,
)

__all__ = [
    "GREEN",
    "LIGHTS_DEFAULTS",
    "RED",
    "UNKNOWN",
    "YELLOW",
    "LightState",
    "LightTiming",
    "TrafficLights",
]
