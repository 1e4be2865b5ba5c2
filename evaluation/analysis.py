"""From episodes to what a reader sees: rows, comparisons, tables and verdicts.

:func:`analyse` is used alike for one run (``evaluate.py``) and for runs side by side
(``evaluate.py compare``), so both show the same statistics; :func:`terminal_output`
prints it in 80 columns (or every column with ``wide``).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from itertools import combinations
from typing import Any

from rich.console import Console

from sdc_evaluation import statistics, tables
from sdc_evaluation.summary import AgentSamples, agent_samples, aggregate
from sdc_evaluation.verdicts import Comparison, compare_all, power_note


@dataclass(frozen=True)
class Analysis:
    """The per-agent rows (:func:`sdc_evaluation.summary.aggregate`), their samples and the
    comparisons of agent pairs."""

    rows: list[dict[str, Any]]
    samples: list[AgentSamples]
    comparisons: list[Comparison]
    settings: statistics.Settings

    @property
    def labels(self) -> dict[str, str]:
        return {sample.agent: sample.label for sample in self.samples}

    def verdicts(self) -> list[str]:
        """One line per comparison, then the power note (the seeds 0.5 mph needs)."""
        lines = tables.verdict_lines(self.comparisons)
        note = power_note(self.comparisons)
        return [*lines, note] if lines and note else lines

    def tables(self, title: str, wide: bool = False) -> list[tables.TableData]:
        """The key table, then incidents by kind (when any) and the track's table; or
        the one wide table."""
        if wide:
            return [tables.wide_table(self.rows, title)]
        result = [tables.key_table(self.rows, title)]
        if any(row["incident_total"] for row in self.rows):
            result.append(tables.incidents_table(self.rows))
        if any("stops" in row for row in self.rows):
            result.append(tables.track_table(self.rows))
        if any("challenge_time" in row for row in self.rows):
            result.append(tables.challenge_table(self.rows))
        return result


def analyse(episodes: Iterable[dict[str, Any]],
            settings: statistics.Settings = statistics.DEFAULT_SETTINGS,
            labels: dict[str, str] | None = None,
            pairs: Sequence[tuple[int, int]] | None = None) -> Analysis:
    """Rows, samples and comparisons (``pairs`` of agent indices; default all pairs)."""
    episodes = list(episodes)
    samples = agent_samples(episodes, labels)
    labels = {sample.agent: sample.label for sample in samples}
    rows = aggregate(episodes, settings, labels)
    return Analysis(rows, samples, compare_all(samples, settings, pairs), settings)


def same_agent_pairs(groups: Sequence[tuple[str, str]]) -> list[tuple[int, int]]:
    """Pairs of ``(run, agent)`` groups with the same agent in different runs; every pair
    when no agent is in more than one run."""
    pairs = [(i, j) for i, j in combinations(range(len(groups)), 2)
             if groups[i][1] == groups[j][1]]
    return pairs or list(combinations(range(len(groups)), 2))


def terminal_output(console: Console, analysis: Analysis, title: str,
                    wide: bool = False) -> None:
    """Print the tables and the verdicts."""
    for table in analysis.tables(title, wide):
        console.print(table.rich(console.width))
    lines = analysis.verdicts()
    for line in [tables.VERDICT_HEADING, *lines] if lines else []:
        # Wrapped at spaces here: rich must not split a name.
        console.print(tables.wrap_verdict(line, console.width), markup=False,
                      highlight=False, soft_wrap=True)
