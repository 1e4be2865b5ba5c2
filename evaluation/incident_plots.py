"""Where incidents happened, and how each came about.

* :func:`incident_map_figure` (``incident_map.png``): the loop with its lanes, one panel
  per agent with its incidents (all seeds) marked by kind; panels fill their rows (a
  shorter last row is centred, never an empty panel) and titles are two short lines;
* :func:`incident_strip_figure` (``incident_gallery/*.png``): one incident as a strip of
  top-down snapshots at -3, -2, -1 and 0 s, drawn from its report's recorded history
  (:mod:`sdc_evaluation.incident_reports`): the road around the ego, the ego (blue) with its
  trail, and every traffic car of the report (grey, heading from its velocity), in the
  ego's frame (driving to the right) so that the strip reads like a dash-cam from above.
  The ego is drawn at its size and place (:class:`EgoShape`: on the track its position is
  the rear axle); traffic cars at 4.7 x 1.9 m, as the report does not record their type.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Polygon
from numpy.typing import NDArray

from sdc_evaluation.plots import KIND_STYLE, new_figure, save_figure
from sdc_gym.metrics import INCIDENT_KINDS

INCIDENT_MAP_FILE = "incident_map.png"
GALLERY_FOLDER = "incident_gallery"
GALLERY_LIMIT = 30
"""Most incidents drawn in the gallery (the first ones of the run, in its order)."""
SNAPSHOT_OFFSETS_S = (-3.0, -2.0, -1.0, 0.0)
CAR_LENGTH_M, CAR_WIDTH_M = 4.7, 1.9
VIEW_BEHIND_M, VIEW_AHEAD_M, VIEW_SIDE_M = 20.0, 40.0, 10.0


@dataclass(frozen=True)
class EgoShape:
    """The ego's box: length, width (m) and how far its centre lies ahead of the position
    the env reports (0 on the highway; about 1.4 m on the track, from the rear axle)."""

    length: float = CAR_LENGTH_M
    width: float = CAR_WIDTH_M
    centre_ahead_m: float = 0.0

    @classmethod
    def of_env(cls, env: Any) -> EgoShape:
        """From an unwrapped env: the track's ``car_length``/``car_width`` and the centre
        ahead of the rear axle, or the highway's ``ego_length``/``ego_width`` config."""
        if hasattr(env, "car_length"):
            return cls(float(env.car_length), float(env.car_width),
                       float(env.front_offset) - 0.5 * float(env.car_length))
        config = getattr(env, "config", {})
        return cls(float(config.get("ego_length", CAR_LENGTH_M)),
                   float(config.get("ego_width", CAR_WIDTH_M)))


DEFAULT_EGO = EgoShape()


def _road_lines(road: Any, spacing: float = 2.0) -> list[tuple[NDArray[np.float64], float]]:
    """Closed (x, y) polylines from the inner edge to the outer one, with their d.

    A highway (``lane_count``, ``lane_width``): the centre line (d = 0, the inner edge), the
    lane lines and the outer edge. A track (``road_half_width_m``): both edges around the
    path, which is the centre line (d = 0).
    """
    reference = getattr(road, "reference", None)
    if reference is None:  # only waypoints: the centre line
        xy = np.asarray(road.waypoints, dtype=np.float64)[:, :2]
        return [(np.vstack([xy, xy[:1]]), 0.0)]
    count = max(int(np.ceil(road.length / spacing)), 64)
    s = np.linspace(0.0, road.length, count + 1)  # s = length closes the loop
    return [(reference.to_xy(s, d), d) for d in _line_offsets(road)]


def _line_offsets(road: Any) -> list[float]:
    half = getattr(road, "road_half_width_m", None)
    if half is not None:
        return [-half, 0.0, half]
    return [k * road.lane_width for k in range(road.lane_count + 1)]


def _draw_loop(ax: Any, road: Any) -> None:
    lines = _road_lines(road)
    outer = max(d for _, d in lines)
    inner_d = lines[0][1]
    if len(lines) > 1:  # the road surface between the centre line and the edge
        ring = np.vstack([lines[0][0], lines[-1][0][::-1]])
        ax.fill(ring[:, 0], ring[:, 1], color="0.92", linewidth=0)
    for xy, d in lines:
        if d == 0.0 and d != inner_d:  # a track's path between its edges
            ax.plot(xy[:, 0], xy[:, 1], color="silver", linewidth=0.6, linestyle="--")
        elif d == 0.0:
            ax.plot(xy[:, 0], xy[:, 1], color="goldenrod", linewidth=1.0)
        elif d in (outer, inner_d):
            ax.plot(xy[:, 0], xy[:, 1], color="dimgray", linewidth=1.0)
        else:
            ax.plot(xy[:, 0], xy[:, 1], color="silver", linewidth=0.6, linestyle="--")
    start = getattr(road, "start_s", None)
    if start is not None and getattr(road, "reference", None) is not None:
        x, y = road.reference.to_xy(start, getattr(road, "start_d", 0.0))
        ax.plot([x], [y], marker="|", markersize=14, color="black", linestyle="none",
                label="start")
    stop_lines = getattr(road, "stop_lines_xy", None)
    if stop_lines is not None and len(stop_lines):
        ax.plot(stop_lines[:, 0], stop_lines[:, 1], marker="_", markersize=12,
                color="black", linestyle="none", label="stop lines")


def _panel_grid(figure: Figure, count: int, columns: int) -> list[Any]:
    """``count`` axes in rows of ``columns``; a shorter last row is centred (a grid of
    half-columns, each panel spanning two), so no panel is left empty."""
    rows = -(-count // columns)
    grid = figure.add_gridspec(rows, 2 * columns)
    axes = []
    for index in range(count):
        row, column = divmod(index, columns)
        in_row = min(columns, count - row * columns)
        first = (columns - in_row) + 2 * column
        axes.append(figure.add_subplot(grid[row, first:first + 2]))
    return axes


def incident_map_figure(road: Any, episodes: Sequence[dict[str, Any]],
                        labels: dict[str, str] | None = None,
                        panel_size: float = 5.0) -> Figure:
    """The loop with its lanes; each agent's incidents (all its seeds) marked by kind.

    ``road`` is the env's map (``env.unwrapped.road`` or ``.track``); incidents come from
    each episode's ``incident_log``. One scatter per kind and panel, labelled
    ``"kind (count)"``.
    """
    labels = labels or {}
    by_agent: dict[str, list[dict[str, Any]]] = {}
    for episode in episodes:
        by_agent.setdefault(episode["agent"], []).append(episode)
    agents = list(by_agent) or ["(no episodes)"]
    columns = 2 if len(agents) == 4 else min(len(agents), 3)
    rows = -(-len(agents) // columns)
    figure = new_figure(panel_size * columns, panel_size * rows + 0.3)
    for ax, agent in zip(_panel_grid(figure, len(agents), columns), agents, strict=True):
        _draw_loop(ax, road)
        log = [entry for episode in by_agent.get(agent, [])
               for entry in episode.get("incident_log", [])]
        for kind in dict.fromkeys([*INCIDENT_KINDS, *(entry["kind"] for entry in log)]):
            points = [(entry["x"], entry["y"]) for entry in log if entry["kind"] == kind]
            if not points:
                continue
            marker, color = KIND_STYLE.get(kind, ("*", "black"))
            xy = np.asarray(points, dtype=np.float64)
            ax.scatter(xy[:, 0], xy[:, 1], marker=marker, color=color, s=40, zorder=3,
                       edgecolors="black", linewidths=0.4, label=f"{kind} ({len(points)})")
        runs = len(by_agent.get(agent, []))
        ax.set_title(f"{labels.get(agent, agent)}\n{len(log)} incident(s) in {runs} "
                     "episode(s)", fontsize="medium")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.legend(loc="best", fontsize="small")
    return figure


# ------------------------------------------------------------------ the incident gallery
def _frame(x0: float, y0: float, yaw: float):
    """Map (x, y) -> the ego's frame at (x0, y0, yaw): ahead +x, left +y."""
    cos, sin = math.cos(yaw), math.sin(yaw)

    def transform(x: Any, y: Any) -> tuple[Any, Any]:
        dx, dy = np.asarray(x) - x0, np.asarray(y) - y0
        return dx * cos + dy * sin, -dx * sin + dy * cos

    return transform


def _box(x: float, y: float, heading: float, length: float = CAR_LENGTH_M,
         width: float = CAR_WIDTH_M) -> NDArray[np.float64]:
    corners = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]], dtype=np.float64)
    corners *= [length / 2, width / 2]
    cos, sin = math.cos(heading), math.sin(heading)
    return corners @ np.array([[cos, sin], [-sin, cos]]) + [x, y]


def _nearest(times: Sequence[float], t: float, tolerance: float = 0.11) -> int | None:
    if not len(times):
        return None
    index = int(np.argmin(np.abs(np.asarray(times) - t)))
    return index if abs(times[index] - t) <= tolerance else None


def _snapshot(ax: Any, road: Any, history: dict[str, Any], index: int,
              ego_shape: EgoShape) -> None:
    ego = history["ego"]
    x0, y0, yaw = ego["x"][index], ego["y"][index], ego["yaw"][index]
    to_frame = _frame(x0, y0, yaw)
    reference = getattr(road, "reference", None)
    if reference is not None and road is not None:
        s = reference.wrap_s(ego["s"][index] + np.linspace(-VIEW_BEHIND_M - 20,
                                                          VIEW_AHEAD_M + 20, 80))
        offsets = _line_offsets(road)
        for d in offsets:
            xy = reference.to_xy(s, d)
            edge = d in (offsets[0], offsets[-1])
            ax.plot(*to_frame(xy[:, 0], xy[:, 1]), color="dimgray" if edge else "silver",
                    linewidth=1.0 if edge else 0.7, linestyle="-" if edge else "--")
        for line_s in getattr(road, "stop_line_s", ()):  # the track's stop lines, across
            across = reference.to_xy(np.full(2, line_s), np.array([offsets[0], offsets[-1]]))
            ax.plot(*to_frame(across[:, 0], across[:, 1]), color="black", linewidth=2.0)
    trail = slice(0, index + 1)
    ax.plot(*to_frame(ego["x"][trail], ego["y"][trail]), color="tab:blue", linewidth=0.8,
            linestyle=":")
    ax.add_patch(Polygon(_box(ego_shape.centre_ahead_m, 0.0, 0.0, ego_shape.length,
                              ego_shape.width), closed=True, facecolor="tab:blue",
                         edgecolor="black", linewidth=0.6, zorder=3))
    now = history["time"][index]
    for car in history.get("cars", []):
        at = _nearest(car["time"], now, tolerance=1e-6)
        if at is None:
            continue
        cx, cy = to_frame(car["x"][at], car["y"][at])
        if not (-VIEW_BEHIND_M - 5 < cx < VIEW_AHEAD_M + 5 and abs(cy) < VIEW_SIDE_M + 5):
            continue
        vx, vy = car["vx"][at], car["vy"][at]
        heading = (math.atan2(vy, vx) - yaw) if math.hypot(vx, vy) > 0.1 else 0.0
        ax.add_patch(Polygon(_box(float(cx), float(cy), heading), closed=True,
                             facecolor="0.65", edgecolor="black", linewidth=0.5, zorder=2))
        ax.text(float(cx), float(cy) + CAR_WIDTH_M, str(car["id"]), fontsize=6,
                ha="center", color="0.3")
    ax.text(0.02, 0.04, f"{ego['speed'][index] * 2.2369362920544:.0f} mph",
            transform=ax.transAxes, fontsize="x-small", color="tab:blue")


def incident_strip_figure(report: dict[str, Any], road: Any, label: str,
                          ego_shape: EgoShape = DEFAULT_EGO) -> Figure:
    """Snapshots at :data:`SNAPSHOT_OFFSETS_S` before ``report``'s incident (see the module
    docstring); a panel whose moment lies before the episode's start says so."""
    figure = new_figure(14.0, 2.4)
    axes = figure.subplots(1, len(SNAPSHOT_OFFSETS_S), sharey=True)
    history = report.get("history") or {"time": [], "ego": {}, "cars": []}
    times = history["time"]
    moment = times[-1] if times else report.get("time", 0.0)
    color = KIND_STYLE.get(report["kind"], ("*", "black"))[1]
    for ax, offset in zip(axes, SNAPSHOT_OFFSETS_S, strict=True):
        index = _nearest(times, moment + offset)
        ax.set_xlim(-VIEW_BEHIND_M, VIEW_AHEAD_M)
        ax.set_ylim(-VIEW_SIDE_M, VIEW_SIDE_M)
        ax.set_aspect("equal")
        ax.set_xticks([-20, 0, 20, 40])
        ax.set_yticks([-10, 0, 10])
        ax.tick_params(labelsize="x-small")
        ax.set_title(f"{offset:+.0f} s" if offset else f"0 s: {report['kind']}",
                     fontsize="small", color=color if not offset else "black")
        if index is None:
            ax.text(0.5, 0.5, "before the episode's start", transform=ax.transAxes,
                    ha="center", va="center", fontsize="small", color="0.4")
            continue
        _snapshot(ax, road, history, index, ego_shape)
        if not offset:
            ax.scatter([ego_shape.centre_ahead_m], [0.0], marker="o", s=260,
                       facecolors="none", edgecolors=color, linewidths=2.0, zorder=4)
    value = report.get("value")
    detail = f", value {value:.2f}" if isinstance(value, int | float) else ""
    figure.suptitle(f"{label} seed {report.get('seed', '?')}: {report['kind']} at "
                    f"{report.get('time', moment):.2f} s, s = {report.get('s', 0.0):.0f} m"
                    f"{detail} (ego blue, driving right; m in its frame)", fontsize="small")
    return figure


def gallery_file_name(index: int, report: dict[str, Any], label: str) -> str:
    slug = re.sub(r"[^A-Za-z0-9_.-]+", "_", label).strip("_")
    return f"{index:03d}_{slug}_seed{report.get('seed', 0)}_{report['kind']}.png"


def write_gallery(folder: Path, reports: Sequence[dict[str, Any]], road: Any,
                  labels: dict[str, str] | None = None, limit: int = GALLERY_LIMIT,
                  ego_shape: EgoShape = DEFAULT_EGO) -> list[tuple[dict[str, Any], Path]]:
    """A strip per report (the first ``limit``) into ``folder``; ``(report, path)`` pairs."""
    labels = labels or {}
    written = []
    for index, report in enumerate(reports[:limit]):
        label = labels.get(report.get("agent", ""), report.get("agent", ""))
        figure = incident_strip_figure(report, road, label, ego_shape)
        written.append((report, save_figure(figure, folder / gallery_file_name(
            index, report, label), dpi=90)))
    return written
