"""The machinery the top-down renderers share: the rotated view, pygame and its window.

:class:`TopDownRenderer` is the base of :class:`~sdc_gym.render.track_renderer.TrackRenderer`
and :class:`~sdc_gym.render.highway_renderer.HighwayRenderer`. A subclass precomputes its
static geometry and implements :meth:`TopDownRenderer._draw`; the base holds everything
that does not depend on what the road looks like:

* the **rotated view**: the car's heading points up the screen and the car sits centred
  horizontally a bit below the middle (:attr:`TopDownRenderer.car_screen_xy`); a point
  ``a`` metres ahead / ``b`` metres right of the car's centre is drawn ``a * ppm`` pixels
  above / ``b * ppm`` pixels right of it (:meth:`TopDownRenderer.world_to_screen`);
  :attr:`TopDownRenderer.view_radius_m` is the half-diagonal of the view seen from the car,
  so anything further is off screen;
* pygame (pygame-ce), imported lazily by the constructor: ``rgb_array`` frames are drawn
  onto a plain ``pygame.Surface`` and only ``pygame.font`` is initialised (no display, no
  ``SDL_VIDEODRIVER`` needed); the ``human`` window opens on the first
  :meth:`TopDownRenderer.render_human` call, pumps events (its close button closes it for
  good) and holds the frame rate;
* cached text and translucent panel surfaces, the upright text panel and status line,
  visible-sample selection, path dots, oriented car/obstacle boxes, and the north-up
  corner mini-map (its fit, background and markers).
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.render.drawing import box_corners, circular_runs

Color = tuple[int, int, int]

OUTLINE_COLOR: Color = (15, 15, 15)
GLASS_COLOR: Color = (45, 60, 85)
TEXT_COLOR: Color = (245, 245, 245)
STATUS_COLOR: Color = (255, 210, 60)
MINIMAP_ROAD_COLOR: Color = (150, 150, 150)
MINIMAP_BORDER_COLOR: Color = (200, 200, 200)
MARKER_RING_COLOR: Color = (255, 255, 255)
PANEL_COLOR: Color = (0, 0, 0)
PANEL_ALPHA = 150  # 0..255: translucency of text panels and the mini-map background

CAR_SCREEN_FRACTION = (0.5, 0.65)  # the car's screen position, as fractions of width, height
TEXT_CACHE_SIZE = 256  # rendered strings kept; the cache is emptied when full
PANEL_MARGIN_PX = 8  # panels and the mini-map stand this far from the frame's edges
PANEL_PAD_PX = 6  # text inside a panel starts this far from its edge
PANEL_ROUND_PX = 20  # panel widths round up to this, so a few cached panels serve all frames
STATUS_PAD_PX = (16, 8)  # status panel size beyond its text (width, height)
STATUS_BOTTOM_PX = 10  # the status panel's gap to the frame's bottom edge
MINIMAP_FRACTION = 0.27  # mini-map side, as a fraction of the frame's shorter side
MINIMAP_MIN_PX = 60
MINIMAP_PAD_PX = 6
MINIMAP_ROAD_PX = 3
MINIMAP_MARKER_PX = 4  # radius of the car's dot on the mini-map
OFFSCREEN_SLACK_PX = 4  # path dots this far outside the frame are still drawn (partly visible)
GLASS_FRONT, GLASS_BACK, GLASS_HALF_WIDTH = 0.25, 0.08, 0.38  # windscreen, body fractions


def _round_up(value: int, step: int) -> int:
    return -(-value // step) * step


class TopDownRenderer:
    """Base of the top-down renderers; see the module doc.

    Args:
        width, height: frame size in pixels.
        pixels_per_meter: zoom of the main view.
        render_fps: frame rate the ``human`` window is limited to (0: unlimited).
        caption: the ``human`` window's title.

    A subclass calls this constructor first, then precomputes its geometry (ending with
    :meth:`_precompute_minimap`), and implements :meth:`_draw`.
    """

    road_closed: bool = True
    """False for an open road: its ends are not joined (a subclass sets it)."""

    def __init__(self, *, width: int, height: int, pixels_per_meter: float, render_fps: int,
                 caption: str) -> None:
        if width <= 0 or height <= 0:
            raise ValueError(f"frame size must be positive, got {width} x {height}")
        if pixels_per_meter <= 0:
            raise ValueError(f"pixels_per_meter must be positive, got {pixels_per_meter}")
        os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
        import pygame

        self._pg: Any = pygame
        pygame.font.init()
        self.width = int(width)
        self.height = int(height)
        self.ppm = float(pixels_per_meter)
        self.render_fps = int(render_fps)
        self.caption = caption
        self.car_screen_xy: tuple[float, float] = (CAR_SCREEN_FRACTION[0] * self.width,
                                                   CAR_SCREEN_FRACTION[1] * self.height)
        cx, cy = self.car_screen_xy
        self.view_radius_m = math.hypot(max(cx, self.width - cx),
                                        max(cy, self.height - cy)) / self.ppm
        self._surface = pygame.Surface((self.width, self.height))
        self._window: Any = None
        self._clock: Any = None
        self.window_closed_by_user = False
        # Font sizes follow the frame height (pygame's default font, size in px).
        self._font_base = max(12, round(self.height / 30))
        self._font = pygame.font.Font(None, self._font_base + 4)
        self._status_font = pygame.font.Font(None, self._font_base + 10)
        self._text_cache: dict[tuple[int, str, Color], Any] = {}
        self._panel_cache: dict[tuple[int, int], Any] = {}
        self._line_px = 1  # road line width, px; subclasses set it from their line width in m

    # ------------------------------------------------------------------ subclass hooks
    def _draw(self, surface: Any, scene: Any) -> None:
        """Draw one whole frame of ``scene`` onto ``surface``."""
        raise NotImplementedError

    def _decorate_minimap(self, surface: Any) -> None:
        """Draw static extras on the mini-map background (before its border); none here."""

    # ------------------------------------------------------------------ view geometry
    def world_to_screen(self, xy: NDArray[np.float64], car_xy: tuple[float, float],
                        car_heading: float) -> NDArray[np.float64]:
        """Map points ``(..., 2)`` to screen pixels ``(..., 2)`` of the rotated view."""
        c, s = math.cos(car_heading), math.sin(car_heading)
        p = self.ppm
        # Columns: screen x = ppm * (rel . right), screen y = -ppm * (rel . forward).
        matrix = np.array([[p * s, -p * c], [-p * c, -p * s]])
        rel = np.asarray(xy, dtype=np.float64) - np.asarray(car_xy, dtype=np.float64)
        return rel @ matrix + np.asarray(self.car_screen_xy)

    def _near(self, points: NDArray[np.float64], centre: NDArray[np.float64],
              margin: float) -> NDArray[np.intp]:
        """Indices of ``points`` (n, 2) within the view radius plus ``margin`` m of ``centre``."""
        if not len(points):
            return np.zeros(0, dtype=np.intp)
        return np.flatnonzero(np.hypot(*(points - centre).T) < self.view_radius_m + margin)

    def _visible_chunks(self, samples_xy: NDArray[np.float64], rows_xy: NDArray[np.float64],
                        margin: float, car_xy: tuple[float, float],
                        car_heading: float) -> list[NDArray[np.float64]]:
        """Screen points ``(rows, k, 2)`` of each visible chunk of a closed road.

        ``samples_xy`` (n, 2) are the road's samples (a sample within the view radius plus
        ``margin`` m is visible); ``rows_xy`` (rows, n, 2) are the lines drawn along them.
        """
        dist = np.hypot(*(samples_xy - np.asarray(car_xy)).T)
        chunks = circular_runs(dist < self.view_radius_m + margin, self.road_closed)
        return [self.world_to_screen(rows_xy[:, chunk], car_xy, car_heading) for chunk in chunks]

    def _fill_bands(self, surface: Any, chunk_pts: list[NDArray[np.float64]], left: int,
                    right: int, color: Color) -> None:
        """Fill the band between rows ``left`` and ``right`` of each visible chunk."""
        for pts in chunk_pts:
            self._pg.draw.polygon(surface, color,
                                  np.concatenate([pts[left], pts[right][::-1]]).tolist())

    def _stroke_rows(self, surface: Any, chunk_pts: list[NDArray[np.float64]],
                     rows: list[tuple[int, Color]]) -> None:
        """Draw rows ``(row, colour)`` of each visible chunk as lines ``_line_px`` wide,
        chunk by chunk."""
        for pts in chunk_pts:
            for row, color in rows:
                self._pg.draw.lines(surface, color, False, pts[row].tolist(), self._line_px)

    # ------------------------------------------------------------------ drawing helpers
    def _text(self, font: Any, text: str, color: Color = TEXT_COLOR) -> Any:
        """``text`` rendered (antialiased) in ``font``, cached."""
        key = (id(font), text, color)
        surface = self._text_cache.get(key)
        if surface is None:
            if len(self._text_cache) >= TEXT_CACHE_SIZE:
                self._text_cache.clear()
            surface = font.render(text, True, color)
            self._text_cache[key] = surface
        return surface

    def _panel(self, width: int, height: int) -> Any:
        """A translucent black panel of this size, cached."""
        key = (width, height)
        panel = self._panel_cache.get(key)
        if panel is None:
            panel = self._pg.Surface((width, height))
            panel.fill(PANEL_COLOR)
            panel.set_alpha(PANEL_ALPHA)
            self._panel_cache[key] = panel
        return panel

    def _draw_segments(self, surface: Any, start_xy: NDArray[np.float64],
                       end_xy: NDArray[np.float64], reach_m: float, color: Color,
                       width_px: int, car_xy: tuple[float, float], car_heading: float) -> None:
        """Straight segments ``start_xy[i] -> end_xy[i]`` whose start lies within the view
        radius plus ``reach_m`` (their length or more) of the car."""
        near = self._near(start_xy, np.asarray(car_xy), reach_m)
        if not near.size:
            return
        a = self.world_to_screen(start_xy[near], car_xy, car_heading).tolist()
        b = self.world_to_screen(end_xy[near], car_xy, car_heading).tolist()
        for start, end in zip(a, b, strict=True):
            self._pg.draw.line(surface, color, start, end, width_px)

    def _draw_path_dots(self, surface: Any, path_xy: NDArray[np.float64],
                        car_xy: tuple[float, float], car_heading: float, color: Color,
                        radius_px: float) -> None:
        """Dots at the on-screen points of ``path_xy`` (m, 2)."""
        path = np.asarray(path_xy, dtype=np.float64).reshape(-1, 2)
        if not len(path):
            return
        pts = self.world_to_screen(path, car_xy, car_heading)
        slack = OFFSCREEN_SLACK_PX
        visible = ((pts[:, 0] > -slack) & (pts[:, 0] < self.width + slack)
                   & (pts[:, 1] > -slack) & (pts[:, 1] < self.height + slack))
        for point in pts[visible].tolist():
            self._pg.draw.circle(surface, color, point, radius_px)

    def _draw_boxes(self, surface: Any, xy: NDArray[np.float64], heading: NDArray[np.float64],
                    length: NDArray[np.float64], width: NDArray[np.float64],
                    colors: list[Color], car_xy: tuple[float, float], car_heading: float, *,
                    glass: bool) -> None:
        """Oriented boxes (n,) with a dark outline, each with a windscreen towards its front
        if ``glass``; box ``i`` is drawn whole before box ``i + 1``."""
        draw = self._pg.draw
        half_l = 0.5 * length
        body = self.world_to_screen(box_corners(xy, heading, half_l, -half_l, 0.5 * width),
                                    car_xy, car_heading).tolist()
        windows: list[Any] = [None] * len(body)
        if glass:
            windows = self.world_to_screen(
                box_corners(xy, heading, GLASS_FRONT * length, GLASS_BACK * length,
                            GLASS_HALF_WIDTH * width), car_xy, car_heading).tolist()
        for corners, window, color in zip(body, windows, colors, strict=True):
            draw.polygon(surface, color, corners)
            draw.polygon(surface, OUTLINE_COLOR, corners, 1)
            if window is not None:
                draw.polygon(surface, GLASS_COLOR, window)

    @staticmethod
    def _clock_lines(speed_mph: float, time_s: float, laps: int) -> list[str]:
        """The text panel's first lines: speed, episode time (m:ss.s) and laps."""
        minutes, seconds = divmod(max(float(time_s), 0.0), 60.0)
        return [
            f"Speed  {speed_mph:5.1f} mph",
            f"Time   {int(minutes)}:{seconds:04.1f}",
            f"Lap    {int(laps)}",
        ]

    def _draw_text_panel(self, surface: Any, lines: list[str]) -> None:
        """``lines`` on a translucent panel in the top-left corner."""
        texts = [self._text(self._font, line) for line in lines]
        line_h = self._font.get_linesize()
        pad = PANEL_PAD_PX
        panel_w = _round_up(max(text.get_width() for text in texts) + 2 * pad, PANEL_ROUND_PX)
        panel_h = line_h * len(texts) + 2 * pad
        margin = PANEL_MARGIN_PX
        surface.blit(self._panel(panel_w, panel_h), (margin, margin))
        for i, text in enumerate(texts):
            surface.blit(text, (margin + pad, margin + pad + i * line_h))

    def _draw_status(self, surface: Any, status: str) -> None:
        """``status`` (if not empty) centred on a panel at the bottom of the frame."""
        if not status:
            return
        text = self._text(self._status_font, status, STATUS_COLOR)
        w = _round_up(text.get_width() + STATUS_PAD_PX[0], PANEL_ROUND_PX)
        h = text.get_height() + STATUS_PAD_PX[1]
        x, y = (self.width - w) // 2, self.height - h - STATUS_BOTTOM_PX
        surface.blit(self._panel(w, h), (x, y))
        surface.blit(text, text.get_rect(center=(x + w // 2, y + h // 2)))

    # ------------------------------------------------------------------ mini-map
    def _precompute_minimap(self, loop_xy: NDArray[np.float64]) -> None:
        """Fit the closed road ``loop_xy`` (n, 2) into the corner mini-map (north-up, equal
        scale on both axes, centred) and draw its background once."""
        pg = self._pg
        size = max(MINIMAP_MIN_PX, round(MINIMAP_FRACTION * min(self.width, self.height)))
        inner = size - 2 * MINIMAP_PAD_PX
        lo = loop_xy.min(axis=0)
        hi = loop_xy.max(axis=0)
        scale = inner / max(float(np.max(hi - lo)), 1e-6)
        self._mini_scale = scale
        self._mini_lo = lo
        self._mini_offset = MINIMAP_PAD_PX + 0.5 * (inner - scale * (hi - lo))
        self._mini_size = size
        self._mini_pos = (self.width - size - PANEL_MARGIN_PX, PANEL_MARGIN_PX)
        surface = pg.Surface((size, size), pg.SRCALPHA)
        surface.fill((*PANEL_COLOR, PANEL_ALPHA))
        pg.draw.lines(surface, MINIMAP_ROAD_COLOR, self.road_closed,
                      self._minimap_points(loop_xy).tolist(), MINIMAP_ROAD_PX)
        self._decorate_minimap(surface)
        pg.draw.rect(surface, MINIMAP_BORDER_COLOR, surface.get_rect(), 1)
        self._minimap = surface

    def _minimap_points(self, xy: NDArray[np.float64]) -> NDArray[np.float64]:
        """Map points (a point (2,) or points (n, 2)) to mini-map pixels (n, 2), north-up,
        relative to the mini-map corner."""
        rel = (np.asarray(xy, dtype=np.float64).reshape(-1, 2) - self._mini_lo) * self._mini_scale
        rel += self._mini_offset
        rel[:, 1] = self._mini_size - rel[:, 1]
        return rel

    def _draw_minimap_car(self, surface: Any, car_xy: tuple[float, float], color: Color) -> None:
        """The car's ringed dot on the mini-map (after the background is blitted)."""
        x0, y0 = self._mini_pos
        cx, cy = self._minimap_points(np.asarray(car_xy, dtype=np.float64))[0]
        draw = self._pg.draw
        draw.circle(surface, color, (x0 + cx, y0 + cy), MINIMAP_MARKER_PX)
        draw.circle(surface, MARKER_RING_COLOR, (x0 + cx, y0 + cy), MINIMAP_MARKER_PX, 1)

    # ------------------------------------------------------------------ public API
    def render_rgb(self, scene: Any) -> NDArray[np.uint8]:
        """Draw ``scene`` off screen; returns a fresh (height, width, 3) uint8 RGB frame."""
        self._draw(self._surface, scene)
        data = bytearray(self._pg.image.tobytes(self._surface, "RGB"))
        return np.frombuffer(data, dtype=np.uint8).reshape(self.height, self.width, 3)

    def render_human(self, scene: Any) -> None:
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
            pg.display.set_caption(self.caption)
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
