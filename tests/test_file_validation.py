"""Map, track and light files: not text, not a sane loop, or the wrong kind of file, each a
clear error naming the file; and the original ``sim_waypoints.csv`` loaded with its speeds."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import sdc_gym  # noqa: F401
from sdc_gym.config import ConfigError
from sdc_gym.road.highway_map import MapFormatError, load_highway_map
from sdc_gym.road.track_map import TrackFormatError, load_light_config, load_track
from sdc_gym.units import KMH_TO_MPS
from tests.conftest import HIGHWAY_MAP_FILE, UDACITY

SIM_WAYPOINTS = UDACITY / "capstone" / "sim_waypoints.csv"
SIM_LIGHTS = UDACITY / "capstone" / "sim_traffic_light_config.yaml"


def highway_rows(xy: np.ndarray) -> str:
    """``x y s dx dy`` rows for points ``xy`` (s along them, (dx, dy) the right normal)."""
    step = np.diff(np.vstack([xy, xy[:1]]), axis=0)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*step.T))[:-1]])
    tangent = step / np.hypot(*step.T)[:, None]
    normal = np.column_stack([tangent[:, 1], -tangent[:, 0]])
    return "".join(f"{x:.6f} {y:.6f} {si:.6f} {dx:.6f} {dy:.6f}\n"
                   for (x, y), si, (dx, dy) in zip(xy, s, normal, strict=True))


SHIFT = np.array([0.0, 5.0])


def circle(radius: float, count: int = 64, turns: float = 1.0) -> np.ndarray:
    angle = np.linspace(0.0, 2 * math.pi * turns, count, endpoint=False)
    return radius * np.column_stack([np.cos(angle), np.sin(angle)]) + 2 * radius + 10.0


@pytest.mark.parametrize("content, fragment", [
    (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", "binary, not text (a NUL byte at offset 8)"),
    ("909.48 1128.67 0 -0.02 -0.99 # café\n".encode("latin-1"),
     ":1: the map file is not UTF-8 text (byte 0xe9 at offset 34; a latin-1"),
])
def test_binary_and_latin1_map_track_and_light_files_are_named(tmp_path, content, fragment):
    for loader, what in ((load_highway_map, "map file"),
                         (lambda path: load_track(path), "waypoint file"),
                         (load_light_config, "light config")):
        path = tmp_path / "file.txt"
        path.write_bytes(content)
        with pytest.raises(MapFormatError) as raised:
            loader(path)
        assert str(path) in str(raised.value)
        assert fragment.replace("map file", what) in str(raised.value)
    # Through an env: a ConfigError naming the key.
    path = tmp_path / "file.txt"
    with pytest.raises(ConfigError, match=r"config key 'track'.*(not UTF-8|binary)"):
        gym.make("sdc_gym/TrackLoop-v0", config={"track": str(path)})


@pytest.mark.parametrize("points, fragment", [
    (circle(500.0) * np.array([1.0, 1e-9]) + 10, "collinear"),  # a flattened circle
    (np.column_stack([np.linspace(10, 1000, 50), np.full(50, 10.0)]), "not a closed loop"),
    # An arc and the same arc back 5 m beside it: a hairpin with a cusp.
    (np.vstack([circle(300.0, 64)[:40], circle(300.0, 64)[:40][::-1] + SHIFT]),
     "not a closed loop|crosses itself|radius"),
    (circle(5.0, 16), "radius of 5 m|long; it must be in"),  # a 31 m, 5 m-radius loop
    (circle(3e11, 64), "a coordinate of"),  # a map around 1e12 m
    (circle(2e4, 256), "long; it must be in \\[200, 100000\\] m"),  # 126 km
])
def test_insane_highway_geometry_is_refused(tmp_path, points, fragment):
    # Said to be loops: with road "auto" a file whose ends do not meet is an open road
    # (tests/test_open_road.py has the open roads' refusals).
    path = tmp_path / "map.csv"
    path.write_text(highway_rows(points))
    with pytest.raises(MapFormatError, match=fragment):
        load_highway_map(path, road="loop")
    with pytest.raises(ConfigError, match=fragment):
        gym.make("sdc_gym/HighwayLoop-v0", config={"map": str(path), "road": "loop"})


def test_a_figure_eight_is_refused_as_crossing_itself(tmp_path):
    t = np.linspace(0.0, 2 * math.pi, 400, endpoint=False)
    eight = np.column_stack([1000 * np.sin(t), 500 * np.sin(2 * t)]) + 2000.0
    path = tmp_path / "eight.csv"
    path.write_text(highway_rows(eight))
    with pytest.raises(MapFormatError, match=r"the road crosses itself \(at s = "):
        load_highway_map(path)


def test_a_1m_radius_track_and_a_self_intersecting_track_are_refused(tmp_path):
    path = tmp_path / "tiny.csv"
    angle = np.linspace(0, 2 * math.pi, 40, endpoint=False)
    rows = [f"{20 + math.cos(a):.4f},{20 + math.sin(a):.4f},0,{a + math.pi / 2:.4f}"
            for a in angle]
    path.write_text("\n".join(rows) + "\n")
    with pytest.raises(TrackFormatError, match="long; it must be in \\[30, 100000\\] m"):
        load_track(path)
    rows = [f"{50 + 8 * math.cos(a):.4f},{50 + 8 * math.sin(a):.4f},0,0" for a in angle]
    path.write_text("\n".join(rows) + "\n")  # 50 m around, 8 m radius: fine
    assert load_track(path).length == pytest.approx(2 * math.pi * 8, rel=0.01)
    squeezed = [f"{50 + 30 * math.cos(a):.4f},{50 + 1.5 * math.sin(a):.4f},0,0" for a in angle]
    path.write_text("\n".join(squeezed) + "\n")  # an ellipse with 0.075 m ends
    with pytest.raises(TrackFormatError, match=r"bends with a radius of 0.0\d+ m.*smallest "
                                               r"radius allowed is 2 m"):
        load_track(path)


def test_the_highway_map_read_as_a_track_is_recognised_and_refused():
    with pytest.raises(TrackFormatError, match=r"this is a highway map \(x y s dx dy"):
        load_track(HIGHWAY_MAP_FILE)
    with pytest.raises(ConfigError, match="give it to HighwayLoop-v0's 'map' key"):
        gym.make("sdc_gym/TrackLoop-v0", config={"track": str(HIGHWAY_MAP_FILE)})


def test_a_track_file_as_the_highway_map_is_named():
    with pytest.raises(MapFormatError, match="4 fields: a track waypoint file x,y,z,yaw"):
        load_highway_map(UDACITY / "capstone" / "wp_yaw_const.csv")


def test_the_original_sim_waypoints_file_loads_with_its_speeds():
    """``sim_waypoints.csv`` is Autoware's waypoint_maker "ver1" format: a first line
    ``x,y,z`` (skipped, as Autoware's loader does), then 11,010 lines ``x,y,z,velocity``
    with the velocity in km/h (50 everywhere)."""
    track = load_track(SIM_WAYPOINTS, SIM_LIGHTS)
    assert track.waypoints.shape == (11010, 4)
    assert track.waypoints[0, :3].tolist() == [909.486, 1128.67, 0.0]  # its 2nd line
    assert track.waypoint_speeds_mps.shape == (11010,)
    assert np.all(track.waypoint_speeds_mps == 50.0 * KMH_TO_MPS)  # 13.89 m/s
    # yaw: the direction to the next point, as Autoware computes it.
    first_step = track.waypoints[1, :2] - track.waypoints[0, :2]
    assert track.waypoints[0, 3] == pytest.approx(math.atan2(first_step[1], first_step[0]))
    # The same loop as wp_yaw_const.csv (within a metre), with the same 8 stop lines.
    assert track.light_count == 8 and track.length == pytest.approx(6982.0, abs=15.0)
    env = gym.make("sdc_gym/TrackLoop-v0", config={"track": str(SIM_WAYPOINTS),
                                                   "light_config": str(SIM_LIGHTS)})
    obs, _ = env.reset(seed=0)
    for _ in range(50):
        obs, *_ = env.step(np.array([0.5, 0.0, 0.0]))
    assert obs["velocity"][0] > 0.5
    env.close()
