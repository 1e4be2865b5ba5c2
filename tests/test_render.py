"""Tests of the highway renderer: frame format, geometry of the rotated view, modes."""

from __future__ import annotations

import math
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from sdc_gym.render import EGO_COLOR, PATH_COLOR, HighwayRenderer, HighwayScene
from sdc_gym.render.highway_renderer import YELLOW_LINE_COLOR
from sdc_gym.road.highway_map import HighwayMap, load_highway_map

MAP_CSV = Path(__file__).resolve().parents[2] / "shared" / "data" / "udacity" / "path_planning"
MAP_CSV = MAP_CSV / "highway_map.csv"
PPM = 5.0
PROBE_COLOR = (10, 200, 220)  # a traffic colour used nowhere else


@pytest.fixture(scope="module")
def circle_map() -> HighwayMap:
    angles = np.linspace(0.0, 2.0 * np.pi, 80, endpoint=False)
    return HighwayMap.from_waypoints("circle", 500.0 * np.column_stack([np.cos(angles),
                                                                        np.sin(angles)]))


@pytest.fixture(scope="module")
def renderer(circle_map: HighwayMap) -> Iterator[HighwayRenderer]:
    r = HighwayRenderer(circle_map, width=600, height=600, pixels_per_meter=PPM)
    yield r
    r.close()


def make_scene(
    road: HighwayMap,
    s: float = 300.0,
    cars: list[tuple[float, float]] | None = None,
    path: np.ndarray | None = None,
    status: str = "",
    speed: float = 42.0,
) -> HighwayScene:
    """Ego at (s, d = 6) heading along the road; ``cars`` are (ahead, right) offsets in
    metres in the ego frame, all heading like the ego."""
    ego = road.reference.to_xy(s, 6.0)
    heading = float(road.reference.heading(s))
    forward = np.array([math.cos(heading), math.sin(heading)])
    right = np.array([forward[1], -forward[0]])
    offsets = np.asarray(cars if cars is not None else [], dtype=np.float64).reshape(-1, 2)
    cars_xy = ego + offsets[:, :1] * forward + offsets[:, 1:] * right
    n = len(cars_xy)
    return HighwayScene(
        ego_xy=(float(ego[0]), float(ego[1])),
        ego_heading=heading,
        ego_length=4.8,
        ego_width=2.0,
        cars_xy=cars_xy,
        cars_heading=np.full(n, heading),
        cars_length=np.full(n, 4.8),
        cars_width=np.full(n, 2.0),
        cars_color=np.tile(np.array(PROBE_COLOR, dtype=np.uint8), (n, 1)),
        path_xy=np.zeros((0, 2)) if path is None else path,
        speed_mph=speed,
        time_s=12.5,
        laps=0,
        distance_m=250.0,
        incidents={"collision": 0, "speeding": 1},
        status=status,
    )


def colour_centre(frame: np.ndarray, colour: tuple[int, int, int], centre: tuple[float, float],
                  half: int = 60) -> tuple[float, float, int]:
    """Bounding-box centre (x, y) and pixel count of ``colour`` in a window around
    ``centre`` (the window keeps the mini-map, which also shows traffic, out)."""
    x0 = max(int(centre[0]) - half, 0)
    y0 = max(int(centre[1]) - half, 0)
    window = frame[y0 : int(centre[1]) + half, x0 : int(centre[0]) + half]
    ys, xs = np.nonzero(np.all(window == np.asarray(colour, dtype=np.uint8), axis=-1))
    if xs.size == 0:
        return math.nan, math.nan, 0
    return x0 + 0.5 * (xs.min() + xs.max()), y0 + 0.5 * (ys.min() + ys.max()), int(xs.size)


def test_frame_shape_dtype(renderer: HighwayRenderer, circle_map: HighwayMap) -> None:
    frame = renderer.render_rgb(make_scene(circle_map, cars=[(15.0, 0.0)]))
    assert frame.shape == (600, 600, 3)
    assert frame.dtype == np.uint8
    assert frame.flags.writeable
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 10  # a picture, not a blank


def test_non_square_frame(circle_map: HighwayMap) -> None:
    r = HighwayRenderer(circle_map, width=320, height=240, pixels_per_meter=3.0)
    frame = r.render_rgb(make_scene(circle_map))
    assert frame.shape == (240, 320, 3)
    r.close()


def test_deterministic_and_scene_dependent(renderer: HighwayRenderer,
                                           circle_map: HighwayMap) -> None:
    scene = make_scene(circle_map, cars=[(12.0, -4.0), (-20.0, 4.0)])
    first = renderer.render_rgb(scene)
    second = renderer.render_rgb(scene)
    fresh = HighwayRenderer(circle_map, pixels_per_meter=PPM).render_rgb(scene)
    np.testing.assert_array_equal(first, second)
    np.testing.assert_array_equal(first, fresh)
    assert first is not second  # a new array each call

    moved = renderer.render_rgb(make_scene(circle_map, s=900.0, cars=[(12.0, -4.0)]))
    assert not np.array_equal(first, moved)
    faster = renderer.render_rgb(
        make_scene(circle_map, cars=[(12.0, -4.0), (-20.0, 4.0)], speed=55.0)
    )
    assert not np.array_equal(first, faster)  # the text changed
    with_status = renderer.render_rgb(
        make_scene(circle_map, cars=[(12.0, -4.0), (-20.0, 4.0)], status="collision!")
    )
    assert not np.array_equal(first, with_status)


def test_ego_drawn_at_its_screen_position(renderer: HighwayRenderer,
                                          circle_map: HighwayMap) -> None:
    frame = renderer.render_rgb(make_scene(circle_map))
    ex, ey = renderer.ego_screen_xy
    assert ex == pytest.approx(300.0)
    assert 300.0 < ey < 480.0  # a bit below the middle
    assert tuple(frame[int(ey), int(ex)]) == EGO_COLOR
    x, y, count = colour_centre(frame, EGO_COLOR, (ex, ey))
    assert count > 50
    assert abs(x - ex) <= 2 and abs(y - ey) <= 2
    # The ego box is 4.8 m long and 2 m wide, drawn upright.
    ys, xs = np.nonzero(np.all(frame[int(ey) - 30 : int(ey) + 30, int(ex) - 30 : int(ex) + 30]
                               == np.asarray(EGO_COLOR, dtype=np.uint8), axis=-1))
    assert ys.max() - ys.min() > xs.max() - xs.min()


@pytest.mark.parametrize("s", [300.0, 1200.0, 2500.0])
def test_car_ahead_appears_above(renderer: HighwayRenderer, circle_map: HighwayMap,
                                 s: float) -> None:
    frame = renderer.render_rgb(make_scene(circle_map, s=s, cars=[(20.0, 0.0)]))
    ex, ey = renderer.ego_screen_xy
    expected = (ex, ey - 20.0 * PPM)
    x, y, count = colour_centre(frame, PROBE_COLOR, expected)
    assert count > 50
    assert abs(x - expected[0]) <= 2
    assert abs(y - expected[1]) <= 2


def test_car_to_the_right_appears_right(renderer: HighwayRenderer,
                                        circle_map: HighwayMap) -> None:
    frame = renderer.render_rgb(make_scene(circle_map, cars=[(0.0, 4.0)]))
    ex, ey = renderer.ego_screen_xy
    x, y, count = colour_centre(frame, PROBE_COLOR, (ex + 4.0 * PPM, ey))
    assert count > 50
    assert abs(x - (ex + 4.0 * PPM)) <= 2
    assert abs(y - ey) <= 2

    frame = renderer.render_rgb(make_scene(circle_map, cars=[(-10.0, -4.0)]))
    x, y, count = colour_centre(frame, PROBE_COLOR, (ex - 4.0 * PPM, ey + 10.0 * PPM))
    assert count > 50
    assert x < ex - 10 and y > ey + 40  # behind-left is below-left


def test_path_points_drawn(renderer: HighwayRenderer, circle_map: HighwayMap) -> None:
    scene = make_scene(circle_map)
    forward = np.array([math.cos(scene.ego_heading), math.sin(scene.ego_heading)])
    right = np.array([forward[1], -forward[0]])
    point = np.asarray(scene.ego_xy) + 10.0 * forward + 3.0 * right
    scene.path_xy = point[None, :]
    frame = renderer.render_rgb(scene)
    ex, ey = renderer.ego_screen_xy
    px, py = ex + 3.0 * PPM, ey - 10.0 * PPM
    assert tuple(frame[round(py), round(px)]) == PATH_COLOR
    x, y, count = colour_centre(frame, PATH_COLOR, (px, py), half=20)
    assert count >= 5
    assert abs(x - px) <= 1.5 and abs(y - py) <= 1.5

    scene.path_xy = np.zeros((0, 2))
    frame = renderer.render_rgb(scene)
    assert colour_centre(frame, PATH_COLOR, (px, py), half=20)[2] == 0


def test_no_traffic_and_empty_path(renderer: HighwayRenderer, circle_map: HighwayMap) -> None:
    scene = make_scene(circle_map, cars=[], path=np.zeros((0, 2)))
    scene.incidents = {}
    frame = renderer.render_rgb(scene)
    assert frame.shape == (600, 600, 3)
    assert colour_centre(frame, PROBE_COLOR, (300, 300), half=300)[2] == 0


def test_lane_lines_left_and_right(renderer: HighwayRenderer, circle_map: HighwayMap) -> None:
    """The yellow centre line (d = 0) is 6 m left of the ego in lane 1 (d = 6)."""
    frame = renderer.render_rgb(make_scene(circle_map))
    ex, ey = renderer.ego_screen_xy
    row = frame[int(ey) + 40]
    yellow = np.flatnonzero(np.all(row == np.asarray(YELLOW_LINE_COLOR, np.uint8), axis=-1))
    assert yellow.size > 0
    assert abs(yellow.mean() - (ex - 6.0 * PPM)) <= 2


def test_whole_small_loop_in_view() -> None:
    angles = np.linspace(0.0, 2.0 * np.pi, 24, endpoint=False)
    small = HighwayMap.from_waypoints("small", 25.0 * np.column_stack([np.cos(angles),
                                                                       np.sin(angles)]))
    r = HighwayRenderer(small, pixels_per_meter=4.0)
    frame = r.render_rgb(make_scene(small, s=10.0, cars=[(8.0, 0.0)]))
    assert frame.shape == (600, 600, 3)
    r.close()


def test_rgb_does_not_start_video(circle_map: HighwayMap) -> None:
    import pygame

    before = pygame.display.get_init()
    r = HighwayRenderer(circle_map)
    r.render_rgb(make_scene(circle_map))
    assert pygame.display.get_init() == before
    r.close()
    r.close()


def test_human_mode(monkeypatch: pytest.MonkeyPatch, circle_map: HighwayMap) -> None:
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    import pygame

    r = HighwayRenderer(circle_map, width=400, height=300, render_fps=100)
    r.close()  # never opened: fine
    r.render_human(make_scene(circle_map, cars=[(20.0, 0.0)]))
    assert pygame.display.get_init()
    assert pygame.display.get_surface().get_size() == (400, 300)
    r.render_human(make_scene(circle_map, s=310.0, cars=[(20.0, 0.0)], status="KEEP_LANE"))
    r.close()
    assert not pygame.display.get_init()
    r.close()
    # rgb still works after the window is gone
    assert r.render_rgb(make_scene(circle_map)).shape == (300, 400, 3)


def test_pygame_imported_lazily() -> None:
    code = (
        "import sys; import sdc_gym.render; "
        "assert 'pygame' not in sys.modules, 'pygame imported at module import'"
    )
    subprocess.run([sys.executable, "-c", code], check=True,
                   cwd=Path(__file__).resolve().parents[1])


@pytest.mark.skipif(not MAP_CSV.is_file(), reason="original highway map not available")
def test_original_map_frame() -> None:
    road = load_highway_map(MAP_CSV)
    r = HighwayRenderer(road)
    s = road.start_s
    ego = road.reference.to_xy(s, road.start_d)
    scene = make_scene(road, s=s, cars=[(20.0, 0.0)])
    assert np.allclose(scene.ego_xy, road.reference.to_xy(s, 6.0))
    assert np.hypot(*(np.asarray(scene.ego_xy) - ego)) < 1.0
    frame = r.render_rgb(scene)
    ex, ey = r.ego_screen_xy
    x, y, count = colour_centre(frame, PROBE_COLOR, (ex, ey - 20.0 * PPM))
    assert count > 50 and abs(x - ex) <= 2 and abs(y - (ey - 20.0 * PPM)) <= 2
    assert np.any(np.all(frame == np.asarray(YELLOW_LINE_COLOR, np.uint8), axis=-1))


def test_human_window_closed_by_user(monkeypatch: pytest.MonkeyPatch,
                                     circle_map: HighwayMap) -> None:
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    import pygame

    r = HighwayRenderer(circle_map, width=200, height=200, render_fps=0)
    r.render_human(make_scene(circle_map))
    pygame.event.post(pygame.event.Event(pygame.QUIT))
    r.render_human(make_scene(circle_map))
    assert r.window_closed_by_user
    assert not pygame.display.get_init()
    r.render_human(make_scene(circle_map))  # a no-op now; does not reopen the window
    assert not pygame.display.get_init()
    r.close()
