"""Top-down renderer of the highway loop, for the env's ``render()``.

The view follows the ego car and is *rotated*: the ego's heading always points up the
screen, the ego sits centred horizontally a bit below the middle (at
:attr:`HighwayRenderer.ego_screen_xy`), and a point ``a`` metres ahead / ``b`` metres to
the right of the ego is drawn ``a * pixels_per_meter`` pixels above / ``b *
pixels_per_meter`` pixels right of it. The corner mini-map and the text are north-up and
upright.

Drawn, back to front: grass, road surface, lane lines (solid yellow centre line at
``d = 0`` on the left, dashed white between lanes, solid white right edge), distance
markers every 100 m (a tick right of the road and ``"1.2 km"``), the planner's path points
(small green dots, the original's green spheres), traffic (oriented rectangles in the
colour the env chose from the vehicle type), the ego (:data:`EGO_COLOR`), a text panel
(speed, time, lap, distance, incidents by kind), an optional status line, and the mini-map
of the whole loop with ego and traffic dots.

Everything static is computed once in world coordinates in the constructor (road edges and
lane lines sampled along the reference line, dashes, marker positions and labels, the
mini-map background). A frame selects the visible samples by their distance to the ego
(vectorized), transforms only those, and draws.

pygame is imported lazily by the constructor, so importing this module (and the env) does
not import pygame. ``rgb_array`` rendering draws onto a plain ``pygame.Surface`` and only
initialises ``pygame.font``: it never starts the video subsystem, so it works with no
display and without ``SDL_VIDEODRIVER``. ``human`` rendering opens a window on the first
:meth:`HighwayRenderer.render_human` call.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.render.drawing import box_corners, circular_runs
from sdc_gym.units import METERS_PER_MILE

if TYPE_CHECKING:
    from sdc_gym.road.highway_map import HighwayMap

Color = tuple[int, int, int]

# Colours (RGB). Traffic colours come from the env; keep them distinct from these.
GRASS_COLOR: Color = (46, 82, 46)
SHOULDER_COLOR: Color = (92, 92, 88)
ROAD_COLOR: Color = (62, 62, 66)
YELLOW_LINE_COLOR: Color = (250, 200, 20)
WHITE_LINE_COLOR: Color = (235, 235, 235)
MARKER_COLOR: Color = (250, 250, 250)
EGO_COLOR: Color = (230, 40, 40)
PATH_COLOR: Color = (0, 255, 0)
OUTLINE_COLOR: Color = (15, 15, 15)
GLASS_COLOR: Color = (45, 60, 85)
TEXT_COLOR: Color = (245, 245, 245)
STATUS_COLOR: Color = (255, 210, 60)
MINIMAP_ROAD_COLOR: Color = (150, 150, 150)

MARKER_SPACING_M = 100.0
DASH_LENGTH_M = 3.0  # US lane dashes: 10 ft paint, 30 ft gap
DASH_PERIOD_M = 12.0
SHOULDER_M = 1.0
SAMPLE_STEP_M = 2.0
_TEXT_CACHE_SIZE = 256


@dataclass(eq=False)
class HighwayScene:
    """Everything one frame shows, in map coordinates (metres, radians CCW from +x).

    Attributes:
        ego_xy, ego_heading, ego_length, ego_width: the ego car's centre and box.
        cars_xy: (n, 2) traffic centres. cars_heading, cars_length, cars_width: (n,).
        cars_color: (n, 3) uint8 RGB per car, chosen by the env from the vehicle type.
        path_xy: (m, 2) remaining path points sent by the planner; may be empty.
        speed_mph, time_s, laps, distance_m: shown in the text panel.
        incidents: incident kind -> count, shown one kind per line.
        status: free text line (e.g. ``"collision!"`` or the agent mode); empty hides it.
    """

    ego_xy: tuple[float, float]
    ego_heading: float
    ego_length: float
    ego_width: float
    cars_xy: NDArray[np.float64]
    cars_heading: NDArray[np.float64]
    cars_length: NDArray[np.float64]
    cars_width: NDArray[np.float64]
    cars_color: NDArray[np.uint8]
    path_xy: NDArray[np.float64]
    speed_mph: float
    time_s: float
    laps: int
    distance_m: float
    incidents: dict[str, int] = field(default_factory=dict)
    status: str = ""


class HighwayRenderer:
    """Draws :class:`HighwayScene` frames of one :class:`HighwayMap`; see the module doc.

    Args:
        road: the highway map (its reference line is the yellow centre line).
        width, height: frame size in pixels.
        pixels_per_meter: zoom of the main view.
        render_fps: frame rate the ``human`` window is limited to (0: unlimited).
    """

    def __init__(
        self,
        road: HighwayMap,
        *,
        width: int = 600,
        height: int = 600,
        pixels_per_meter: float = 5.0,
        render_fps: int = 50,
    ) -> None:
        if width <= 0 or height <= 0:
            raise ValueError(f"frame size must be positive, got {width} x {height}")
        if pixels_per_meter <= 0:
            raise ValueError(f"pixels_per_meter must be positive, got {pixels_per_meter}")
        os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
        import pygame

        self._pg: Any = pygame
        pygame.font.init()
        self.road = road
        self.width = int(width)
        self.height = int(height)
        self.ppm = float(pixels_per_meter)
        self.render_fps = int(render_fps)
        self.ego_screen_xy: tuple[float, float] = (0.5 * self.width, 0.65 * self.height)
        # Half-diagonal of the view seen from the ego, in metres: anything further is off
        # screen. Samples up to one step (plus the shoulder) beyond it are kept.
        cx, cy = self.ego_screen_xy
        self.view_radius_m = math.hypot(max(cx, self.width - cx), max(cy, self.height - cy)) / (
            self.ppm
        )

        self._surface = pygame.Surface((self.width, self.height))
        self._window: Any = None
        self._clock: Any = None
        self.window_closed_by_user = False

        base = max(12, round(self.height / 30))
        self._font = pygame.font.Font(None, base + 4)
        self._small_font = pygame.font.Font(None, base)
        self._status_font = pygame.font.Font(None, base + 10)
        self._text_cache: dict[tuple[int, str, Color], Any] = {}
        self._panel_cache: dict[tuple[int, int], Any] = {}

        self._line_px = max(1, round(0.3 * self.ppm))
        self._precompute_road()
        self._precompute_markers()
        self._precompute_minimap()

    # ------------------------------------------------------------------ static geometry
    def _precompute_road(self) -> None:
        ref = self.road.reference
        road_width = self.road.road_width
        count = max(math.ceil(ref.length / SAMPLE_STEP_M), 16)
        s = np.linspace(0.0, ref.length, count, endpoint=False)
        self._center_xy = ref.to_xy(s, np.zeros_like(s))
        # Rows (each (count, 2)): shoulder edges, lane-surface edges (inset a little so
        # the edge lines cover them), the yellow centre line and the white right edge.
        inset = min(0.1, 0.5 / self.ppm)
        offsets = (
            -SHOULDER_M, road_width + SHOULDER_M, inset, road_width - inset, 0.0, road_width
        )
        self._edges_xy = np.stack([ref.to_xy(s, np.full_like(s, d)) for d in offsets])
        self._sample_margin_m = SAMPLE_STEP_M + road_width + SHOULDER_M

        dash_s = np.arange(0.0, ref.length - DASH_PERIOD_M + DASH_LENGTH_M, DASH_PERIOD_M)
        starts, ends = [], []
        for lane in range(1, self.road.lane_count):
            d = np.full_like(dash_s, lane * self.road.lane_width)
            starts.append(ref.to_xy(dash_s, d))
            ends.append(ref.to_xy(dash_s + DASH_LENGTH_M, d))
        self._dash_start = np.concatenate(starts) if starts else np.zeros((0, 2))
        self._dash_end = np.concatenate(ends) if ends else np.zeros((0, 2))

    def _precompute_markers(self) -> None:
        ref = self.road.reference
        marker_s = np.arange(0.0, ref.length - 0.5 * MARKER_SPACING_M, MARKER_SPACING_M)
        d0 = self.road.road_width + SHOULDER_M
        self._marker_in = ref.to_xy(marker_s, np.full_like(marker_s, d0))
        self._marker_out = ref.to_xy(marker_s, np.full_like(marker_s, d0 + 2.0))
        self._marker_label_at = ref.to_xy(marker_s, np.full_like(marker_s, d0 + 2.5))
        self._marker_labels = [
            self._small_font.render(f"{s / 1000.0:.1f} km", True, MARKER_COLOR) for s in marker_s
        ]
        # Start/finish line across the road at s = 0.
        self._start_line = ref.to_xy(np.zeros(2), np.array([0.0, self.road.road_width]))

    def _precompute_minimap(self) -> None:
        pg = self._pg
        size = max(60, round(0.27 * min(self.width, self.height)))
        pad = 6
        lo = self._center_xy.min(axis=0)
        hi = self._center_xy.max(axis=0)
        scale = (size - 2 * pad) / max(float(np.max(hi - lo)), 1e-6)
        offset = pad + 0.5 * ((size - 2 * pad) - scale * (hi - lo))
        self._mini_scale = scale
        self._mini_lo = lo
        self._mini_offset = offset
        self._mini_size = size
        self._mini_pos = (self.width - size - 8, 8)
        surface = pg.Surface((size, size), pg.SRCALPHA)
        surface.fill((0, 0, 0, 150))
        loop = self._minimap_points(self._center_xy)
        pg.draw.lines(surface, MINIMAP_ROAD_COLOR, True, loop.tolist(), 3)
        start = self._minimap_points(self._center_xy[:1])[0]
        pg.draw.circle(surface, WHITE_LINE_COLOR, start.tolist(), 3)
        pg.draw.rect(surface, (200, 200, 200), surface.get_rect(), 1)
        self._minimap = surface

    def _minimap_points(self, xy: NDArray[np.float64]) -> NDArray[np.float64]:
        """Map points to mini-map pixels (north-up), relative to the mini-map corner."""
        rel = (np.asarray(xy, dtype=np.float64) - self._mini_lo) * self._mini_scale
        rel += self._mini_offset
        rel[..., 1] = self._mini_size - rel[..., 1]
        return rel

    # ------------------------------------------------------------------ per frame
    def world_to_screen(
        self, xy: NDArray[np.float64], ego_xy: tuple[float, float], ego_heading: float
    ) -> NDArray[np.float64]:
        """Map points ``(..., 2)`` to screen pixels ``(..., 2)`` of the rotated view."""
        c, s = math.cos(ego_heading), math.sin(ego_heading)
        p = self.ppm
        # Columns: screen x = ppm * (rel . right), screen y = -ppm * (rel . forward).
        matrix = np.array([[p * s, -p * c], [-p * c, -p * s]])
        rel = np.asarray(xy, dtype=np.float64) - np.asarray(ego_xy, dtype=np.float64)
        return rel @ matrix + np.asarray(self.ego_screen_xy)

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

    def _draw(self, surface: Any, scene: HighwayScene) -> None:
        pg = self._pg
        draw = pg.draw
        ego_xy = (float(scene.ego_xy[0]), float(scene.ego_xy[1]))
        heading = float(scene.ego_heading)
        ego = np.asarray(ego_xy)
        to_screen = self.world_to_screen
        surface.fill(GRASS_COLOR)

        # Road surface and solid lines, run by run of visible centre-line samples.
        dist = np.hypot(*(self._center_xy - ego).T)
        chunks = circular_runs(dist < self.view_radius_m + self._sample_margin_m)
        chunk_pts = [to_screen(self._edges_xy[:, chunk], ego_xy, heading) for chunk in chunks]
        # Layer by layer (all shoulders, then all lanes, then lines): a later chunk's
        # shoulder must not cover the overlap it shares with the previous chunk's lanes.
        for pts in chunk_pts:
            draw.polygon(surface, SHOULDER_COLOR, np.concatenate([pts[0], pts[1][::-1]]).tolist())
        for pts in chunk_pts:
            draw.polygon(surface, ROAD_COLOR, np.concatenate([pts[2], pts[3][::-1]]).tolist())
        for pts in chunk_pts:
            draw.lines(surface, YELLOW_LINE_COLOR, False, pts[4].tolist(), self._line_px)
            draw.lines(surface, WHITE_LINE_COLOR, False, pts[5].tolist(), self._line_px)

        # Dashed lane separators.
        radius = self.view_radius_m + DASH_LENGTH_M
        if len(self._dash_start):
            near = np.hypot(*(self._dash_start - ego).T) < radius
            if near.any():
                a = to_screen(self._dash_start[near], ego_xy, heading).tolist()
                b = to_screen(self._dash_end[near], ego_xy, heading).tolist()
                for start, end in zip(a, b, strict=True):
                    draw.line(surface, WHITE_LINE_COLOR, start, end, self._line_px)

        # Start/finish line.
        start_line = to_screen(self._start_line, ego_xy, heading)
        draw.line(surface, WHITE_LINE_COLOR, *start_line.tolist(), max(2, self._line_px * 2))

        # Distance markers: tick outside the right edge, label next to it (upright).
        near = np.flatnonzero(np.hypot(*(self._marker_in - ego).T) < self.view_radius_m + 20.0)
        if near.size:
            tick_a = to_screen(self._marker_in[near], ego_xy, heading).tolist()
            tick_b = to_screen(self._marker_out[near], ego_xy, heading).tolist()
            label_at = to_screen(self._marker_label_at[near], ego_xy, heading)
            for i, index in enumerate(near.tolist()):
                draw.line(surface, MARKER_COLOR, tick_a[i], tick_b[i], 2)
                label = self._marker_labels[index]
                # Put the label on the far side of the tick's outer end.
                direction = np.subtract(tick_b[i], tick_a[i])
                norm = float(np.hypot(*direction)) or 1.0
                ux, uy = direction / norm
                lx = label_at[i, 0] + ux * 0.5 * label.get_width()
                ly = label_at[i, 1] + uy * 0.5 * label.get_height()
                surface.blit(label, label.get_rect(center=(round(lx), round(ly))))

        # Planner path points.
        path = np.asarray(scene.path_xy, dtype=np.float64).reshape(-1, 2)
        if len(path):
            pts = to_screen(path, ego_xy, heading)
            visible = (
                (pts[:, 0] > -4) & (pts[:, 0] < self.width + 4)
                & (pts[:, 1] > -4) & (pts[:, 1] < self.height + 4)
            )
            dot = max(2.0, 0.3 * self.ppm)
            for point in pts[visible].tolist():
                draw.circle(surface, PATH_COLOR, point, dot)

        # Traffic.
        cars = np.asarray(scene.cars_xy, dtype=np.float64).reshape(-1, 2)
        if len(cars):
            length = np.broadcast_to(np.asarray(scene.cars_length, dtype=np.float64), len(cars))
            width = np.broadcast_to(np.asarray(scene.cars_width, dtype=np.float64), len(cars))
            reach = 0.5 * np.hypot(length, width)
            visible = np.hypot(*(cars - ego).T) < self.view_radius_m + reach
            if visible.any():
                colors = np.asarray(scene.cars_color, dtype=np.uint8).reshape(-1, 3)[visible]
                self._draw_boxes(
                    surface,
                    cars[visible],
                    np.broadcast_to(np.asarray(scene.cars_heading, dtype=np.float64),
                                    len(cars))[visible],
                    length[visible],
                    width[visible],
                    [tuple(color) for color in colors.tolist()],
                    ego_xy,
                    heading,
                )

        # Ego.
        self._draw_boxes(
            surface,
            ego[None, :],
            np.array([heading]),
            np.array([float(scene.ego_length)]),
            np.array([float(scene.ego_width)]),
            [EGO_COLOR],
            ego_xy,
            heading,
        )

        self._draw_overlay(surface, scene)
        self._draw_minimap(surface, scene, cars)

    def _draw_boxes(
        self,
        surface: Any,
        xy: NDArray[np.float64],
        heading: NDArray[np.float64],
        length: NDArray[np.float64],
        width: NDArray[np.float64],
        colors: list[Color],
        ego_xy: tuple[float, float],
        ego_heading: float,
    ) -> None:
        """Oriented car boxes with a dark outline and a windscreen towards the front."""
        draw = self._pg.draw
        half_l = 0.5 * length
        body = box_corners(xy, heading, half_l, -half_l, 0.5 * width)
        glass = box_corners(xy, heading, 0.25 * length, 0.08 * length, 0.38 * width)
        body_px = self.world_to_screen(body, ego_xy, ego_heading).tolist()
        glass_px = self.world_to_screen(glass, ego_xy, ego_heading).tolist()
        for body_i, glass_i, color in zip(body_px, glass_px, colors, strict=True):
            draw.polygon(surface, color, body_i)
            draw.polygon(surface, OUTLINE_COLOR, body_i, 1)
            draw.polygon(surface, GLASS_COLOR, glass_i)

    def _draw_overlay(self, surface: Any, scene: HighwayScene) -> None:
        minutes, seconds = divmod(max(float(scene.time_s), 0.0), 60.0)
        lines = [
            f"Speed  {scene.speed_mph:5.1f} mph",
            f"Time   {int(minutes)}:{seconds:04.1f}",
            f"Lap    {int(scene.laps)}",
            f"Dist   {scene.distance_m / METERS_PER_MILE:.2f} mi",
        ]
        if scene.incidents:
            lines.append(f"Incidents  {sum(int(v) for v in scene.incidents.values())}")
            lines.extend(f"  {kind}: {int(count)}" for kind, count in scene.incidents.items())
        else:
            lines.append("Incidents  0")
        texts = [self._text(self._font, line) for line in lines]
        line_h = self._font.get_linesize()
        pad = 6
        panel_w = max(text.get_width() for text in texts) + 2 * pad
        panel_h = line_h * len(texts) + 2 * pad
        # Round the panel size up so a handful of cached panels serve all frames.
        panel_w = -(-panel_w // 20) * 20
        surface.blit(self._panel(panel_w, panel_h), (8, 8))
        for i, text in enumerate(texts):
            surface.blit(text, (8 + pad, 8 + pad + i * line_h))

        if scene.status:
            text = self._text(self._status_font, scene.status, STATUS_COLOR)
            w, h = text.get_width() + 16, text.get_height() + 8
            w = -(-w // 20) * 20
            x = (self.width - w) // 2
            y = self.height - h - 10
            surface.blit(self._panel(w, h), (x, y))
            surface.blit(text, text.get_rect(center=(x + w // 2, y + h // 2)))

    def _draw_minimap(self, surface: Any, scene: HighwayScene, cars: NDArray[np.float64]) -> None:
        draw = self._pg.draw
        x0, y0 = self._mini_pos
        surface.blit(self._minimap, (x0, y0))
        if len(cars):
            colors = np.asarray(scene.cars_color, dtype=np.uint8).reshape(-1, 3).tolist()
            for (px, py), color in zip(self._minimap_points(cars).tolist(), colors, strict=True):
                draw.circle(surface, color, (x0 + px, y0 + py), 2)
        ex, ey = self._minimap_points(np.asarray(scene.ego_xy, dtype=np.float64)[None])[0]
        draw.circle(surface, EGO_COLOR, (x0 + ex, y0 + ey), 4)
        draw.circle(surface, (255, 255, 255), (x0 + ex, y0 + ey), 4, 1)

    # ------------------------------------------------------------------ public API
    def render_rgb(self, scene: HighwayScene) -> NDArray[np.uint8]:
        """Draw ``scene`` off screen; returns a fresh (height, width, 3) uint8 RGB frame."""
        self._draw(self._surface, scene)
        data = bytearray(self._pg.image.tobytes(self._surface, "RGB"))
        return np.frombuffer(data, dtype=np.uint8).reshape(self.height, self.width, 3)

    def render_human(self, scene: HighwayScene) -> None:
        """Show ``scene`` in a window (opened on the first call), keep it responsive and
        hold the frame rate to ``render_fps``.

        Closing the window with its close button closes it for good: later calls return
        at once (see :attr:`window_closed_by_user`).
        """
        pg = self._pg
        if self.window_closed_by_user:
            return
        if self._window is None:
            pg.display.init()
            pg.display.set_caption("sdc-gym highway")
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
