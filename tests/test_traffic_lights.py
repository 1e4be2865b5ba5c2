"""Traffic light phases: cycle order and durations, seeded offsets, scripted lights."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sdc_gym.config import ConfigError
from sdc_gym.lights import (
    GREEN,
    LIGHTS_DEFAULTS,
    RED,
    UNKNOWN,
    YELLOW,
    LightState,
    LightTiming,
    TrafficLights,
)


def test_state_codes_are_the_originals():
    assert (RED, YELLOW, GREEN, UNKNOWN) == (0, 1, 2, 4)
    assert LightState.GREEN == 2 and LightState(4) is LightState.UNKNOWN


def test_default_timing_and_yellow_rationale():
    timing = LightTiming()
    assert (timing.green_s, timing.yellow_s, timing.red_s, timing.cycle_s) == (10, 3, 10, 23)
    # ITE kinematic yellow at 40 km/h: 1 s reaction + v / (2 * 3.05 m/s^2) = 2.82 s <= 3 s.
    v = 40 / 3.6
    kinematic_yellow_s = 1.0 + v / (2 * 3.05)
    assert kinematic_yellow_s == pytest.approx(2.82, abs=0.01)
    assert kinematic_yellow_s <= timing.yellow_s


@pytest.mark.parametrize(("time_s", "state", "to_change"), [
    (0.0, GREEN, 10.0), (9.99, GREEN, 0.01), (10.0, YELLOW, 3.0), (12.5, YELLOW, 0.5),
    (13.0, RED, 10.0), (22.9, RED, 0.1), (23.0, GREEN, 10.0), (33.5, YELLOW, 2.5),
    (46.0 + 14.0, RED, 9.0),
])
def test_cycle_green_yellow_red_known_times(time_s, state, to_change):
    lights = TrafficLights(1, offsets_s=[0.0])
    assert lights.state_at(time_s)[0] == state
    assert lights.time_to_change_at(time_s)[0] == pytest.approx(to_change)


def test_offset_is_the_phase_at_time_zero():
    # Offsets 5 s (green, 5 s left), 11 s (yellow, 2 s left), 20 s (red, 3 s left),
    # 23 + 1 s (wraps to 1 s: green, 9 s left).
    lights = TrafficLights(4, offsets_s=[5.0, 11.0, 20.0, 24.0])
    lights.reset(None)
    assert lights.states.tolist() == [GREEN, YELLOW, RED, GREEN]
    np.testing.assert_allclose(lights.time_to_change, [5.0, 2.0, 3.0, 9.0])
    np.testing.assert_allclose(lights.offsets_s, [5.0, 11.0, 20.0, 1.0])


def test_stepping_at_50_hz_changes_at_the_phase_boundaries():
    lights = TrafficLights(1, offsets_s=[0.0])
    lights.reset(None)
    dt, changes, previous = 0.02, [], int(lights.states[0])
    for _ in range(round(2 * 23.0 / dt)):
        state = int(lights.step(dt)[0])
        assert state == lights.state_at(lights.time_s)[0]
        if state != previous:
            changes.append((round(lights.time_s, 6), state))
            previous = state
    expected = [(10.0, YELLOW), (13.0, RED), (23.0, GREEN), (33.0, YELLOW), (36.0, RED),
                (46.0, GREEN)]
    assert [state for _, state in changes] == [state for _, state in expected]
    for (time_s, _), (expected_s, _) in zip(changes, expected, strict=True):
        assert expected_s <= time_s < expected_s + dt + 1e-9


def test_seeded_offsets_are_reproducible_and_cover_the_cycle():
    lights = TrafficLights(8)
    first = lights.reset(np.random.default_rng(7)).copy()
    offsets = lights.offsets_s
    lights.step(4.0)
    again = lights.reset(np.random.default_rng(7))
    np.testing.assert_array_equal(lights.offsets_s, offsets)
    np.testing.assert_array_equal(again, first)
    assert lights.time_s == 0.0
    lights.reset(np.random.default_rng(8))
    assert not np.array_equal(lights.offsets_s, offsets)
    assert np.all((offsets >= 0) & (offsets < 23.0))
    with pytest.raises(ValueError, match="needs an rng"):
        lights.reset(None)


def test_per_light_timing():
    lights = TrafficLights(2, timing=[LightTiming(5, 2, 5), LightTiming(20, 4, 6)],
                           offsets_s=[0.0, 0.0])
    assert lights.state_at(6.0).tolist() == [YELLOW, GREEN]
    assert lights.state_at(12.5).tolist() == [GREEN, GREEN]  # first wrapped at 12 s
    assert lights.state_at(25.0).tolist() == [GREEN, RED]  # 25 mod 12 = 1; 24..30 red


def test_scripted_and_constant_lights_beside_a_cycling_one():
    lights = TrafficLights(3, offsets_s=[0.0, 0.0, 0.0],
                           script=[None, [(0.0, RED), (5.0, GREEN), (7.0, GREEN), (9.0, UNKNOWN)],
                                   YELLOW])
    lights.reset(None)
    assert lights.states.tolist() == [GREEN, RED, YELLOW]
    np.testing.assert_allclose(lights.time_to_change, [10.0, 5.0, math.inf])
    assert lights.state_at(4.99).tolist() == [GREEN, RED, YELLOW]
    assert lights.state_at(5.0).tolist() == [GREEN, GREEN, YELLOW]
    # The repeated GREEN at 7 s is no change: the next change is UNKNOWN at 9 s.
    assert lights.time_to_change_at(6.0)[1] == pytest.approx(3.0)
    assert lights.state_at(100.0).tolist() == [lights.state_at(100.0)[0], UNKNOWN, YELLOW]
    assert lights.time_to_change_at(100.0)[1] == math.inf
    for _ in range(500):
        lights.step(0.02)
    assert lights.states.tolist() == [GREEN, UNKNOWN, YELLOW]  # t = 10 s (yellow at 10.0)
    lights.step(0.02)
    assert lights.states[0] == YELLOW


def test_all_scripted_lights_need_no_rng():
    lights = TrafficLights(2, script=[RED, [(0.0, GREEN), (1.0, RED)]])
    assert lights.reset(None).tolist() == [RED, GREEN]
    assert lights.step(1.0).tolist() == [RED, RED]


def test_states_are_read_only():
    lights = TrafficLights(2, offsets_s=[0.0, 1.0])
    with pytest.raises(ValueError):
        lights.states[0] = RED


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"count": 2, "offsets_s": [1.0]}, "offsets_s must be 2"),
    ({"count": 1, "script": [[(1.0, RED)]]}, "first entry must be at time 0"),
    ({"count": 1, "script": [[(0.0, RED), (0.0, GREEN)]]}, "strictly increasing"),
    ({"count": 1, "script": [3]}, "RED 0, YELLOW 1, GREEN 2, UNKNOWN 4"),
    ({"count": 1, "script": [[(0.0, RED, 1)]]}, "expected a \\(time_s, state\\) pair"),
    ({"count": 2, "script": [None]}, "one entry per light \\(2\\)"),
    ({"count": -1}, "count must be an int >= 0"),
])
def test_bad_arguments_raise_clear_errors(kwargs, message):
    with pytest.raises(ValueError, match=message):
        TrafficLights(**kwargs)


def test_bad_timing_and_dt():
    with pytest.raises(ValueError, match="yellow_s must be a finite number > 0"):
        LightTiming(yellow_s=0.0)
    with pytest.raises(ValueError, match="dt must be >= 0"):
        TrafficLights(1, offsets_s=[0.0]).step(-0.02)


def test_from_config():
    lights = TrafficLights.from_config(2, {"green_s": 4.0, "offsets_s": [0.0, 5.0]})
    assert lights.state_at(0.0).tolist() == [GREEN, YELLOW]  # 5 s: 4 green + 1 into yellow
    assert set(LIGHTS_DEFAULTS) == {"green_s", "yellow_s", "red_s", "offsets_s", "script"}
    with pytest.raises(ConfigError, match="unknown config key 'green'"):
        TrafficLights.from_config(2, {"green": 4.0})
    with pytest.raises(ConfigError, match=r"lights: LightTiming\.red_s"):
        TrafficLights.from_config(2, {"red_s": -1.0})
