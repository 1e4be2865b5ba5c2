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
and draws. pygame (pygame-ce) is imported lazily by the constructor: ``rgb_array`` draws
onto a plain ``pygame.Surface`` and only initialises ``pygame.font`` (no display needed);
``human`` opens a window on the first :meth:`TrackRenderer.render_human`.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.lights.traffic_lights import GREEN, RED, UNKNOWN, YELLOW
from sdc_gym.render.drawing import box_corners, circular_runs

if TYPE_CHECKING:
    from sdc_gym.road.track_map import TrackMap

Color = tuple[int, int, int]

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
OUTLINE_COLOR: Color = (15, 15, 15)
GLASS_COLOR: Color = (45, 60, 85)
TEXT_COLOR: Color = (245, 245, 245)
STATUS_COLOR: Color = (255, 210, 60)
MINIMAP_ROAD_COLOR: Color = (150, 150, 150)

SAMPLE_STEP_M = 2.0
DASH_LENGTH_M = 2.0
DASH_PERIOD_M = 6.0
STOP_LINE_WIDTH_M = 0.6
LAMP_RADIUS_M = 0.8
HOUSING_HALF_SIZE_M = 1.1
POLE_OVERHANG_M = 1.0  # the pole stands this far outside the road edge
_TEXT_CACHE_SIZE = 256
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


class TrackRenderer:
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
        if width <= 0 or height <= 0:
            raise ValueError(f"frame size must be positive, got {width} x {height}")
        if pixels_per_meter <= 0:
            raise ValueError(f"pixels_per_meter must be positive, got {pixels_per_meter}")
        if road_half_width <= 0:
            raise ValueError(f"road_half_width must be positive, got {road_half_width}")
        os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
        import pygame

        self._pg: Any = pygame
        pygame.font.init()
        self.track = track
        self.road_half_width = float(road_half_width)
        self.width = int(width)
        self.height = int(height)
        self.ppm = float(pixels_per_meter)
        self.render_fps = int(render_fps)
        self.car_screen_xy: tuple[float, float] = (0.5 * self.width, 0.65 * self.height)
        cx, cy = self.car_screen_xy
        # Half-diagonal of the view seen from the car, m: anything further is off screen.
        self.view_radius_m = math.hypot(max(cx, self.width - cx),
                                        max(cy, self.height - cy)) / self.ppm
        self._surface = pygame.Surface((self.width, self.height))
        self._window: Any = None
        self._clock: Any = None
        self.window_closed_by_user = False
        base = max(12, round(self.height / 30))
        self._font = pygame.font.Font(None, base + 4)
        self._status_font = pygame.font.Font(None, base + 10)
        self._text_cache: dict[tuple[int, str, Color], Any] = {}
        self._panel_cache: dict[tuple[int, int], Any] = {}
        self._line_px = max(1, round(0.25 * self.ppm))
        self._precompute_road()
        self._precompute_lights()
        self._precompute_minimap()

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

    def _precompute_minimap(self) -> None:
        pg = self._pg
        size = max(60, round(0.27 * min(self.width, self.height)))
        pad = 6
        lo = self._center_xy.min(axis=0)
        hi = self._center_xy.max(axis=0)
        scale = (size - 2 * pad) / max(float(np.max(hi - lo)), 1e-6)
        self._mini_scale = scale
        self._mini_lo = lo
        self._mini_offset = pad + 0.5 * ((size - 2 * pad) - scale * (hi - lo))
        self._mini_size = size
        self._mini_pos = (self.width - size - 8, 8)
        surface = pg.Surface((size, size), pg.SRCALPHA)
        surface.fill((0, 0, 0, 150))
        pg.draw.lines(surface, MINIMAP_ROAD_COLOR, True,
                      self._minimap_points(self._center_xy).tolist(), 3)
        pg.draw.rect(surface, (200, 200, 200), surface.get_rect(), 1)
        self._minimap = surface
        self._mini_lights = self._minimap_points(self._lights_xy).tolist()

    def _minimap_points(self, xy: NDArray[np.float64]) -> NDArray[np.float64]:
        """Map points to mini-map pixels (north-up), relative to the mini-map corner."""
        rel = (np.asarray(xy, dtype=np.float64).reshape(-1, 2) - self._mini_lo) * self._mini_scale
        rel += self._mini_offset
        rel[:, 1] = self._mini_size - rel[:, 1]
        return rel

    # ------------------------------------------------------------------ per frame
    def world_to_screen(self, xy: NDArray[np.float64], car_xy: tuple[float, float],
                        car_heading: float) -> NDArray[np.float64]:
        """Map points ``(..., 2)`` to screen pixels ``(..., 2)`` of the rotated view."""
        c, s = math.cos(car_heading), math.sin(car_heading)
        p = self.ppm
        matrix = np.array([[p * s, -p * c], [-p * c, -p * s]])
        rel = np.asarray(xy, dtype=np.float64) - np.asarray(car_xy, dtype=np.float64)
        return rel @ matrix + np.asarray(self.car_screen_xy)

    def _text(self, font: Any, text: str, color: Color = TEXT_COLOR) -> Any:
        key = (id(font), text, color)
        surface = self._text_cache.get(key)
        if surface is None:
            if len(self._text_cache) >= _TEXT_CACHE_SIZE:
                self._text_cache.clear()
            surface = font.render(text, True, color)
            self._text_cache[key] = surface
        return surface

    def _panel(self, width: int, height: int) -> Any:
        key = (width, height)
        panel = self._panel_cache.get(key)
        if panel is None:
            panel = self._pg.Surface((width, height))
            panel.fill((0, 0, 0))
            panel.set_alpha(150)
            self._panel_cache[key] = panel
        return panel

    def _near(self, points: NDArray[np.float64], centre: NDArray[np.float64],
              margin: float) -> NDArray[np.intp]:
        if not len(points):
            return np.zeros(0, dtype=np.intp)
        return np.flatnonzero(np.hypot(*(points - centre).T) < self.view_radius_m + margin)

    def _draw(self, surface: Any, scene: TrackScene) -> None:
        draw = self._pg.draw
        car_xy = (float(scene.car_xy[0]), float(scene.car_xy[1]))
        heading = float(scene.car_heading)
        centre = np.asarray(car_xy)
        to_screen = self.world_to_screen
        surface.fill(GRASS_COLOR)

        # Road surface and edge lines, run by run of visible path samples.
        dist = np.hypot(*(self._center_xy - centre).T)
        chunks = circular_runs(dist < self.view_radius_m + self._sample_margin_m)
        chunk_pts = [to_screen(self._edges_xy[:, chunk], car_xy, heading) for chunk in chunks]
        for pts in chunk_pts:
            draw.polygon(surface, ROAD_COLOR, np.concatenate([pts[0], pts[1][::-1]]).tolist())
        for pts in chunk_pts:
            draw.lines(surface, EDGE_COLOR, False, pts[0].tolist(), self._line_px)
            draw.lines(surface, EDGE_COLOR, False, pts[1].tolist(), self._line_px)
        near = self._near(self._dash_start, centre, DASH_LENGTH_M)
        if near.size:
            a = to_screen(self._dash_start[near], car_xy, heading).tolist()
            b = to_screen(self._dash_end[near], car_xy, heading).tolist()
            for start, end in zip(a, b, strict=True):
                draw.line(surface, PATH_LINE_COLOR, start, end, 1)

        # Stop lines, then the lights with their poles.
        states = np.asarray(scene.light_states).reshape(-1).tolist()
        stop_width = max(2, round(STOP_LINE_WIDTH_M * self.ppm))
        near = self._near(self._stop_a, centre, self.road_half_width)
        if near.size:
            a = to_screen(self._stop_a[near], car_xy, heading).tolist()
            b = to_screen(self._stop_b[near], car_xy, heading).tolist()
            for start, end in zip(a, b, strict=True):
                draw.line(surface, STOP_LINE_COLOR, start, end, stop_width)
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
            self._draw_boxes(surface, obstacles[near], headings, scene.obstacle_length,
                             scene.obstacle_width, OBSTACLE_COLOR, car_xy, heading,
                             glass=False)

        # The agent's final waypoints.
        path = np.asarray(scene.path_xy, dtype=np.float64).reshape(-1, 2)
        if len(path):
            pts = to_screen(path, car_xy, heading)
            visible = ((pts[:, 0] > -4) & (pts[:, 0] < self.width + 4)
                       & (pts[:, 1] > -4) & (pts[:, 1] < self.height + 4))
            dot = max(2.0, 0.25 * self.ppm)
            for point in pts[visible].tolist():
                draw.circle(surface, PATH_COLOR, point, dot)

        # The car.
        color = CAR_DBW_COLOR if scene.dbw_enabled else CAR_MANUAL_COLOR
        self._draw_boxes(surface, centre[None, :], np.array([heading]), scene.car_length,
                         scene.car_width, color, car_xy, heading, glass=True)
        self._draw_overlay(surface, scene, states)
        self._draw_minimap(surface, scene, states)

    def _draw_boxes(self, surface: Any, xy: NDArray[np.float64], heading: NDArray[np.float64],
                    length: float, width: float, color: Color, car_xy: tuple[float, float],
                    car_heading: float, *, glass: bool) -> None:
        """Oriented boxes with a dark outline (and a windscreen towards the front)."""
        draw = self._pg.draw
        n = len(xy)
        half_l = np.full(n, 0.5 * length)
        half_w = np.full(n, 0.5 * width)
        body = self.world_to_screen(box_corners(xy, heading, half_l, -half_l, half_w),
                                    car_xy, car_heading).tolist()
        for corners in body:
            draw.polygon(surface, color, corners)
            draw.polygon(surface, OUTLINE_COLOR, corners, 1)
        if glass:
            windows = box_corners(xy, heading, 0.25 * length + np.zeros(n),
                                  0.08 * length + np.zeros(n), 0.38 * width + np.zeros(n))
            for corners in self.world_to_screen(windows, car_xy, car_heading).tolist():
                draw.polygon(surface, GLASS_COLOR, corners)

    def _draw_overlay(self, surface: Any, scene: TrackScene, states: list[int]) -> None:
        minutes, seconds = divmod(max(float(scene.time_s), 0.0), 60.0)
        lines = [
            f"Speed  {scene.speed_mph:5.1f} mph",
            f"Time   {int(minutes)}:{seconds:04.1f}",
            f"Lap    {int(scene.laps)}",
            f"Dist   {scene.distance_m / 1000.0:.2f} km",
            f"Mode   {'DBW' if scene.dbw_enabled else 'MANUAL'}",
        ]
        if scene.next_line >= 0:
            state = _STATE_NAMES.get(int(states[scene.next_line]), "UNKNOWN")
            lines.append(f"Light {scene.next_line}  {state} in {scene.line_distance_m:.0f} m")
        total = sum(int(count) for count in scene.incidents.values())
        lines.append(f"Incidents  {total}")
        lines.extend(f"  {kind}: {int(count)}" for kind, count in scene.incidents.items())
        texts = [self._text(self._font, line) for line in lines]
        line_h = self._font.get_linesize()
        pad = 6
        panel_w = -(-(max(text.get_width() for text in texts) + 2 * pad) // 20) * 20
        panel_h = line_h * len(texts) + 2 * pad
        surface.blit(self._panel(panel_w, panel_h), (8, 8))
        for i, text in enumerate(texts):
            surface.blit(text, (8 + pad, 8 + pad + i * line_h))
        if scene.status:
            text = self._text(self._status_font, scene.status, STATUS_COLOR)
            w = -(-(text.get_width() + 16) // 20) * 20
            h = text.get_height() + 8
            x, y = (self.width - w) // 2, self.height - h - 10
            surface.blit(self._panel(w, h), (x, y))
            surface.blit(text, text.get_rect(center=(x + w // 2, y + h // 2)))

    def _draw_minimap(self, surface: Any, scene: TrackScene, states: list[int]) -> None:
        draw = self._pg.draw
        x0, y0 = self._mini_pos
        surface.blit(self._minimap, (x0, y0))
        for (px, py), state in zip(self._mini_lights, states, strict=True):
            draw.circle(surface, LIGHT_COLORS.get(int(state), LIGHT_COLORS[UNKNOWN]),
                        (x0 + px, y0 + py), 3)
        cx, cy = self._minimap_points(np.asarray(scene.car_xy, dtype=np.float64))[0]
        color = CAR_DBW_COLOR if scene.dbw_enabled else CAR_MANUAL_COLOR
        draw.circle(surface, color, (x0 + cx, y0 + cy), 4)
        draw.circle(surface, (255, 255, 255), (x0 + cx, y0 + cy), 4, 1)

    # ------------------------------------------------------------------ public API
    def render_rgb(self, scene: TrackScene) -> NDArray[np.uint8]:
        """Draw ``scene`` off screen; returns a fresh (height, width, 3) uint8 RGB frame."""
        self._draw(self._surface, scene)
        data = bytearray(self._pg.image.tobytes(self._surface, "RGB"))
        return np.frombuffer(data, dtype=np.uint8).reshape(self.height, self.width, 3)

    def render_human(self, scene: TrackScene) -> None:
        """Show ``scene`` in a window (opened on the first call) at ``render_fps``; closing
        the window with its close button closes it for good (later calls return at once)."""
        pg = self._pg
        if self.window_closed_by_user:
            return
        if self._window is None:
            pg.display.init()
            pg.display.set_caption("sdc-gym track")
            self._window = pg.display.set_mode((self.width, self.height))
            self._clock = pg.time.Clock()
        for event in pg.event.get():
            if event.type == pg.QUIT:
                self.window_closed_by_user = True
                self.close()
                return
        self._draw(self._window, scene)
        pg.display.flip()
        self._clock.tick(self.render_fps)

    def close(self) -> None:
        """Close the window if one is open; safe to call repeatedly or if never opened."""
        if self._window is not None:
            self._window = None
            self._clock = None
            self._pg.display.quit()
