"""Top-down renderer of the highway loop, for the env's ``render()``.

The view follows the ego car and is *rotated*: the ego's heading always points up the
screen, the ego sits centred horizontally a bit below the middle (at
:attr:`HighwayRenderer.ego_screen_xy`), and a point ``a`` metres ahead / ``b`` metres to
the right of the ego is drawn ``a * pixels_per_meter`` pixels above / ``b *
pixels_per_meter`` pixels right of it. The corner mini-map and the text are north-up and
upright.

Drawn, back to front: grass, road surface, lane lines (solid yellow centre line at
``d = 0`` on the left, dashed white between lanes, solid white right edge), distance
markers every 100 m (a tick right of the road and ``"1.2 km"``), closed lanes (a
construction zone: the lane's surface in :data:`ZONE_COLOR` with a row of cones along its
edges and across its start), the planner's path points (small green dots, the original's
green spheres), traffic and road objects (oriented rectangles in the colour the env chose
from their kind: barriers orange, cargo brown, animals tan), the ego (:data:`EGO_COLOR`), a
text panel
(speed, time, lap, distance, incidents by kind), an optional status line, and the mini-map
of the whole loop with ego and traffic dots.

Everything static is computed once in world coordinates in the constructor (road edges and
lane lines sampled along the reference line, dashes, marker positions and labels, the
mini-map background). A frame selects the visible samples by their distance to the ego
(vectorized), transforms only those, and draws.

pygame is imported lazily by the constructor, so importing this module (and the env) does
not import pygame. The view, pygame, the ``human`` window, the text panel and the mini-map's
fit come from the shared base :class:`~sdc_gym.render.top_down.TopDownRenderer`:
``rgb_array`` rendering never starts the video subsystem (no display needed), ``human``
rendering opens a window on the first :meth:`HighwayRenderer.render_human` call.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.render.top_down import Color, TopDownRenderer
from sdc_gym.units import METERS_PER_MILE

if TYPE_CHECKING:
    from sdc_gym.road.highway_map import HighwayMap

# Colours (RGB). Traffic colours come from the env; keep them distinct from these.
GRASS_COLOR: Color = (46, 82, 46)
SHOULDER_COLOR: Color = (92, 92, 88)
ROAD_COLOR: Color = (62, 62, 66)
YELLOW_LINE_COLOR: Color = (250, 200, 20)
WHITE_LINE_COLOR: Color = (235, 235, 235)
MARKER_COLOR: Color = (250, 250, 250)
EGO_COLOR: Color = (230, 40, 40)
PATH_COLOR: Color = (0, 255, 0)
ZONE_COLOR: Color = (112, 86, 52)  # a closed lane's surface
CONE_COLOR: Color = (255, 140, 0)
CONE_SPACING_M = 4.0
CONE_RADIUS_M = 0.35

MARKER_SPACING_M = 100.0
DASH_LENGTH_M = 3.0  # US lane dashes: 10 ft paint, 30 ft gap
DASH_PERIOD_M = 12.0
SHOULDER_M = 1.0
SAMPLE_STEP_M = 2.0
LINE_WIDTH_M = 0.3  # lane lines
PATH_DOT_M = 0.3  # radius of the path dots (at least 2 px)
MARKER_REACH_M = 20.0  # markers this far beyond the view radius are drawn (label width)
MINIMAP_CAR_PX = 2  # radius of a traffic car's dot on the mini-map
MINIMAP_START_PX = 3  # radius of the start/finish dot on the mini-map


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
        closed_lanes: ``(s_start, s_end, lane)`` of each closed lane (construction zone).
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
    closed_lanes: list[tuple[float, float, int]] = field(default_factory=list)


class HighwayRenderer(TopDownRenderer):
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
        super().__init__(width=width, height=height, pixels_per_meter=pixels_per_meter,
                         render_fps=render_fps, caption="sdc-gym highway")
        self.road = road
        self.ego_screen_xy = self.car_screen_xy  # the ego is this renderer's car
        self._small_font = self._pg.font.Font(None, self._font_base)
        self._line_px = max(1, round(LINE_WIDTH_M * self.ppm))
        self._precompute_road()
        self._precompute_markers()
        self._precompute_minimap(self._center_xy)

    # ------------------------------------------------------------------ static geometry
    def _precompute_road(self) -> None:
        ref = self.road.reference
        road_width = self.road.road_width
        # A loop's samples go once around; an open road's from its start to its end.
        self.road_closed = self.road.closed
        count = max(math.ceil(ref.end_s / SAMPLE_STEP_M), 16)
        s = np.linspace(0.0, ref.end_s, count + (0 if ref.closed else 1),
                        endpoint=not ref.closed)
        self._center_xy = ref.to_xy(s, np.zeros_like(s))
        # Rows (each (count, 2)): shoulder edges, lane-surface edges (inset a little so
        # the edge lines cover them), the yellow centre line and the white right edge.
        inset = min(0.1, 0.5 / self.ppm)
        offsets = (
            -SHOULDER_M, road_width + SHOULDER_M, inset, road_width - inset, 0.0, road_width
        )
        self._edges_xy = np.stack([ref.to_xy(s, np.full_like(s, d)) for d in offsets])
        self._sample_margin_m = SAMPLE_STEP_M + road_width + SHOULDER_M

        dash_s = np.arange(0.0, ref.end_s - DASH_PERIOD_M + DASH_LENGTH_M, DASH_PERIOD_M)
        starts, ends = [], []
        for lane in range(1, self.road.lane_count):
            d = np.full_like(dash_s, lane * self.road.lane_width)
            starts.append(ref.to_xy(dash_s, d))
            ends.append(ref.to_xy(dash_s + DASH_LENGTH_M, d))
        self._dash_start = np.concatenate(starts) if starts else np.zeros((0, 2))
        self._dash_end = np.concatenate(ends) if ends else np.zeros((0, 2))

    def _precompute_markers(self) -> None:
        ref = self.road.reference
        marker_s = np.arange(0.0, ref.end_s - 0.5 * MARKER_SPACING_M, MARKER_SPACING_M)
        d0 = self.road.road_width + SHOULDER_M
        self._marker_in = ref.to_xy(marker_s, np.full_like(marker_s, d0))
        self._marker_out = ref.to_xy(marker_s, np.full_like(marker_s, d0 + 2.0))
        self._marker_label_at = ref.to_xy(marker_s, np.full_like(marker_s, d0 + 2.5))
        self._marker_labels = [
            self._small_font.render(f"{s / 1000.0:.1f} km", True, MARKER_COLOR) for s in marker_s
        ]
        # Start/finish line across the road at s = 0.
        self._start_line = ref.to_xy(np.zeros(2), np.array([0.0, self.road.road_width]))

    def _decorate_minimap(self, surface: Any) -> None:
        """The start/finish point on the mini-map."""
        start = self._minimap_points(self._center_xy[:1])[0]
        self._pg.draw.circle(surface, WHITE_LINE_COLOR, start.tolist(), MINIMAP_START_PX)

    # ------------------------------------------------------------------ per frame
    def _draw(self, surface: Any, scene: HighwayScene) -> None:
        draw = self._pg.draw
        ego_xy = (float(scene.ego_xy[0]), float(scene.ego_xy[1]))
        heading = float(scene.ego_heading)
        ego = np.asarray(ego_xy)
        to_screen = self.world_to_screen
        surface.fill(GRASS_COLOR)

        # Road surface and solid lines, run by run of visible centre-line samples.
        chunk_pts = self._visible_chunks(self._center_xy, self._edges_xy,
                                         self._sample_margin_m, ego_xy, heading)
        # Layer by layer (all shoulders, then all lanes, then lines): a later chunk's
        # shoulder must not cover the overlap it shares with the previous chunk's lanes.
        self._fill_bands(surface, chunk_pts, 0, 1, SHOULDER_COLOR)
        self._fill_bands(surface, chunk_pts, 2, 3, ROAD_COLOR)
        self._stroke_rows(surface, chunk_pts, [(4, YELLOW_LINE_COLOR), (5, WHITE_LINE_COLOR)])

        # Dashed lane separators.
        self._draw_segments(surface, self._dash_start, self._dash_end, DASH_LENGTH_M,
                            WHITE_LINE_COLOR, self._line_px, ego_xy, heading)

        # Start/finish line.
        start_line = to_screen(self._start_line, ego_xy, heading)
        draw.line(surface, WHITE_LINE_COLOR, *start_line.tolist(), max(2, self._line_px * 2))

        # Distance markers: tick outside the right edge, label next to it (upright).
        near = self._near(self._marker_in, ego, MARKER_REACH_M)
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

        # Construction zones: the closed lane's surface, cones along it and across its start.
        for s_start, s_end, lane in scene.closed_lanes:
            self._draw_closed_lane(surface, s_start, s_end, lane, ego, ego_xy, heading)

        # Planner path points.
        self._draw_path_dots(surface, scene.path_xy, ego_xy, heading, PATH_COLOR,
                             max(2.0, PATH_DOT_M * self.ppm))

        # Traffic.
        cars = np.asarray(scene.cars_xy, dtype=np.float64).reshape(-1, 2)
        if len(cars):
            length = np.broadcast_to(np.asarray(scene.cars_length, dtype=np.float64), len(cars))
            width = np.broadcast_to(np.asarray(scene.cars_width, dtype=np.float64), len(cars))
            reach = 0.5 * np.hypot(length, width)
            visible = np.hypot(*(cars - ego).T) < self.view_radius_m + reach
            if visible.any():
                colors = np.asarray(scene.cars_color, dtype=np.uint8).reshape(-1, 3)[visible]
                headings = np.broadcast_to(np.asarray(scene.cars_heading, dtype=np.float64),
                                           len(cars))[visible]
                self._draw_boxes(surface, cars[visible], headings, length[visible],
                                 width[visible], [tuple(color) for color in colors.tolist()],
                                 ego_xy, heading, glass=True)

        # Ego.
        self._draw_boxes(surface, ego[None, :], np.array([heading]),
                         np.array([float(scene.ego_length)]),
                         np.array([float(scene.ego_width)]), [EGO_COLOR], ego_xy, heading,
                         glass=True)

        self._draw_overlay(surface, scene)
        self._draw_minimap(surface, scene, cars)

    def _draw_closed_lane(self, surface: Any, s_start: float, s_end: float, lane: int,
                          ego: NDArray[np.float64], ego_xy: tuple[float, float],
                          heading: float) -> None:
        """A closed lane from ``s_start`` to ``s_end``, drawn where it is in view."""
        ref = self.road.reference
        width = self.road.lane_width
        s = np.arange(s_start, s_end + 1e-9, SAMPLE_STEP_M)
        if not len(s):
            return
        left = ref.to_xy(ref.wrap_s(s), np.full(len(s), lane * width))
        right = ref.to_xy(ref.wrap_s(s), np.full(len(s), (lane + 1) * width))
        reach = self.view_radius_m + SAMPLE_STEP_M
        seen = np.hypot(*(left - ego).T) < reach
        if not seen.any():
            return
        rows = np.flatnonzero(seen)
        band = np.concatenate([left[rows], right[rows][::-1]])
        if len(rows) >= 2:
            self._pg.draw.polygon(surface, ZONE_COLOR,
                                  self.world_to_screen(band, ego_xy, heading).tolist())
        cones_s = np.arange(s_start, s_end + 1e-9, CONE_SPACING_M)
        across = np.linspace(lane * width + 0.4, (lane + 1) * width - 0.4, 4)
        points = [ref.to_xy(ref.wrap_s(cones_s), np.full(len(cones_s), d))
                  for d in (lane * width + 0.3, (lane + 1) * width - 0.3)]
        points.append(ref.to_xy(ref.wrap_s(np.full(4, s_start)), across))
        cones = np.concatenate(points)
        cones = cones[np.hypot(*(cones - ego).T) < reach]
        radius = max(1.5, CONE_RADIUS_M * self.ppm)
        for x, y in self.world_to_screen(cones, ego_xy, heading).tolist():
            self._pg.draw.circle(surface, CONE_COLOR, (x, y), radius)

    def _draw_overlay(self, surface: Any, scene: HighwayScene) -> None:
        lines = [
            *self._clock_lines(scene.speed_mph, scene.time_s, scene.laps),
            f"Dist   {scene.distance_m / METERS_PER_MILE:.2f} mi",
        ]
        if scene.incidents:
            lines.append(f"Incidents  {sum(int(v) for v in scene.incidents.values())}")
            lines.extend(f"  {kind}: {int(count)}" for kind, count in scene.incidents.items())
        else:
            lines.append("Incidents  0")
        self._draw_text_panel(surface, lines)
        self._draw_status(surface, scene.status)

    def _draw_minimap(self, surface: Any, scene: HighwayScene, cars: NDArray[np.float64]) -> None:
        draw = self._pg.draw
        x0, y0 = self._mini_pos
        surface.blit(self._minimap, (x0, y0))
        if len(cars):
            colors = np.asarray(scene.cars_color, dtype=np.uint8).reshape(-1, 3).tolist()
            for (px, py), color in zip(self._minimap_points(cars).tolist(), colors, strict=True):
                draw.circle(surface, color, (x0 + px, y0 + py), MINIMAP_CAR_PX)
        self._draw_minimap_car(surface, scene.ego_xy, EGO_COLOR)
