"""Runs side by side: ``evaluate.py compare RUN_A RUN_B ...``.

Each run folder's ``summary.json`` holds every episode; the episodes of all runs are
analysed together (:func:`sdc_evaluation.analysis.analyse`), each agent of each run as its own
group named ``run/agent``, with the same statistics as a single run. Verdicts compare the
same agent across runs (what changed between them); when no agent is in two runs, every
pair. Runs of different envs or configs are still compared, with a warning naming what
differs.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rich.console import Console

from sdc_evaluation import files, statistics
from sdc_evaluation.analysis import Analysis, analyse, same_agent_pairs, terminal_output
from sdc_evaluation.outputs import summary_plots
from sdc_evaluation.report import REPORT_FILE, Report, write_report
from sdc_evaluation.summary import unique_labels


def run_names(folders: Sequence[Path]) -> list[str]:
    """A short unique name per run folder: its resolved name (``results/latest`` becomes
    the run it points to), with the parent folder when two names are equal."""
    resolved = [Path(folder).resolve() for folder in folders]
    names = [path.name for path in resolved]
    if len(set(names)) < len(names):
        names = [f"{path.parent.name}/{path.name}" for path in resolved]
    if len(set(names)) < len(names):
        raise SystemExit(f"compare: the same run folder is given twice: {list(map(str, folders))}")
    return names


def _differences(summaries: Sequence[dict[str, Any]], names: Sequence[str]) -> list[str]:
    """What differs between the runs' settings (env id, env config, laps)."""
    keys = ("env_id", "env_config")
    warnings = []
    for key in keys:
        values = [summary.get("run", {}).get(key) for summary in summaries]
        if any(value != values[0] for value in values[1:]):
            shown = ", ".join(f"{name}: {value}" for name, value in zip(names, values,
                                                                        strict=True))
            warnings.append(f"warning: the runs differ in {key} ({shown})")
    return warnings


def compare_runs(folders: Sequence[Path],
                 settings: statistics.Settings = statistics.DEFAULT_SETTINGS
                 ) -> tuple[Analysis, list[str], list[dict[str, Any]]]:
    """The analysis of the runs' episodes together, the warnings, and the episodes (each
    agent renamed ``run/agent``)."""
    if len(folders) < 2:
        raise SystemExit("compare: give at least two run folders")
    summaries = [files.load_summary(Path(folder)) for folder in folders]
    names = run_names(folders)
    episodes: list[dict[str, Any]] = []
    labels: dict[str, str] = {}
    groups: list[tuple[str, str]] = []
    for name, summary in zip(names, summaries, strict=True):
        short = unique_labels(list(dict.fromkeys(e["agent"] for e in summary["episodes"])))
        for episode in summary["episodes"]:
            group = f"{name}/{episode['agent']}"
            if group not in labels:
                labels[group] = f"{name}/{short[episode['agent']]}"
                groups.append((name, episode["agent"]))
            episodes.append({**episode, "agent": group})
    analysis = analyse(episodes, settings, labels, same_agent_pairs(groups))
    return analysis, _differences(summaries, names), episodes


def compare_main(folders: Sequence[Path], console: Console, wide: bool = False,
                 settings: statistics.Settings = statistics.DEFAULT_SETTINGS,
                 output: Path | None = None) -> dict[str, Any]:
    """Print the runs side by side; with ``output`` also write its CSV, JSON, plots and
    ``report.html`` there. Returns the rows, comparisons and files."""
    analysis, warnings, episodes = compare_runs(folders, settings)
    title = "runs side by side: " + ", ".join(run_names(folders))
    for warning in warnings:
        console.print(warning, markup=False, highlight=False)
    terminal_output(console, analysis, title, wide)
    written: list[Path] = []
    if output is not None:
        comparisons = [c.as_dict() for c in analysis.comparisons]
        written = files.write_results(output, episodes, analysis.rows, comparisons,
                                      {"compared": [str(f) for f in folders],
                                       "statistics": settings.as_dict()})
        images = summary_plots(output, analysis)
        written += [image.path for image in images]
        written.append(write_report(output / REPORT_FILE, Report(
            title=title, settings=[("runs", " ".join(map(str, folders)))],
            tables=analysis.tables(title), verdicts=analysis.verdicts(),
            notes=warnings, plots=images)))
        console.print(f"written to {output}: " + ", ".join(path.name for path in written),
                      markup=False, highlight=False)
    return {"rows": analysis.rows, "comparisons": analysis.comparisons, "files": written}
