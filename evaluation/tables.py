"""The tables evaluate.py prints, as rich Tables that read in an 80-column terminal.

* :func:`key_table`: per agent the mean speed, the mean lap time and the incidents per
  100 miles, each with its 95 % interval;
* :func:`incidents_table`: incidents by kind per agent (printed when there are any);
* :func:`track_table`: red lights, stops and tracking on the track loop;
* :func:`wide_table`: every column in one table (``--wide``: about 200 columns);
* :func:`endurance_table`: distance without incident of endurance episodes;
* :func:`verdict_lines`: one line per agent pair (:mod:`sdc_evaluation.verdicts`).

Each returns a :class:`TableData` (title, headers, rows of text), which becomes a rich
Table (:meth:`TableData.rich`: the ``SIMPLE_HEAD`` box without vertical rules, cells that
fold instead of being cut with an ellipsis, so a narrow terminal gets every figure) or an
HTML table in the report (:mod:`sdc_evaluation.report`), with the same text.
"""

from __future__ import annotations

import re
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from rich import box
from rich.table import Table

from sdc_evaluation.verdicts import Comparison
from sdc_gym.units import METERS_PER_MILE

SEED_RECORD_MILES = 276.53
"""Distance without incident of the seed's rule-based planner, miles (to beat)."""

KIND_HEADERS: dict[str, str] = {
    "collision": "collision", "acceleration": "acc", "jerk": "jerk", "speed": "speed",
    "lane": "lane", "off_road": "off road", "red_light": "red light",
}
"""Short headers of the incident kinds (80 columns)."""


@dataclass
class TableData:
    """A table as text: ``left`` names the left-aligned columns (the rest are numbers)."""

    title: str | None = None
    caption: str | None = None
    headers: list[str] = field(default_factory=list)
    left: set[str] = field(default_factory=set)
    rows: list[list[str]] = field(default_factory=list)

    def add_column(self, header: str, left: bool = False) -> None:
        self.headers.append(header)
        if left:
            self.left.add(header)

    def add_row(self, *cells: str) -> None:
        if len(cells) != len(self.headers):
            raise ValueError(f"{len(cells)} cells for {len(self.headers)} columns")
        self.rows.append(list(cells))

    def rich(self) -> Table:
        table = Table(title=self.title, caption=self.caption, box=box.SIMPLE_HEAD,
                      show_edge=False, pad_edge=False, title_justify="left",
                      caption_justify="left")
        for header in self.headers:  # the names give way (fold) before any figure
            left = header in self.left
            table.add_column(header, justify="left" if left else "right", overflow="fold",
                             no_wrap=not left)
        for row in self.rows:
            table.add_row(*row)
        return table


def _table(title: str | None = None, caption: str | None = None) -> TableData:
    return TableData(title=title, caption=caption)


def _column(table: TableData, header: str, left: bool = False) -> None:
    table.add_column(header, left)


def number(value: float | None, digits: int) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def rate_number(value: float | None) -> str:
    """A rate in about 3 significant figures: 0, 2.95, 18.4, 123."""
    if value is None:
        return "-"
    if value == 0:
        return "0"
    return f"{value:.2f}" if value < 10 else f"{value:.1f}" if value < 100 else f"{value:.0f}"


def with_interval(value: float | None, ci: Sequence[float] | None, digits: int,
                  ci_digits: int | None = None) -> str:
    """``"46.14 [45.79, 46.50]"``; the value alone without an interval; ``"-"`` without
    a value."""
    if value is None:
        return "-"
    ci_digits = digits if ci_digits is None else ci_digits
    text = f"{value:.{digits}f}"
    if ci is not None:
        text += f" [{ci[0]:.{ci_digits}f}, {ci[1]:.{ci_digits}f}]"
    return text


def rate_with_interval(value: float | None, ci: Sequence[float] | None) -> str:
    if value is None:
        return "-"
    text = rate_number(value)
    if ci is not None:
        text += f" [{rate_number(ci[0])}, {rate_number(ci[1])}]"
    return text


def key_table(rows: list[dict[str, Any]], title: str) -> TableData:
    """The key columns with their 95 % intervals (fits 80 columns; see the caption)."""
    table = _table(title, caption="95% CI: bootstrap over seeds; incidents: Garwood; "
                              "--wide: all")
    for header, left in (("agent", True), ("n", False), ("mph [95% CI]", False),
                         ("lap s [95% CI]", False), ("incidents/100mi", False)):
        _column(table, header, left)
    for row in rows:
        table.add_row(
            row["label"], str(row["episodes"]),
            with_interval(row["mean_speed_mph"], row["mean_speed_mph_ci"], 2),
            with_interval(row["mean_lap_time"], row["mean_lap_time_ci"], 1, 0),
            rate_with_interval(row["incidents_per_100_miles"],
                               row["incidents_per_100_miles_ci"]))
    return table


def _kinds(rows: list[dict[str, Any]]) -> list[str]:
    return list(dict.fromkeys(kind for row in rows for kind in row["incidents"]))


def incidents_table(rows: list[dict[str, Any]]) -> TableData:
    """Incident counts by kind, with the miles they were counted over."""
    table = _table("incidents by kind")
    _column(table, "agent", left=True)
    kinds = _kinds(rows)
    for kind in kinds:
        _column(table, KIND_HEADERS.get(kind, kind))
    _column(table, "miles")
    for row in rows:
        table.add_row(row["label"], *[str(row["incidents"].get(kind, 0)) for kind in kinds],
                      f"{row['miles']:.1f}")
    return table


def track_table(rows: list[dict[str, Any]]) -> TableData:
    """Red lights, stops relative to their lines and tracking (track loop rows)."""
    table = _table("stop lines and tracking", caption="short / past: the farthest a stop "
                   "ended before / past its line (front bumper); lat acc: max, m/s²")
    for header, left in (("agent", True), ("red lights", False), ("stops", False),
                         ("short m", False), ("past m", False), ("CTE rms m", False),
                         ("lat acc", False)):
        _column(table, header, left)
    for row in rows:
        table.add_row(row["label"], str(row.get("red_light_violations", "-")),
                      str(row.get("stops", "-")), number(row.get("stop_short_max_m"), 2),
                      number(row.get("max_overshoot"), 2),
                      number(row.get("rms_cross_track_error"), 3),
                      number(row.get("max_lateral_acceleration"), 2))
    return table


def wide_table(rows: list[dict[str, Any]], title: str) -> TableData:
    """Every per-agent column in one table (about 200 columns wide)."""
    table = _table(title)
    kinds = _kinds(rows)
    track = any("stops" in row for row in rows)
    extra = ("stops", "short of line m", "overshoot m", "CTE rms m", "max lat acc") if track \
        else ()
    for header in ("agent", "laps", "mean lap s [95% CI]", "IQM lap s", "best lap s",
                   "mean mph [95% CI]", "IQM mph [95% CI]", "miles no incident",
                   "incidents/100 mi [95% CI]", *kinds, "max acc", "max jerk", *extra):
        _column(table, header, left=header == "agent")
    for row in rows:
        cells = [
            row["label"], str(row["laps"]),
            with_interval(row["mean_lap_time"], row["mean_lap_time_ci"], 1),
            number(row["iqm_lap_time"], 1), number(row["best_lap_time"], 1),
            with_interval(row["mean_speed_mph"], row["mean_speed_mph_ci"], 2),
            with_interval(row["iqm_speed_mph"], row["iqm_speed_mph_ci"], 2),
            f"{row['longest_miles_without_incident']:.2f}",
            rate_with_interval(row["incidents_per_100_miles"],
                               row["incidents_per_100_miles_ci"]),
            *[str(row["incidents"].get(kind, 0)) for kind in kinds],
            f"{row['max_acceleration']:.2f}", f"{row['max_jerk']:.2f}"]
        if track:
            cells += [str(row.get("stops", "-")), number(row.get("stop_short_max_m"), 2),
                      number(row.get("max_overshoot"), 2),
                      number(row.get("rms_cross_track_error"), 3),
                      number(row.get("max_lateral_acceleration"), 2)]
        table.add_row(*cells)
    return table


VERDICT_HEADING = ("verdicts: difference of mean mph [95% CI]; P(improvement): the chance "
                   "that an episode of the first agent is faster than one of the second")
"""What the verdict lines say (printed before them, in the report above them)."""


def verdict_lines(comparisons: Sequence[Comparison]) -> list[str]:
    """One sentence per comparison (:attr:`sdc_evaluation.verdicts.Comparison.verdict`), with
    its incident note when either agent had incidents."""
    return [comparison.verdict + (f"; {comparison.incident_note}"
                                  if comparison.incident_note else "")
            for comparison in comparisons]


def wrap_verdict(line: str, width: int) -> str:
    """A verdict wrapped to ``width`` at spaces, continuation lines indented; an interval
    ``[a, b]`` and ``P(improvement) p`` are never split."""
    glued = re.sub(r"\[[^\]]*\]|P\(improvement\) \S+|\bp \d\S*",
                   lambda match: match.group(0).replace(" ", _NBSP), line)
    return textwrap.fill(glued, width=width, subsequent_indent="    ",
                         break_long_words=False, break_on_hyphens=False).replace(_NBSP, " ")


_NBSP = "\u00a0"  # not whitespace to textwrap: glues the words it joins


def endurance_table(episodes: list[dict[str, Any]], title: str,
                    labels: dict[str, str] | None = None) -> TableData:
    """Endurance episodes: distance without incident (miles), wall time."""
    table = _table(title, caption=f"seed planner's record: {SEED_RECORD_MILES:.2f} miles "
                                  "without incident")
    for header in ("agent", "seed", "miles", "longest clean", "clean at end", "incidents",
                   "vs record", "sim time", "wall time", "end"):
        _column(table, header, left=header in ("agent", "end"))
    labels = labels or {}
    for episode in episodes:
        longest = episode["longest_distance_without_incident"] / METERS_PER_MILE
        table.add_row(
            labels.get(episode["agent"], episode["agent"]), str(episode["seed"]),
            f"{episode['distance'] / METERS_PER_MILE:.2f}", f"{longest:.2f}",
            f"{episode['distance_without_incident'] / METERS_PER_MILE:.2f}",
            str(episode["incident_total"]), f"{100.0 * longest / SEED_RECORD_MILES:.1f} %",
            duration(episode["time"]), duration(episode["wall_time"]),
            episode["termination_reason"])
    return table


def duration(seconds: float) -> str:
    if seconds < 60.0:
        return f"{seconds:.1f} s"
    minutes, rest = divmod(round(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}:{minutes:02d}:{rest:02d}" if hours else f"{minutes}:{rest:02d}"
