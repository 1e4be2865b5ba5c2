"""Speed profiles of one seed: over distance (with the limits) and over time.

* :func:`profile_figure` (``profiles.png``): speed (mph), total acceleration and jerk over
  distance (km), the limits dashed; on the track loop the stop lines as dotted verticals;
* :func:`speed_time_figure` (``speed_time.png``): speed over time (min), where time spent
  standing shows as a flat line at zero.

One line per agent, in cycling line styles (:data:`~sdc_evaluation.plots.LINE_STYLES`) and
thinning widths, so that agents that drive identically still show as two lines; an agent
whose trace equals an earlier one's is labelled ``"b (= a)"``. Where the trace has the
light the car drives up to (the track loop: within 100 m of its stop line), a strip per
agent above the speed panel shows its state (red, yellow, green; grey: no line near)
along the axis: standing at red is then visible.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from sdc_evaluation.episodes import TRACE_KEY, EpisodeTrace
from sdc_evaluation.plots import (
    DEFAULT_LIMITS,
    LINE_STYLES,
    PLOT_POINTS,
    Limits,
    minmax_indices,
    new_figure,
    save_figure,
)
from sdc_gym.lights import GREEN, RED, UNKNOWN, YELLOW
from sdc_gym.units import MPS_TO_MPH

PROFILE_FILE = "profiles.png"
SPEED_TIME_FILE = "speed_time.png"

LIGHT_COLORS: dict[int, str] = {RED: "tab:red", YELLOW: "gold", GREEN: "tab:green",
                                UNKNOWN: "0.85"}


def traces_for_seed(episodes: Iterable[dict[str, Any]], seed: int,
                    labels: Mapping[str, str] | None = None) -> dict[str, EpisodeTrace]:
    """``{label: trace}`` of every agent's episode with ``seed`` (agents in run order); a
    trace equal to an earlier agent's is labelled ``"b (= a)"``."""
    labels = labels or {}
    chosen: dict[str, EpisodeTrace] = {}
    for episode in episodes:
        trace = episode.get(TRACE_KEY)
        if trace is None or episode["seed"] != seed:
            continue
        label = labels.get(episode["agent"], episode["agent"])
        twin = next((other for other, seen in chosen.items() if _same(trace, seen)), None)
        chosen[label if twin is None else f"{label} (= {twin.split(' (= ')[0]})"] = trace
    return chosen


def _same(a: EpisodeTrace, b: EpisodeTrace) -> bool:
    return len(a) == len(b) and all(np.array_equal(a.columns()[name], b.columns()[name])
                                    for name in ("time", "distance", "speed"))


def _style(index: int) -> dict[str, Any]:
    return {"linestyle": LINE_STYLES[index % len(LINE_STYLES)],
            "linewidth": max(1.6 - 0.35 * index, 0.6)}


def _light_strip(ax: Any, traces: Mapping[str, EpisodeTrace], axis: str, scale: float) -> None:
    """One row per agent: the state of the light ahead along ``axis`` (time or distance)."""
    names = list(traces)
    for row, name in enumerate(names):
        trace = traces[name]
        states = trace.light_state_near
        if states is None or not len(states):
            continue
        x = getattr(trace, axis) * scale
        changes = np.flatnonzero(np.diff(states)) + 1
        starts = np.concatenate([[0], changes])
        ends = np.concatenate([changes, [len(states) - 1]])
        for state in np.unique(states):
            keep = states[starts] == state
            spans = [(x[s], max(x[e] - x[s], 0.0)) for s, e in zip(starts[keep], ends[keep],
                                                                    strict=True)]
            ax.broken_barh(spans, (row - 0.4, 0.8),
                           color=LIGHT_COLORS.get(int(state), "0.85"), linewidth=0)
    ax.set_yticks(range(len(names)), [name.split(" (= ")[0] for name in names],
                  fontsize="x-small")
    ax.set_ylim(len(names) - 0.5, -0.5)
    ax.set_title("light ahead within 100 m (red / yellow / green; grey: no stop line near)",
                 fontsize="small")
    ax.tick_params(axis="x", labelbottom=False)


def _has_lights(traces: Mapping[str, EpisodeTrace]) -> bool:
    return any(trace.light_state_near is not None for trace in traces.values())


def profile_figure(traces: Mapping[str, EpisodeTrace], limits: Limits = DEFAULT_LIMITS,
                   max_points: int = PLOT_POINTS,
                   stop_lines_m: Sequence[float] = (), title: str = "") -> Figure:
    """Speed, total acceleration and jerk over distance (km): one line per label;
    ``stop_lines_m``: distances from the start of the stop lines, drawn dotted."""
    lights = _has_lights(traces)
    farthest = max((float(trace.distance[-1]) for trace in traces.values() if len(trace)),
                   default=0.0)
    stop_lines_m = [d for d in stop_lines_m if d <= farthest]
    figure = new_figure(10.0, 8.8 if lights else 8.0)
    ratios = ([0.25 + 0.12 * len(traces)] if lights else []) + [1.0, 1.0, 1.0]
    axes = figure.subplots(len(ratios), 1, sharex=True, height_ratios=ratios)
    if lights:
        _light_strip(axes[0], traces, "distance", 1e-3)
        axes = axes[1:]
    panels = (("speed", MPS_TO_MPH, "speed (mph)", (limits.speed_mph,)),
              ("acceleration", 1.0, "total acceleration (m/s²)", (limits.acceleration,)),
              ("jerk", 1.0, "jerk (m/s³)", (limits.jerk, -limits.jerk)))
    for index, (label, trace) in enumerate(traces.items()):
        distance_km = trace.distance / 1000.0
        for ax, (name, scale, _, _) in zip(axes, panels, strict=True):
            values = getattr(trace, name) * scale
            keep = minmax_indices(values, max_points)
            ax.plot(distance_km[keep], values[keep], label=label, **_style(index))
    for ax, (_, _, ylabel, lines) in zip(axes, panels, strict=True):
        for value in lines:
            ax.axhline(value, color="black", linestyle="--", linewidth=1.0)
        for distance in stop_lines_m:
            ax.axvline(distance / 1000.0, color="0.3", linestyle=":", linewidth=0.8)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    heading = "speed, acceleration and jerk over distance (dashed: limits"
    heading += "; dotted: stop lines)" if len(stop_lines_m) else ")"
    axes[0].set_title(f"{title}: {heading}" if title else heading, fontsize="medium")
    axes[-1].set_xlabel("distance (km)")
    if traces:
        axes[0].legend(loc="lower right", fontsize="small")
    return figure


def speed_time_figure(traces: Mapping[str, EpisodeTrace], limits: Limits = DEFAULT_LIMITS,
                      max_points: int = PLOT_POINTS, title: str = "") -> Figure:
    """Speed (mph) over time (min): one line per label, the limit dashed."""
    lights = _has_lights(traces)
    figure = new_figure(10.0, 4.8 if lights else 3.8)
    if lights:
        strip, ax = figure.subplots(2, 1, sharex=True,
                                    height_ratios=[0.25 + 0.12 * len(traces), 1.0])
        _light_strip(strip, traces, "time", 1.0 / 60.0)
    else:
        ax = figure.subplots()
    for index, (label, trace) in enumerate(traces.items()):
        values = trace.speed * MPS_TO_MPH
        keep = minmax_indices(values, max_points)
        ax.plot(trace.time[keep] / 60.0, values[keep], label=label, **_style(index))
    ax.axhline(limits.speed_mph, color="black", linestyle="--", linewidth=1.0)
    ax.set_xlabel("time (min)")
    ax.set_ylabel("speed (mph)")
    ax.grid(alpha=0.3)
    heading = "speed over time (dashed: limit)"
    figure.suptitle(f"{title}: {heading}" if title else heading, fontsize="medium")
    if traces:
        ax.legend(loc="lower right", fontsize="small")
    return figure


def stop_line_distances(road: Any, start_s: float, laps: int) -> list[float]:
    """Distances from the start of every stop line over ``laps`` laps (none without)."""
    stop_s: NDArray[np.float64] | None = getattr(road, "stop_line_s", None)
    if stop_s is None or not len(stop_s):
        return []
    ahead = np.sort((np.asarray(stop_s) - start_s) % road.length)
    return [float(d + lap * road.length) for lap in range(laps) for d in ahead]


def write_profiles(output: Path, traces: Mapping[str, EpisodeTrace], limits: Limits,
                   stop_lines_m: Sequence[float], title: str) -> list[Path]:
    """``profiles.png`` and ``speed_time.png`` of ``traces``; their paths (none without)."""
    if not traces:
        return []
    return [save_figure(profile_figure(traces, limits, stop_lines_m=stop_lines_m,
                                       title=title), output / PROFILE_FILE),
            save_figure(speed_time_figure(traces, limits, title=title),
                        output / SPEED_TIME_FILE)]
