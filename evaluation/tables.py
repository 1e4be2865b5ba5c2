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
HTML table in the report (:mod:`sdc_evaluation.report`), with the same text. Names (agents,
scenarios) are never split: when a table would not fit the terminal with them whole, the
longest are printed as keys ``(1)``, ``(2)``, ... with each full name under the table.
"""

from __future__ import annotations

import re
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import scipy.stats
from rich import box
from rich.table import Table

from sdc_evaluation.verdicts import Comparison
from sdc_gym.units import METERS_PER_MILE

SEED_RECORD_MILES = 276.53
"""Distance without incident of the seed's rule-based planner, miles (to beat)."""

NAME_COLUMNS = ("agent", "scenario")
"""Headers of the columns that hold names (never split in the printed tables)."""

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
    names: set[str] = field(default_factory=lambda: set(NAME_COLUMNS))
    """Columns of names, never split (:meth:`rich` prints keys for the longest instead)."""

    def add_column(self, header: str, left: bool = False) -> None:
        self.headers.append(header)
        if left:
            self.left.add(header)

    def add_row(self, *cells: str) -> None:
        if len(cells) != len(self.headers):
            raise ValueError(f"{len(cells)} cells for {len(self.headers)} columns")
        self.rows.append(list(cells))

    def rich(self, width: int | None = None) -> Table:
        """The rich Table; with the terminal's ``width``, names too long to fit whole are
        replaced by keys, listed with the full names in the caption (:meth:`keyed`)."""
        data = self.keyed(width) if width is not None else self
        table = Table(title=data.title, caption=data.caption, box=box.SIMPLE_HEAD,
                      show_edge=False, pad_edge=False, title_justify="left",
                      caption_justify="left")
        for header in data.headers:  # prose gives way (wraps at spaces) before any figure
            left = header in data.left
            table.add_column(header, justify="left" if left else "right", overflow="fold",
                             no_wrap=not left or header in data.names)
        for row in data.rows:
            table.add_row(*row)
        return table

    def keyed(self, width: int) -> TableData:
        """This table with the longest names replaced by keys ``(1)``, ``(2)``, ... until
        it fits ``width`` columns with every name and figure whole (prose columns count
        with their longest word, as they wrap); the keys' names go under the caption."""
        named = [i for i, header in enumerate(self.headers) if header in self.names]
        keys: dict[str, str] = {}
        while True:
            candidate = self._with_keys(keys)
            if candidate.narrowest() <= width:
                return candidate
            waiting = sorted({row[i] for row in self.rows for i in named if row[i] not in keys},
                             key=lambda cell: (-len(cell), cell))
            if not waiting or len(waiting[0]) <= len(f"({len(keys) + 1})"):
                return candidate  # nothing left to shorten: rich folds what it must
            keys[waiting[0]] = f"({len(keys) + 1})"

    def narrowest(self) -> int:
        """The fewest terminal columns this table prints in with every name and figure
        whole (prose columns wrap at spaces: their longest word), as :meth:`rich` lays it
        out: one space of padding on each inner side of a column, and the box's one-column
        rule between columns."""
        widths = []
        for i, header in enumerate(self.headers):
            cells = [header, *(row[i] for row in self.rows)]
            prose = header in self.left and header not in self.names
            widths.append(max(len(word) for cell in cells for word in cell.split() or [""])
                          if prose else max(len(cell) for cell in cells))
        return sum(widths) + 3 * (len(widths) - 1)

    def _with_keys(self, keys: dict[str, str]) -> TableData:
        if not keys:
            return self
        named = {i for i, header in enumerate(self.headers) if header in self.names}
        rows = [[keys.get(cell, cell) if i in named else cell for i, cell in enumerate(row)]
                for row in self.rows]
        legend = "\n".join(f"{key} {name}" for name, key in keys.items())
        caption = f"{self.caption}\n{legend}" if self.caption else legend
        return TableData(self.title, caption, list(self.headers), set(self.left), rows,
                         set(self.names))


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


FEW_SEEDS = 5
"""Below this many episodes an agent's ``n`` is marked: too few seeds to decide."""
FEW_SEEDS_MARK = "*"


def few_seeds_note(episodes: int) -> str:
    """The key table's footnote for an agent with ``episodes`` < :data:`FEW_SEEDS`: how wide
    its t interval is in units of one seed's spread."""
    if episodes < 2:
        return f"{FEW_SEEDS_MARK} one seed: no interval, nothing to decide"
    half_width = float(scipy.stats.t.ppf(0.975, episodes - 1)) / episodes ** 0.5
    return (f"{FEW_SEEDS_MARK} under {FEW_SEEDS} seeds: too few to decide, the interval is "
            f"mean ± {half_width:.1f} s.d. of one seed at n = {episodes}")


def key_table(rows: list[dict[str, Any]], title: str) -> TableData:
    """The key columns with their 95 % intervals (fits 80 columns; see the caption). An
    ``n`` under :data:`FEW_SEEDS` is marked, the caption says why: on the intervals'
    headers when every agent has so few (the default 3 seeds: the 80 columns have no room
    for a mark beside each n), else beside each such ``n``."""
    counts = [row["episodes"] for row in rows]
    fewest = min(counts, default=FEW_SEEDS)
    caption = "95% CI: Student t over seeds; incidents: Garwood; --wide: all"
    if fewest < FEW_SEEDS:
        caption += "\n" + few_seeds_note(fewest)
    every_row = bool(counts) and max(counts) < FEW_SEEDS
    table = _table(title, caption=caption)
    mark = FEW_SEEDS_MARK * every_row
    for header, left in (("agent", True), ("n", False), (f"mph [95% CI]{mark}", False),
                         (f"lap s [95% CI]{mark}", False), ("incidents/100mi", False)):
        _column(table, header, left)
    for row in rows:
        few = FEW_SEEDS_MARK if row["episodes"] < FEW_SEEDS and not every_row else ""
        table.add_row(
            row["label"], f"{row['episodes']}{few}",
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
                   "that an episode of the first agent is faster than one of the second; "
                   "seeds to decide: per agent, at 80% power, from the spread measured")
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


def challenge_table(rows: list[dict[str, Any]]) -> TableData:
    """Timed open-road runs (:mod:`sdc_evaluation.challenge`'s columns): per agent the runs
    finished, the mean challenge time [95 % CI], the best; every run's verdict in the
    caption (agent seed: verdict)."""
    lines = [f"{row['label']} seed {seed}: {text}" for row in rows
             if "challenge_time" in row for seed, text in row["challenge_verdicts"]]
    result = TableData(title="challenge time (the target's distance, without incident)",
                       caption="; ".join(lines))
    for header, left in (("agent", True), ("finished", False), ("time s [95% CI]", False),
                         ("best s", False)):
        result.add_column(header, left)
    for row in rows:
        if "challenge_time" not in row:
            continue
        result.add_row(row["label"], f"{row['challenge_finished']}/{row['challenge_runs']}",
                       with_interval(row["challenge_time"], row["challenge_time_ci"], 2),
                       number(row["challenge_best_time"], 2))
    return result
