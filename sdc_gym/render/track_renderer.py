"""Top-down renderer of the track loop, for the env's ``render()``.

The view follows the car and is *rotated* like the highway's
(:mod:`sdc_gym.render.highway_renderer`): the car's heading points up the screen, the car
sits centred horizontally a bit below the middle (:attr:`TrackRenderer.car_screen_xy`), and
a point ``a`` metres ahead / ``b`` metres to the right of the car's centre is drawn ``a *
pixels_per_meter`` pixels above / ``b * pixels_per_meter`` pixels right of it. The panel
text and the corner mini-map are upright and north-up.

Drawn, back to front: grass; the road (``road_half_width`` either side of the path, with
white edge lines and the driven path as a faint dashed line); stop lines (white bars
across the road); traffic lights (a dark housing with a lamp in the colour of its state:
red, yellow, green, grey for UNKNOWN, and a thin pole to the road side); obstacles (grey
boxes); the agent's final waypoints if it handed them over (small green dots, the
original's ``drawline``); the car (red while drive-by-wire drives, orange in manual
override); a text panel (speed, time, lap, distance, mode, the next light and its distance,
incidents); an optional status line; and the mini-map with the lights in their state.

Everything static (road samples, stop bars, mini-map background) is computed once in the
constructor; a frame selects the samples near the car (vectorized), transforms only those
and draws. The view, pygame (imported lazily, no display needed for ``rgb_array``), the
``human`` window, the text panel and the mini-map's fit come from the shared base
:class:`~sdc_gym.render.top_down.TopDownRenderer`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.lights.traffic_lights import GREEN, RED, UNKNOWN, YELLOW
from sdc_gym.render.top_down import Color, TopDownRenderer

if TYPE_CHECKING:
    from sdc_gym.road.track_map import TrackMap

GRASS_COLOR: Color = (46, 82, 46)
ROAD_COLOR: Color = (70, 70, 74)
EDGE_COLOR: Color = (235, 235, 235)
PATH_LINE_COLOR: Color = (150, 150, 150)
STOP_LINE_COLOR: Color = (250, 250, 250)
HOUSING_COLOR: Color = (20, 20, 20)
POLE_COLOR: Color = (120, 120, 120)
LIGHT_COLORS: dict[int, Color] = {RED: (255, 40, 30), YELLOW: (255, 200, 20),
                                  GREEN: (40, 230, 80), UNKNOWN: (130, 130, 130)}
CAR_DBW_COLOR: Color = (230, 40, 40)
CAR_MANUAL_COLOR: Color = (255, 150, 30)
OBSTACLE_COLOR: Color = (185, 185, 190)
PATH_COLOR: Color = (0, 255, 0)

SAMPLE_STEP_M = 2.0
DASH_LENGTH_M = 2.0
DASH_PERIOD_M = 6.0
LINE_WIDTH_M = 0.25  # edge lines and poles
PATH_DOT_M = 0.25  # radius of the waypoint dots (at least 2 px)
STOP_LINE_WIDTH_M = 0.6
LAMP_RADIUS_M = 0.8
HOUSING_HALF_SIZE_M = 1.1
POLE_OVERHANG_M = 1.0  # the pole stands this far outside the road edge
MINIMAP_LIGHT_PX = 3  # radius of a light's dot on the mini-map
_STATE_NAMES = {RED: "RED", YELLOW: "YELLOW", GREEN: "GREEN", UNKNOWN: "UNKNOWN"}


@dataclass(eq=False)
class TrackScene:
    """Everything one frame shows, in map coordinates (metres, radians CCW from +x).

    Attributes:
        car_xy, car_heading, car_length, car_width: the car body's centre and box.
        light_states: (k,) state code per light (index = stop line index).
        obstacles_xy: (n, 2) obstacle centres; obstacles_heading: (n,); obstacle_length,
            obstacle_width: their size.
        path_xy: (m, 2) points to draw (the agent's final waypoints); may be empty.
        speed_mph, time_s, laps, distance_m: shown in the text panel.
        dbw_enabled: drive-by-wire (True) or manual override (False).
        next_line, line_distance_m: the next stop line ahead (-1: none) and its distance.
        incidents: incident kind -> count (only the kinds to show).
        status: free text line (e.g. the termination reason); empty hides it.
    """

    car_xy: tuple[float, float]
    car_heading: float
    car_length: float
    car_width: float
    light_states: NDArray[np.int8]
    obstacles_xy: NDArray[np.float64]
    obstacles_heading: NDArray[np.float64]
    obstacle_length: float
    obstacle_width: float
    path_xy: NDArray[np.float64]
    speed_mph: float
    time_s: float
    laps: int
    distance_m: float
    dbw_enabled: bool = True
    next_line: int = -1
    line_distance_m: float = 0.0
    incidents: dict[str, int] = field(default_factory=dict)
    status: str = ""


class TrackRenderer(TopDownRenderer):
    """Draws :class:`TrackScene` frames of one :class:`TrackMap`; see the module doc.

    Args:
        track: the track (its path, stop lines and lights).
        road_half_width: m of road either side of the path.
        width, height: frame size in pixels.
        pixels_per_meter: zoom of the main view.
        render_fps: frame rate the ``human`` window is limited to (0: unlimited).
    """

    def __init__(
        self,
        track: TrackMap,
        *,
        road_half_width: float,
        width: int = 600,
        height: int = 600,
        pixels_per_meter: float = 5.0,
        render_fps: int = 50,
    ) -> None:
        if road_half_width <= 0:
            raise ValueError(f"road_half_width must be positive, got {road_half_width}")
        super().__init__(width=width, height=height, pixels_per_meter=pixels_per_meter,
                         render_fps=render_fps, caption="sdc-gym track")
        self.track = track
        self.road_half_width = float(road_half_width)
        self._line_px = max(1, round(LINE_WIDTH_M * self.ppm))
        self._precompute_road()
        self._precompute_lights()
        self._precompute_minimap(self._center_xy)
        self._mini_lights = self._minimap_points(self._lights_xy).tolist()

    # ------------------------------------------------------------------ static geometry
    def _precompute_road(self) -> None:
        ref = self.track.reference
        half = self.road_half_width
        count = max(math.ceil(ref.length / SAMPLE_STEP_M), 16)
        s = np.linspace(0.0, ref.length, count, endpoint=False)
        zeros = np.zeros_like(s)
        self._center_xy = ref.to_xy(s, zeros)
        self._edges_xy = np.stack([ref.to_xy(s, zeros - half), ref.to_xy(s, zeros + half)])
        self._sample_margin_m = SAMPLE_STEP_M + half
        dash_s = np.arange(0.0, ref.length - DASH_PERIOD_M + DASH_LENGTH_M, DASH_PERIOD_M)
        self._dash_start = ref.to_xy(dash_s, np.zeros_like(dash_s)).reshape(-1, 2)
        self._dash_end = ref.to_xy(dash_s + DASH_LENGTH_M, np.zeros_like(dash_s)).reshape(-1, 2)

    def _precompute_lights(self) -> None:
        track = self.track
        half = self.road_half_width
        stop_s = np.asarray(track.stop_line_s, dtype=np.float64)
        k = len(stop_s)
        ref = track.reference
        self._stop_a = ref.to_xy(stop_s, np.full(k, -half)).reshape(-1, 2)
        self._stop_b = ref.to_xy(stop_s, np.full(k, half)).reshape(-1, 2)
        self._lights_xy = np.asarray(track.light_positions, dtype=np.float64)[:, :2].reshape(-1, 2)
        if k:
            light_s, _ = ref.to_frenet(self._lights_xy)
            light_s = np.atleast_1d(light_s)
        else:
            light_s = np.zeros(0)
        self._poles_xy = ref.to_xy(light_s, np.full(k, half + POLE_OVERHANG_M)).reshape(-1, 2)

    # ------------------------------------------------------------------ per frame
    def _draw(self, surface: Any, scene: TrackScene) -> None:
        draw = self._pg.draw
        car_xy = (float(scene.car_xy[0]), float(scene.car_xy[1]))
        heading = float(scene.car_heading)
        centre = np.asarray(car_xy)
        to_screen = self.world_to_screen
        surface.fill(GRASS_COLOR)

        # Road surface and edge lines, run by run of visible path samples.
        chunk_pts = self._visible_chunks(self._center_xy, self._edges_xy,
                                         self._sample_margin_m, car_xy, heading)
        self._fill_bands(surface, chunk_pts, 0, 1, ROAD_COLOR)
        self._stroke_rows(surface, chunk_pts, [(0, EDGE_COLOR), (1, EDGE_COLOR)])
        self._draw_segments(surface, self._dash_start, self._dash_end, DASH_LENGTH_M,
                            PATH_LINE_COLOR, 1, car_xy, heading)

        # Stop lines, then the lights with their poles.
        states = np.asarray(scene.light_states).reshape(-1).tolist()
        stop_width = max(2, round(STOP_LINE_WIDTH_M * self.ppm))
        self._draw_segments(surface, self._stop_a, self._stop_b, self.road_half_width,
                            STOP_LINE_COLOR, stop_width, car_xy, heading)
        near = self._near(self._lights_xy, centre, HOUSING_HALF_SIZE_M)
        if near.size:
            lights = to_screen(self._lights_xy[near], car_xy, heading).tolist()
            poles = to_screen(self._poles_xy[near], car_xy, heading).tolist()
            housing = max(3, round(HOUSING_HALF_SIZE_M * self.ppm))
            lamp = max(2, round(LAMP_RADIUS_M * self.ppm))
            for index, light, pole in zip(near.tolist(), lights, poles, strict=True):
                draw.line(surface, POLE_COLOR, light, pole, max(1, self._line_px))
                rect = self._pg.Rect(0, 0, 2 * housing, 2 * housing)
                rect.center = (round(light[0]), round(light[1]))
                draw.rect(surface, HOUSING_COLOR, rect)
                color = LIGHT_COLORS.get(int(states[index]), LIGHT_COLORS[UNKNOWN])
                draw.circle(surface, color, light, lamp)

        # Obstacles.
        obstacles = np.asarray(scene.obstacles_xy, dtype=np.float64).reshape(-1, 2)
        reach = 0.5 * math.hypot(scene.obstacle_length, scene.obstacle_width)
        near = self._near(obstacles, centre, reach)
        if near.size:
            headings = np.asarray(scene.obstacles_heading, dtype=np.float64).reshape(-1)[near]
            n = near.size
            self._draw_boxes(surface, obstacles[near], headings,
                             np.full(n, float(scene.obstacle_length)),
                             np.full(n, float(scene.obstacle_width)), [OBSTACLE_COLOR] * n,
                             car_xy, heading, glass=False)

        # The agent's final waypoints, then the car.
        self._draw_path_dots(surface, scene.path_xy, car_xy, heading, PATH_COLOR,
                             max(2.0, PATH_DOT_M * self.ppm))
        color = CAR_DBW_COLOR if scene.dbw_enabled else CAR_MANUAL_COLOR
        self._draw_boxes(surface, centre[None, :], np.array([heading]),
                         np.array([float(scene.car_length)]),
                         np.array([float(scene.car_width)]), [color], car_xy, heading,
                         glass=True)
        self._draw_overlay(surface, scene, states)
        self._draw_minimap(surface, scene, states)

    def _draw_overlay(self, surface: Any, scene: TrackScene, states: list[int]) -> None:
        lines = [
            *self._clock_lines(scene.speed_mph, scene.time_s, scene.laps),
            f"Dist   {scene.distance_m / 1000.0:.2f} km",
            f"Mode   {'DBW' if scene.dbw_enabled else 'MANUAL'}",
        ]
        if scene.next_line >= 0:
            state = _STATE_NAMES.get(int(states[scene.next_line]), "UNKNOWN")
            lines.append(f"Light {scene.next_line}  {state} in {scene.line_distance_m:.0f} m")
        total = sum(int(count) for count in scene.incidents.values())
        lines.append(f"Incidents  {total}")
        lines.extend(f"  {kind}: {int(count)}" for kind, count in scene.incidents.items())
        self._draw_text_panel(surface, lines)
        self._draw_status(surface, scene.status)

    def _draw_minimap(self, surface: Any, scene: TrackScene, states: list[int]) -> None:
        draw = self._pg.draw
        x0, y0 = self._mini_pos
        surface.blit(self._minimap, (x0, y0))
        for (px, py), state in zip(self._mini_lights, states, strict=True):
            draw.circle(surface, LIGHT_COLORS.get(int(state), LIGHT_COLORS[UNKNOWN]),
                        (x0 + px, y0 + py), MINIMAP_LIGHT_PX)
        color = CAR_DBW_COLOR if scene.dbw_enabled else CAR_MANUAL_COLOR
        self._draw_minimap_car(surface, scene.car_xy, color)
