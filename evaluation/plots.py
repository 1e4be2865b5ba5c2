"""The plots of an evaluation run, written as PNG files (used by ``evaluate.py``).

* ``means.png`` (:func:`means_figure`): mean speed and mean lap time per agent with their
  95 % intervals, every episode's value as a dot, the IQM as a diamond;
* ``incidents.png`` (:func:`incidents_figure`): incidents by kind per agent, with the rate
  per 100 miles and its interval;
* ``profiles.png`` and ``speed_time.png`` (:mod:`sdc_evaluation.profiles`): speed,
  acceleration and jerk over distance, and speed over time, for one seed;
* ``incident_map.png`` and ``incident_gallery/`` (:mod:`sdc_evaluation.incident_plots`): the
  incidents on the loop, and a strip of top-down snapshots before each one.

Figures are built with the object-oriented API on the Agg canvas (no ``pyplot``, no global
backend switch, nothing kept alive between calls) and written atomically like the other
result files. Agents are labelled by their short labels (``row["label"]``) and drawn in
the order of the run, top to bottom where they are on the y axis (long names never
collide there).
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator
from numpy.typing import NDArray

from sdc_evaluation.files import atomic_write_bytes
from sdc_evaluation.summary import AgentSamples
from sdc_evaluation.tables import rate_with_interval
from sdc_gym.metrics import INCIDENT_KINDS, IncidentRules
from sdc_gym.units import MPS_TO_MPH

PLOT_POINTS = 5000
"""Most points drawn per line: longer traces are decimated (keeping each bucket's min and
max, so that spikes above a limit stay visible)."""

MEANS_FILE = "means.png"
INCIDENTS_FILE = "incidents.png"

KIND_STYLE: dict[str, tuple[str, str]] = {
    "collision": ("X", "tab:red"),
    "acceleration": ("^", "tab:orange"),
    "jerk": ("v", "tab:purple"),
    "speed": ("o", "tab:blue"),
    "lane": ("s", "tab:green"),
    "off_road": ("D", "tab:brown"),
    "red_light": ("P", "crimson"),
}
"""Marker and colour of each incident kind (map, bars, gallery)."""

LINE_STYLES = ("-", "--", "-.", ":")
"""Line styles cycled over agents, so that agents whose lines coincide stay visible."""


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


DEFAULT_LIMITS = Limits()


def new_figure(width: float, height: float) -> Figure:
    """A figure on its own Agg canvas (independent of pyplot and its backend)."""
    figure = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def png_bytes(figure: Figure, dpi: int = 110) -> bytes:
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi)
    return buffer.getvalue()


def save_figure(figure: Figure, path: Path, dpi: int = 110) -> Path:
    """Render ``figure`` as PNG and write it atomically to ``path``."""
    atomic_write_bytes(path, png_bytes(figure, dpi))
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


def _interval_panel(ax: Any, samples: Sequence[AgentSamples], rows: Sequence[dict[str, Any]],
                    values: str, mean: str, iqm: str, xlabel: str) -> None:
    """One horizontal point chart: agents on y, dots per episode, mean with its CI bar."""
    jitter = np.random.default_rng(0)
    positions = np.arange(len(rows))[::-1]  # the first agent on top
    for position, sample, row in zip(positions, samples, rows, strict=True):
        episode_values = getattr(sample, values)
        if len(episode_values):
            ax.scatter(episode_values, position + jitter.uniform(-0.18, 0.18,
                                                                 len(episode_values)),
                       s=14, color="0.6", alpha=0.7, zorder=2,
                       label="episodes" if position == positions[0] else None)
        if row[mean] is None:
            ax.text(0.5, position, "no lap", transform=ax.get_yaxis_transform(),
                    ha="center", va="center", color="0.4")
            continue
        ci = row[f"{mean}_ci"]
        error = None if ci is None else [[row[mean] - ci[0]], [ci[1] - row[mean]]]
        ax.errorbar([row[mean]], [position], xerr=error, fmt="o", color="tab:blue",
                    markersize=7, capsize=5, linewidth=2, zorder=3,
                    label="mean [95 % CI]" if position == positions[0] else None)
        ax.scatter([row[iqm]], [position], marker="D", s=28, facecolors="none",
                   edgecolors="tab:orange", zorder=4,
                   label="IQM" if position == positions[0] else None)
    ax.set_yticks(positions, [row["label"] for row in rows])
    ax.set_ylim(-0.6, len(rows) - 0.4)
    ax.set_xlabel(xlabel)
    ax.grid(axis="x", alpha=0.3)


def means_figure(rows: Sequence[dict[str, Any]], samples: Sequence[AgentSamples]) -> Figure:
    """Mean speed and mean lap time per agent with 95 % intervals (see the module doc)."""
    with_laps = any(row["mean_lap_time"] is not None for row in rows)
    figure = new_figure(11.0 if with_laps else 6.0, 1.2 + 0.55 * max(len(rows), 1))
    axes = figure.subplots(1, 2 if with_laps else 1, sharey=True, squeeze=False)[0]
    _interval_panel(axes[0], samples, rows, "speed_mph", "mean_speed_mph", "iqm_speed_mph",
                    "mean speed (mph)")
    axes[0].set_title("speed per episode, mean [95 % CI]", fontsize="medium")
    if with_laps:
        _interval_panel(axes[1], samples, rows, "lap_time", "mean_lap_time", "iqm_lap_time",
                        "lap time (s)")
        axes[1].set_title("lap time per episode, mean [95 % CI]", fontsize="medium")
    if rows:
        axes[0].legend(loc="best", fontsize="small")
    return figure


def incidents_figure(rows: Sequence[dict[str, Any]]) -> Figure:
    """Incidents by kind per agent as stacked horizontal bars, each bar labelled with the
    rate per 100 miles and its interval."""
    figure = new_figure(9.0, 1.3 + 0.5 * max(len(rows), 1))
    ax = figure.subplots()
    positions = np.arange(len(rows))[::-1]
    kinds = list(dict.fromkeys([*INCIDENT_KINDS, *(k for row in rows for k in row["incidents"])]))
    left = np.zeros(len(rows))
    for kind in kinds:
        counts = np.array([row["incidents"].get(kind, 0) for row in rows], dtype=np.float64)
        if not counts.any():
            continue
        ax.barh(positions, counts, left=left, color=KIND_STYLE.get(kind, ("*", "0.5"))[1],
                edgecolor="black", linewidth=0.4, label=kind, height=0.6)
        left += counts
    largest = max(left.max(initial=0.0), 1.0)
    for position, row, total in zip(positions, rows, left, strict=True):
        text = (f"{row['incident_total']} in {row['miles']:.1f} mi: "
                + rate_with_interval(row["incidents_per_100_miles"],
                                     row["incidents_per_100_miles_ci"]) + " per 100 mi")
        ax.text(total + 0.02 * largest, position, text, va="center", fontsize="small")
    ax.set_xlim(0, largest * 1.9)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # counts
    ax.set_yticks(positions, [row["label"] for row in rows])
    ax.set_ylim(-0.6, len(rows) - 0.4)
    ax.set_xlabel("incidents (all episodes)")
    total = sum(row["incident_total"] for row in rows)
    ax.set_title("incidents by kind" + ("" if total else ": none"), fontsize="medium")
    if total:
        ax.legend(loc="lower right", fontsize="small")
    ax.grid(axis="x", alpha=0.3)
    return figure
