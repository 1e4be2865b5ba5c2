"""Each bad config of the hostile audit (issue 14), by name: it ended in a raw exception or
was accepted silently; now each is a ConfigError naming the key, the value and the valid
range (or bound). Files: see test_file_validation.py; actions: test_fuzz.py."""

from __future__ import annotations

import math

import gymnasium as gym
import pytest

import sdc_gym  # noqa: F401
from sdc_gym.config import ConfigError

HIGHWAY = "sdc_gym/HighwayLoop-v0"
TRACK = "sdc_gym/TrackLoop-v0"
HIGHWAY_BEHAVIOR = "sdc_gym/HighwayLoopBehavior-v0"
TRACK_BEHAVIOR = "sdc_gym/TrackLoopBehavior-v0"


def refused(env_id: str, config: dict, *fragments: str) -> str:
    with pytest.raises(ConfigError) as raised:
        gym.make(env_id, config=config)
    message = str(raised.value)
    for fragment in fragments:
        assert fragment in message, message
    return message


# The 17 raw exceptions (IndexError, math domain error, MemoryError, ZeroDivisionError,
# TypeError); the files' UnicodeDecodeErrors are in test_file_validation.py.
RAW_EXCEPTIONS = {
    "speed_ahead_mph [40.0] (IndexError)": (
        HIGHWAY, {"traffic": {"speed_ahead_mph": [40.0]}},
        ("'traffic.speed_ahead_mph' must be a [min, max] pair", "got [40.0]")),
    "idm.a_max -1 (math domain error)": (
        HIGHWAY, {"traffic": {"idm": {"a_max": -1}}},
        ("'traffic.idm.a_max' must be a finite number in (0, 50] (m/s^2), got -1",)),
    "start_s nan (IndexError)": (
        HIGHWAY, {"start_s": math.nan}, ("'start_s' must be None or a finite number", "nan")),
    "start_d nan": (HIGHWAY, {"start_d": math.nan}, ("'start_d'", "got nan")),
    "start_d 'x'": (HIGHWAY, {"start_d": "x"}, ("'start_d' must be None or a finite number",
                                                "got 'x'")),
    "car_count 10**6 (MemoryError)": (
        HIGHWAY, {"traffic": {"car_count": 10**6}},
        ("'traffic.car_count' must be an int in [0, 1000] (cars)", "got 1000000")),
    "path_points 10**8 (MemoryError)": (
        HIGHWAY, {"path_points": 10**8},
        ("'path_points' must be an int in [2, 10000]", "(path_points, 2) arrays")),
    "steps_per_action 10**9 (MemoryError)": (
        HIGHWAY, {"steps_per_action": 10**9},
        ("'steps_per_action' must be an int in [1, 30000]", "max_duration (600.0 s)",
         "at most 50000 frames")),
    "TrackLoopBehavior track.steps_per_action 0 (ZeroDivisionError)": (
        TRACK_BEHAVIOR, {"track": {"steps_per_action": 0}},
        ("'track.steps_per_action' must be an int in [1, 50000]", "got 0")),
    "TrackLoopBehavior track.steps_per_action '5' (TypeError)": (
        TRACK_BEHAVIOR, {"track": {"steps_per_action": "5"}},
        ("'track.steps_per_action' must be an int", "got '5'")),
}

# Values that were accepted silently.
SILENTLY_ACCEPTED = {
    "steps_per_action 10**6 (a step past 90 s)": (
        HIGHWAY, {"steps_per_action": 10**6}, ("'steps_per_action' must be an int in [1, ",)),
    "steps_per_action longer than max_duration": (
        HIGHWAY, {"steps_per_action": 600, "max_duration": 10.0},
        ("'steps_per_action' must be an int in [1, 500]",)),
    "negative ego_length": (HIGHWAY, {"ego_length": -4.7}, ("'ego_length' must be a finite "
                                                            "number in [0.5, 30] (m)",)),
    "NaN ego_length": (HIGHWAY, {"ego_length": math.nan}, ("'ego_length'", "got nan")),
    "zero ego_width": (HIGHWAY, {"ego_width": 0}, ("'ego_width' must be a finite number in "
                                                   "[0.5, 5] (m), got 0",)),
    "negative lateral_wander": (HIGHWAY, {"traffic": {"lateral_wander": -0.1}},
                                ("'traffic.lateral_wander' must be a finite number in [0, 1]",)),
    "NaN reward weight (highway)": (
        HIGHWAY, {"reward_incident": {"collision": math.nan, "acceleration": -1.0,
                                      "jerk": -1.0, "speed": -1.0, "lane": -1.0,
                                      "off_road": -1.0}},
        ("'reward_incident.collision' must be a finite number (NaN and infinity",)),
    "NaN reward weight (progress)": (HIGHWAY, {"reward_progress": math.nan},
                                     ("'reward_progress' must be a finite number",)),
    "NaN reward weight (behavior)": (HIGHWAY_BEHAVIOR, {"reward_lane_change": math.nan},
                                     ("'reward_lane_change' must be a finite number",)),
    "inf reward weight (track)": (TRACK, {"reward_progress": math.inf},
                                  ("'reward_progress' must be a finite number",)),
    "render_width -1": (HIGHWAY, {"render_width": -1},
                        ("'render_width' must be an int in [1, 8192] (px), got -1",)),
    "render_height 0 (track)": (TRACK, {"render_height": 0}, ("'render_height'",)),
    "start_d 1e6": (HIGHWAY, {"start_d": 1e6},
                    ("'start_d' must be None or a finite number in [0, 12]", "got 1000000.0")),
    "decision_frames beyond the episode": (
        HIGHWAY_BEHAVIOR, {"decision_frames": 10**6}, ("'decision_frames' must be an int in",)),
    "NaN shield parameter": (HIGHWAY_BEHAVIOR, {"shield": {"min_ahead_m": math.nan}},
                             ("'shield.min_ahead_m' must be a finite number",)),
    "NaN vehicle override (track)": (TRACK, {"vehicle_overrides": {"vehicle_mass": math.nan}},
                                     ("'vehicle_overrides.vehicle_mass' must be a finite",)),
    "track max_duration 1e300": (TRACK, {"max_duration": 1e300},
                                 ("'max_duration' must be a finite number in (0, 10000000]",)),
}


@pytest.mark.parametrize("name", list(RAW_EXCEPTIONS))
def test_each_raw_exception_of_the_audit_is_a_config_error_naming_the_key(name):
    env_id, config, fragments = RAW_EXCEPTIONS[name]
    refused(env_id, config, *fragments)


@pytest.mark.parametrize("name", list(SILENTLY_ACCEPTED))
def test_each_silently_accepted_value_of_the_audit_is_refused(name):
    env_id, config, fragments = SILENTLY_ACCEPTED[name]
    refused(env_id, config, *fragments)


def test_the_bounds_still_take_every_real_use():
    """The original's settings, the endurance runs and the external planners' 500 points
    are far inside the bounds."""
    for config in ({"steps_per_action": 1}, {"path_points": 500, "steps_per_action": 5},
                   {"laps": 70, "max_duration": 70_000.0, "traffic": {"car_count": 50}},
                   {"start_s": 1000.0, "start_d": 10.0},
                   {"traffic": {"lane_change_max_braking_imposed": math.inf}}):
        gym.make(HIGHWAY, config=config).close()
    gym.make(TRACK, config={"steps_per_action": 50, "max_duration": 1.0}).close()
    refused(TRACK, {"steps_per_action": 51, "max_duration": 1.0},
            "'steps_per_action' must be an int in [1, 50]")
