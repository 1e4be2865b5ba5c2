"""Plots of an evaluation run, written as PNG files (used by ``evaluate.py``).

* :func:`profile_figure`: speed (mph), total acceleration and jerk over distance, three
  stacked panels, one line per agent, the limits as dashed lines;
* :func:`lap_time_figure`: every lap time of every agent as points over a box plot;
* :func:`incident_map_figure`: the loop with its lanes and each agent's incidents marked
  by kind (one panel per agent).

Figures are built with the object-oriented API on the Agg canvas (no ``pyplot``, no global
backend switch, nothing kept alive between calls) and written atomically like the other
result files.
"""

from __future__ import annotations

import io
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from numpy.typing import NDArray

from agents.evaluation import TRACE_KEY, EpisodeTrace, atomic_write_bytes
from sdc_gym.metrics import INCIDENT_KINDS, IncidentRules
from sdc_gym.units import MPS_TO_MPH

PLOT_POINTS = 5000
"""Most points drawn per line: longer traces are decimated (keeping each bucket's min and
max, so that spikes above a limit stay visible)."""

PROFILE_FILE = "profiles.png"
LAP_TIME_FILE = "lap_times.png"
INCIDENT_MAP_FILE = "incident_map.png"

KIND_STYLE: dict[str, tuple[str, str]] = {
    "collision": ("X", "tab:red"),
    "acceleration": ("^", "tab:orange"),
    "jerk": ("v", "tab:purple"),
    "speed": ("o", "tab:blue"),
    "lane": ("s", "tab:green"),
    "off_road": ("D", "tab:brown"),
    "red_light": ("P", "crimson"),
}
"""Marker and colour of each incident kind on the map."""


@dataclass(frozen=True)
class Limits:
    """The limits drawn as dashed lines: mph, m/s^2, m/s^3 (the Udacity highway's)."""

    speed_mph: float = 50.0
    acceleration: float = 10.0
    jerk: float = 10.0

    @classmethod
    def from_rules(cls, rules: IncidentRules) -> Limits:
        return cls(speed_mph=rules.speed_limit * MPS_TO_MPH,
                   acceleration=rules.max_acceleration, jerk=rules.max_jerk)


def new_figure(width: float, height: float) -> Figure:
    """A figure on its own Agg canvas (independent of pyplot and its backend)."""
    figure = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def save_figure(figure: Figure, path: Path, dpi: int = 110) -> Path:
    """Render ``figure`` as PNG and write it atomically to ``path``."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi)
    atomic_write_bytes(path, buffer.getvalue())
    return path


def minmax_indices(values: NDArray[np.float64], max_points: int = PLOT_POINTS
                   ) -> NDArray[np.int64]:
    """Indices of at most about ``max_points`` samples: each bucket's min and max, the ends.

    All indices when ``values`` is short enough; sorted, without duplicates.
    """
    n = len(values)
    if n <= max_points:
        return np.arange(n)
    size = int(np.ceil(n / max(max_points // 2 - 2, 1)))
    full = n // size
    blocks = values[: full * size].reshape(full, size)
    offsets = np.arange(full) * size
    parts = [np.array([0, n - 1]), offsets + blocks.argmin(axis=1),
             offsets + blocks.argmax(axis=1)]
    if full * size < n:
        tail = values[full * size:]
        parts.append(full * size + np.array([tail.argmin(), tail.argmax()]))
    return np.unique(np.concatenate(parts))


def profile_figure(traces: Mapping[str, EpisodeTrace], limits: Limits = Limits(),
                   max_points: int = PLOT_POINTS) -> Figure:
    """Speed, total acceleration and jerk over distance (km): one line per label."""
    figure = new_figure(10.0, 8.0)
    axes = figure.subplots(3, 1, sharex=True)
    panels = (("speed", MPS_TO_MPH, "speed (mph)", (limits.speed_mph,)),
              ("acceleration", 1.0, "total acceleration (m/s²)", (limits.acceleration,)),
              ("jerk", 1.0, "jerk (m/s³)", (limits.jerk, -limits.jerk)))
    for label, trace in traces.items():
        distance_km = trace.distance / 1000.0
        for ax, (name, scale, _, _) in zip(axes, panels, strict=True):
            values = getattr(trace, name) * scale
            keep = minmax_indices(values, max_points)
            ax.plot(distance_km[keep], values[keep], linewidth=0.8, label=label)
    for ax, (_, _, ylabel, lines) in zip(axes, panels, strict=True):
        for value in lines:
            ax.axhline(value, color="black", linestyle="--", linewidth=1.0)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    axes[0].set_title("speed, acceleration and jerk (dashed: limits)")
    axes[-1].set_xlabel("distance (km)")
    if traces:
        axes[0].legend(loc="lower right", fontsize="small")
    return figure


def lap_time_figure(episodes: Iterable[dict[str, Any]]) -> Figure:
    """Every lap time per agent as points over a box plot (agents in order of appearance)."""
    laps: dict[str, list[float]] = {}
    for episode in episodes:
        laps.setdefault(episode["agent"], []).extend(episode["lap_times"])
    agents = list(laps)
    figure = new_figure(max(4.0, 1.8 * len(agents) + 2.0), 4.5)
    ax = figure.subplots()
    positions = np.arange(1, len(agents) + 1)
    filled = [(position, laps[agent]) for position, agent in zip(positions, agents, strict=True)
              if laps[agent]]
    if filled:
        ax.boxplot([times for _, times in filled], positions=[p for p, _ in filled],
                   widths=0.5, showfliers=False)
    jitter = np.random.default_rng(0)
    for position, times in filled:
        offsets = jitter.uniform(-0.12, 0.12, len(times))
        ax.scatter(position + offsets, times, s=18, alpha=0.7, zorder=3)
    for position, agent in zip(positions, agents, strict=True):
        if not laps[agent]:
            ax.text(position, 0.5, "no lap", ha="center", transform=ax.get_xaxis_transform())
    ax.set_xticks(positions, agents)
    ax.set_xlim(0.4, len(agents) + 0.6)
    ax.set_ylabel("lap time (s)")
    ax.set_title("lap times (every lap of every seed)")
    ax.grid(axis="y", alpha=0.3)
    return figure


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
    half = getattr(road, "road_half_width_m", None)
    offsets = ([-half, 0.0, half] if half is not None
               else [k * road.lane_width for k in range(road.lane_count + 1)])
    return [(reference.to_xy(s, d), d) for d in offsets]


def incident_map_figure(road: Any, episodes: Sequence[dict[str, Any]],
                        panel_size: float = 5.5) -> Figure:
    """The loop with its lanes; each agent's incidents (all its seeds) marked by kind.

    ``road`` is a :class:`~sdc_gym.road.highway_map.HighwayMap` (``env.unwrapped.road``);
    incidents come from each episode's ``incident_log``. One scatter per kind and panel,
    labelled ``"kind (count)"``.
    """
    by_agent: dict[str, list[dict[str, Any]]] = {}
    for episode in episodes:
        by_agent.setdefault(episode["agent"], []).append(episode)
    agents = list(by_agent) or ["(no episodes)"]
    columns = min(len(agents), 3)
    rows = -(-len(agents) // columns)
    figure = new_figure(panel_size * columns, panel_size * rows)
    axes = np.atleast_1d(figure.subplots(rows, columns, squeeze=False)).ravel()
    lines = _road_lines(road)
    outer = max(d for _, d in lines)
    inner_d = lines[0][1]
    for ax, agent in zip(axes, agents, strict=False):
        if len(lines) > 1:  # the road surface between the centre line and the edge
            inner, edge = lines[0][0], lines[-1][0]
            ring = np.vstack([inner, edge[::-1]])
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
        ax.set_title(f"{agent}: {len(log)} incident(s) in {runs} episode(s)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.legend(loc="best", fontsize="small")
    for ax in axes[len(agents):]:
        ax.set_visible(False)
    return figure


def first_traces(episodes: Iterable[dict[str, Any]]) -> dict[str, EpisodeTrace]:
    """The trace of each agent's first episode that has one: ``{"agent (seed n)": trace}``."""
    chosen: dict[str, tuple[int, EpisodeTrace]] = {}
    for episode in episodes:
        trace = episode.get(TRACE_KEY)
        if trace is not None and episode["agent"] not in chosen:
            chosen[episode["agent"]] = (episode["seed"], trace)
    return {f"{agent} (seed {seed})": trace for agent, (seed, trace) in chosen.items()}


def write_plots(output: Path, episodes: Sequence[dict[str, Any]], road: Any = None,
                limits: Limits = Limits()) -> list[Path]:
    """Write the three plots to ``output`` (the map only with a ``road``); their paths."""
    written = []
    traces = first_traces(episodes)
    if traces:
        written.append(save_figure(profile_figure(traces, limits), output / PROFILE_FILE))
    written.append(save_figure(lap_time_figure(episodes), output / LAP_TIME_FILE))
    if road is not None:
        written.append(save_figure(incident_map_figure(road, episodes),
                                   output / INCIDENT_MAP_FILE))
    return written
