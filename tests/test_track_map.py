"""Track maps: the original capstone files, light configs, lights, built-in tracks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sdc_gym.road.builtin_tracks import BUILTIN_TRACKS, get_track_map
from sdc_gym.road.highway_map import MapFormatError
from sdc_gym.road.track_map import (
    DEFAULT_FOCAL_LENGTH_X_PX,
    DEFAULT_FOCAL_LENGTH_Y_PX,
    LIGHT_CENTER_HEIGHT_M,
    LIGHT_POLE_OFFSET_M,
    SITE_LIGHT_POLE_OFFSET_M,
    TrackFormatError,
    TrackMap,
    load_light_config,
    load_track,
    load_track_waypoints,
    loop_points,
)
from tests.conftest import UDACITY

CAPSTONE = UDACITY / "capstone"
SIM_WAYPOINTS = CAPSTONE / "wp_yaw_const.csv"
SIM_LIGHTS = CAPSTONE / "sim_traffic_light_config.yaml"
SITE_WAYPOINTS = CAPSTONE / "churchlot_with_cars.csv"
SITE_LIGHTS = CAPSTONE / "site_traffic_light_config.yaml"

# spec/track_sim.md: where the simulator's 8 stop lines project along the path.
SIM_STOP_LINE_S = [247.7, 660.0, 1472.3, 1746.6, 3723.3, 4400.6, 5434.4, 6202.4]


def polyline_lengths(xy: np.ndarray) -> tuple[float, float]:
    """Open polyline length and the closing gap (last point back to the first)."""
    return float(np.hypot(*np.diff(xy, axis=0).T).sum()), float(np.hypot(*(xy[0] - xy[-1])))


@pytest.fixture(scope="module")
def sim_track() -> TrackMap:
    return load_track(SIM_WAYPOINTS, SIM_LIGHTS)


@pytest.fixture(scope="module")
def site_track() -> TrackMap:
    return load_track(SITE_WAYPOINTS, SITE_LIGHTS)


# ------------------------------------------------------------------ original data
def test_sim_waypoint_file_facts(sim_track):
    waypoints = sim_track.waypoints
    assert waypoints.shape == (10902, 4)
    assert np.all(waypoints[:, 2] == 0.0)
    open_length, gap = polyline_lengths(waypoints[:, :2])
    assert open_length == pytest.approx(6968.74, abs=0.01)
    assert gap == pytest.approx(13.25, abs=0.01)
    assert open_length + gap == pytest.approx(6981.99, abs=0.01)
    # The smooth loop is 0.12 m shorter than the polyline (it cuts the corners' chords).
    assert sim_track.length == pytest.approx(6981.87, abs=0.01)
    # Every waypoint of the file is on the smooth line, within 1.2 cm; it is built from
    # all 10,902 points (nothing to trim: the closing chord points forwards).
    assert len(sim_track.reference.waypoints) == 10902
    _, d = sim_track.reference.to_frenet(waypoints[:, :2])
    assert np.abs(d).max() < 0.015


def test_sim_yaw_column_is_the_heading(sim_track):
    """Yaw (radians, [0, 2 pi)) follows the direction to the next waypoint (< 0.04 rad)."""
    xy = sim_track.waypoints[:, :2]
    heading = np.arctan2(*np.diff(xy, axis=0).T[::-1])
    error = np.angle(np.exp(1j * (sim_track.waypoints[:-1, 3] - heading)))
    assert np.abs(error).max() < 0.04


def test_sim_stop_lines_project_onto_the_path(sim_track):
    assert sim_track.light_count == 8
    assert sim_track.stop_lines_xy[0].tolist() == [1148.56, 1184.65]  # file order kept
    assert sim_track.stop_line_s == pytest.approx(SIM_STOP_LINE_S, abs=0.5)
    assert np.all(np.abs(sim_track.stop_line_d) <= 0.44)
    assert not sim_track.is_site
    assert (sim_track.image_width, sim_track.image_height) == (800, 600)
    # The simulator's config has no focal lengths: the seed team's are the default.
    assert sim_track.focal_length_x == DEFAULT_FOCAL_LENGTH_X_PX == 2574.0
    assert sim_track.focal_length_y == DEFAULT_FOCAL_LENGTH_Y_PX == 2744.0
    assert sim_track.speed_limit_mps == pytest.approx(40 / 3.6)
    assert sim_track.start_s == 0.0


def test_lights_stand_past_their_stop_lines_over_the_lane_facing_back(sim_track):
    reference = sim_track.reference
    light_s, light_d = reference.to_frenet(sim_track.light_positions[:, :2])
    ahead = reference.s_difference(light_s, sim_track.stop_line_s)
    assert ahead == pytest.approx(np.full(8, LIGHT_POLE_OFFSET_M), abs=1e-6)
    assert light_d == pytest.approx(np.zeros(8), abs=1e-6)
    assert sim_track.light_positions[:, 2] == pytest.approx(np.full(8, LIGHT_CENTER_HEIGHT_M))
    facing = np.angle(np.exp(1j * (sim_track.light_yaw - reference.heading(light_s))))
    assert np.abs(facing) == pytest.approx(np.full(8, np.pi))
    # The first light: 24 m along an almost straight stretch from (1148.56, 1184.65).
    assert sim_track.light_positions[0, :2] == pytest.approx([1172.51, 1186.21], abs=0.01)


def test_next_stop_line_known_answers_and_wrap(sim_track):
    length, first, last = sim_track.length, sim_track.stop_line_s[0], sim_track.stop_line_s[7]
    assert sim_track.next_stop_line(0.0) == (0, pytest.approx(first))
    assert sim_track.next_stop_line(float(first)) == (0, 0.0)  # at the line: 0 m ahead
    assert sim_track.next_stop_line(1000.0) == (2, pytest.approx(1472.19 - 1000.0, abs=0.01))
    # Past the last stop line (s = 6202.12) the next is the first (s = 247.83), a wrap.
    index, ahead = sim_track.next_stop_line(6300.0)
    assert index == 0
    assert ahead == pytest.approx(6981.87 - 6300.0 + 247.83, abs=0.01)
    assert ahead == pytest.approx(length - 6300.0 + first)
    assert sim_track.next_stop_line(float(last) + 1e-6)[0] == 0
    # s outside [0, length) wraps.
    assert sim_track.next_stop_line(-10.0)[1] == pytest.approx(first + 10.0)
    assert sim_track.next_stop_line(length + 1000.0)[0] == 2
    # The vectorized form agrees.
    s = np.array([0.0, 1000.0, 6300.0, -10.0, 5434.0])
    indices, distances = sim_track.next_stop_lines(s)
    expected = [sim_track.next_stop_line(float(value)) for value in s]
    assert indices.tolist() == [index for index, _ in expected]
    assert distances == pytest.approx([distance for _, distance in expected])


def test_track_without_lights():
    track = load_track(SIM_WAYPOINTS)
    assert track.light_count == 0
    assert track.stop_line_s.shape == (0,)
    assert track.light_positions.shape == (0, 3)
    assert track.next_stop_line(100.0) == (-1, math.inf)
    indices, distances = track.next_stop_lines([1.0, 2.0])
    assert indices.tolist() == [-1, -1] and np.all(np.isinf(distances))


def test_site_churchlot_facts(site_track):
    waypoints = site_track.waypoints
    assert waypoints.shape == (61, 4)  # the fifth column is dropped
    open_length, gap = polyline_lengths(waypoints[:, :2])
    assert open_length + gap == pytest.approx(72.39, abs=0.01)
    # The recording overruns its start: the last 4 points retrace the first metres and
    # the 3.9 m "closing gap" points backwards. The loop is closed without them.
    assert gap == pytest.approx(3.90, abs=0.01)
    assert len(site_track.reference.waypoints) == 57
    assert site_track.length == pytest.approx(64.63, abs=0.01)
    assert site_track.is_site
    assert site_track.light_count == 1
    assert site_track.stop_lines_xy.tolist() == [[8.0, 16.2]]
    # The stop line is 2 m after the first waypoint, 1.5 m right of the path.
    assert site_track.stop_line_s == pytest.approx([1.98], abs=0.01)
    assert site_track.stop_line_d == pytest.approx([1.53], abs=0.01)
    assert site_track.focal_length_x == pytest.approx(1345.200806)
    assert site_track.focal_length_y == pytest.approx(1353.838257)
    assert site_track.speed_limit_mps == pytest.approx(10 / 3.6)
    light_s, _ = site_track.reference.to_frenet(site_track.light_positions[:, :2])
    assert light_s == pytest.approx(site_track.stop_line_s + SITE_LIGHT_POLE_OFFSET_M)


def test_light_configs_parse():
    sim = load_light_config(SIM_LIGHTS)
    assert sim.stop_line_positions.shape == (8, 2)
    assert (sim.image_width, sim.image_height, sim.is_site) == (800, 600, False)
    assert sim.focal_length_x is None and sim.focal_length_y is None
    site = load_light_config(SITE_LIGHTS)
    assert site.stop_line_positions.tolist() == [[8.0, 16.2]]
    assert site.is_site is True
    assert site.focal_length_x == pytest.approx(1345.200806)


# ------------------------------------------------------------------ format errors
def write(tmp_path, text: str, name: str = "track.csv"):
    path = tmp_path / name
    path.write_bytes(text.encode())
    return path


SQUARE = "0,0,0,0\n10,0,0,1.57\n10,10,0,3.14\n0,10,0,4.71\n"


def test_waypoints_tolerate_crlf_comments_and_a_fifth_column(tmp_path):
    text = ("# x,y,z,yaw,unused\r\n0,0,0,0,12\r\n10,0,0,1.57,12\r\n\r\n"
            "10,10,0,3.14,12\r\n0,10,0,4.71,12\r\n")
    waypoints = load_track_waypoints(write(tmp_path, text))
    assert waypoints.shape == (4, 4)
    assert waypoints[2].tolist() == [10.0, 10.0, 0.0, 3.14]


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        (SQUARE + "1,2,3\n", ":5: expected 4 fields 'x,y,z,yaw' (a 5th is ignored"),
        (SQUARE + "1,2,3,4,5,6\n", ":5: expected 4 fields"),
        ("0,0,0,0\n1,x,0,0\n", ":2: not a number in '1,x,0,0'"),
        ("0,0,0,0\n1,nan,0,0\n", ":2: non-finite value in '1,nan,0,0'"),
        ("0,0,0,0\n1,0,0,0\n1,1,0,0\n", "a closed track needs at least 4 waypoints, got 3"),
    ],
)
def test_malformed_waypoint_files_name_file_line_and_problem(tmp_path, text, fragment):
    path = write(tmp_path, text)
    with pytest.raises(TrackFormatError) as error:
        load_track_waypoints(path)
    assert str(path) in str(error.value)
    assert fragment in str(error.value)


def test_format_errors_are_map_format_errors(tmp_path):
    """One exception type to catch for highway and track files."""
    assert issubclass(TrackFormatError, MapFormatError)
    assert issubclass(TrackFormatError, ValueError)
    with pytest.raises(MapFormatError, match="waypoint file not found"):
        load_track(tmp_path / "missing.csv")


def test_repeated_points_are_dropped_from_the_loop(tmp_path):
    # A repeated point (car standing while recording) and a repeated closing point.
    path = write(tmp_path, SQUARE + "0,10,0,4.71\n0,0,0,0\n")
    track = load_track(path)
    assert track.waypoints.shape == (6, 4)  # the file as read
    assert track.reference.waypoints.tolist() == [[0, 0], [10, 0], [10, 10], [0, 10]]


def test_too_few_distinct_points_names_the_file(tmp_path):
    path = write(tmp_path, "0,0,0,0\n0,0,0,0\n1,0,0,0\n1,1,0,0\n")
    with pytest.raises(TrackFormatError) as error:
        load_track(path)
    assert str(path) in str(error.value)
    assert "at least 4 waypoints; got 3" in str(error.value)


def test_loop_points_drop_a_retraced_tail():
    square = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    # The recording passes its start and goes on along the first side: (1, 0.2) and
    # (3, 0.2) run backwards against the closing chord; (0, 1) still approaches the start.
    overrun = np.vstack([square, [[0.0, 1.0], [1.0, 0.2], [3.0, 0.2]]])
    assert loop_points(overrun).tolist() == [*square.tolist(), [0.0, 1.0]]
    assert loop_points(np.vstack([square, square[:1]])).tolist() == square.tolist()


LIGHTS_OK = ("camera_info:\n  image_width: 800\n  image_height: 600\n"
             "stop_line_positions:\n  - [1.0, 2.0]\n")


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("camera_info:\n  image_width: 800\n  image_height: 600\n",
         "missing key 'stop_line_positions'"),
        ("stop_line_positions: []\n", "camera_info must be a mapping"),
        ("camera_info:\n  image_width: 800\nstop_line_positions: []\n",
         "missing key 'camera_info.image_height'"),
        (LIGHTS_OK.replace("600", "'600'"),
         "camera_info.image_height must be an integer in [1, 4096] (pixels)"),
        (LIGHTS_OK + "  - [1.0, 2.0, 3.0]\n",
         "stop_line_positions[1] must be a pair [x, y] of finite numbers, got [1.0, 2.0, 3.0]"),
        (LIGHTS_OK.replace("[1.0, 2.0]", "[1.0, abc]"), "stop_line_positions[0] must be a pair"),
        (LIGHTS_OK + "is_site: 3\n", "is_site must be true or false, got 3"),
        (LIGHTS_OK.replace("  image_height", "  focal_length_x: -5\n  image_height"),
         "camera_info.focal_length_x must be a positive number"),
        ("stop_line_positions: [1, 2\n", "not valid YAML"),
        ("- 1\n- 2\n", "expected a mapping"),
    ],
)
def test_malformed_light_configs_name_file_and_key(tmp_path, text, fragment):
    path = write(tmp_path, text, "lights.yaml")
    with pytest.raises(TrackFormatError) as error:
        load_light_config(path)
    assert str(path) in str(error.value)
    assert fragment in str(error.value)


def test_track_arrays_are_read_only(sim_track):
    with pytest.raises(ValueError, match="read-only"):
        sim_track.stop_line_s[0] = 0.0
    with pytest.raises(AttributeError):
        sim_track.start_s = 5.0  # type: ignore[misc]


# ------------------------------------------------------------------ built-in tracks
def test_builtin_default_track():
    track = get_track_map("default")
    assert 6900.0 < track.length < 7100.0
    assert track.light_count == 8
    assert np.all(np.abs(track.stop_line_d) < 0.5)
    # Stop lines in driving order, spaced irregularly (580 to 1580 m apart).
    gaps = np.diff(np.append(track.stop_line_s, track.stop_line_s[0] + track.length))
    assert np.all(gaps > 500.0) and gaps.max() - gaps.min() > 500.0
    assert not track.is_site and track.speed_limit_mps == pytest.approx(40 / 3.6)
    # Counter-clockwise: positive signed area; curvature mostly left, tightest ~49 m.
    xy = track.waypoints[:, :2]
    assert np.sum(xy[:, 0] * np.roll(xy[:, 1], -1) - np.roll(xy[:, 0], -1) * xy[:, 1]) > 0
    curvature = track.reference.curvature(np.arange(0.0, track.length, 0.5))
    assert 45.0 < 1.0 / np.abs(curvature).max() < 55.0
    # Stop lines and their lights are on straights.
    assert np.abs(track.reference.curvature(track.stop_line_s)).max() < 1e-6
    assert np.abs(track.reference.curvature(track.stop_line_s + LIGHT_POLE_OFFSET_M)).max() < 1e-6


def test_builtin_waypoints_are_the_original_format():
    track = get_track_map("default")
    waypoints = track.waypoints
    assert waypoints.shape[1] == 4 and np.all(waypoints[:, 2] == 0.0)
    spacing = np.hypot(*np.diff(waypoints[:, :2], axis=0).T)
    assert spacing == pytest.approx(np.full(len(spacing), 0.64), abs=0.001)
    assert np.all((waypoints[:, 3] >= 0.0) & (waypoints[:, 3] < 2 * np.pi))
    heading = np.arctan2(*np.diff(waypoints[:, :2], axis=0).T[::-1])
    assert np.abs(np.angle(np.exp(1j * (waypoints[:-1, 3] - heading)))).max() < 0.01
    # Lifted into positive coordinates like the original.
    assert waypoints[:, :2].min() == pytest.approx(100.0, abs=0.2)


def test_builtin_next_stop_line_wraps_past_the_last():
    track = get_track_map("default")
    s = float(track.stop_line_s[-1]) + 10.0
    assert track.stop_line_s[0] == pytest.approx(230.0, abs=0.1)
    assert track.next_stop_line(s) == (0, pytest.approx(track.length - s + 230.0, abs=0.1))


def test_builtin_site_track():
    track = get_track_map("site")
    assert 70.0 < track.length < 80.0
    assert track.is_site and track.light_count == 1
    assert track.speed_limit_mps == pytest.approx(10 / 3.6)
    assert (track.focal_length_x, track.focal_length_y) == (1345.2, 1353.84)
    assert np.abs(track.stop_line_d[0]) < 0.5
    curvature = track.reference.curvature(np.arange(0.0, track.length, 0.1))
    assert 1.0 / np.abs(curvature).max() > 5.0  # above a DBW car's ~4.8 m turning radius


def test_get_track_map_names_paths_and_errors(tmp_path):
    assert BUILTIN_TRACKS == ("default", "site")
    assert get_track_map("default") is get_track_map("default")
    loaded = get_track_map(str(SITE_WAYPOINTS), str(SITE_LIGHTS))
    assert loaded.light_count == 1 and loaded.is_site
    assert get_track_map(str(SITE_WAYPOINTS), str(SITE_LIGHTS)) is loaded
    assert get_track_map(str(SITE_WAYPOINTS)).light_count == 0
    with pytest.raises(TrackFormatError, match=r"neither a built-in \(default, site\)"):
        get_track_map("defualt")
    with pytest.raises(TrackFormatError, match="has its own lights"):
        get_track_map("default", str(SIM_LIGHTS))
    with pytest.raises(TrackFormatError, match="built-in name"):
        get_track_map("")
