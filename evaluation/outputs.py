"""Everything an evaluation writes into its run folder, in one place.

:func:`write_run` writes the result files (:mod:`sdc_evaluation.files`), the plots
(:mod:`sdc_evaluation.plots`, :mod:`sdc_evaluation.profiles`, :mod:`sdc_evaluation.incident_plots`)
and ``report.html`` (:mod:`sdc_evaluation.report`). :data:`OWNED_NAMES` lists every name it
may write, which ``--overwrite`` clears first (:func:`sdc_evaluation.run_folders.prepare_output`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sdc_evaluation import files, incident_plots, plots, profiles
from sdc_evaluation.analysis import Analysis
from sdc_evaluation.episodes import REPORTS_KEY
from sdc_evaluation.report import REPORT_FILE, Report, ReportImage, write_report

PLANNER_LOGS = "planner_logs"  # written by external planners (sdc_agents.external.LOG_FOLDER)
STACK_LOGS = "stack_logs"  # written by capstone stacks (sdc_agents.capstone.LOG_FOLDER)
OWNED_NAMES: tuple[str, ...] = (
    files.EPISODES_FILE, files.AGENTS_FILE, files.COMPARISONS_FILE, files.SUMMARY_FILE,
    files.TRACES_FILE, files.INCIDENTS_FILE, plots.MEANS_FILE, plots.INCIDENTS_FILE,
    profiles.PROFILE_FILE, profiles.SPEED_TIME_FILE, incident_plots.INCIDENT_MAP_FILE,
    incident_plots.GALLERY_FOLDER, REPORT_FILE, PLANNER_LOGS, STACK_LOGS)
"""Every file and folder name an evaluation may write into its run folder."""


@dataclass(frozen=True)
class PlotOptions:
    """What the plots need from the env: its map, limits, the stop lines' distances from
    the start (track loop), the seed whose profiles to draw and the ego's box."""

    road: Any = None
    limits: plots.Limits = plots.DEFAULT_LIMITS
    stop_lines_m: Sequence[float] = ()
    plot_seed: int | None = None
    ego_shape: incident_plots.EgoShape = incident_plots.DEFAULT_EGO


def write_run(output: Path, episodes: list[dict[str, Any]], analysis: Analysis,
              title: str, settings: list[tuple[str, str]], run: dict[str, Any],
              plot_options: PlotOptions | None) -> list[Path]:
    """Write the run folder's files (no plots when ``plot_options`` is None); their paths.

    ``title`` heads the tables (env, seeds, laps); ``settings`` are the report's key-value
    lines; ``run`` goes into ``summary.json`` (with the statistics' settings).
    """
    written = files.write_results(output, episodes, analysis.rows,
                                  [c.as_dict() for c in analysis.comparisons],
                                  {**run, "statistics": analysis.settings.as_dict()})
    if files.write_traces(output / files.TRACES_FILE, episodes):
        written.append(output / files.TRACES_FILE)
    if any(REPORTS_KEY in episode for episode in episodes):  # off: --incident-history 0
        files.write_incident_reports(output / files.INCIDENTS_FILE, episodes)  # [] if none
        written.append(output / files.INCIDENTS_FILE)
    report = Report(title=f"sdc-gym evaluation: {output.resolve().name}", settings=settings,
                    tables=analysis.tables(title),
                    verdicts=analysis.verdicts())
    if plot_options is not None:
        figures = write_plots(output, episodes, analysis, plot_options)
        written += [image.path for image in figures]
        report.plots = figures
        reports = files.incident_reports(episodes)
        gallery = incident_plots.write_gallery(output / incident_plots.GALLERY_FOLDER,
                                               reports, plot_options.road, analysis.labels,
                                               ego_shape=plot_options.ego_shape)
        report.gallery = [ReportImage(path, _gallery_caption(entry, analysis.labels))
                          for entry, path in gallery]
        if reports:
            shown = len(gallery)
            report.gallery_note = (f"{len(reports)} incident(s); " + (
                f"the first {shown} drawn" if shown < len(reports) else "all drawn")
                + f", files in {incident_plots.GALLERY_FOLDER}/.")
            written.append(output / incident_plots.GALLERY_FOLDER)
    written.append(write_report(output / REPORT_FILE, report))
    return written


def _gallery_caption(report: dict[str, Any], labels: dict[str, str]) -> str:
    return (f"{labels.get(report['agent'], report['agent'])} seed {report['seed']}: "
            f"{report['kind']} at {report.get('time', 0.0):.2f} s")


def summary_plots(output: Path, analysis: Analysis) -> list[ReportImage]:
    """``means.png`` and ``incidents.png`` (a run's or runs side by side), with captions."""
    return [
        ReportImage(plots.save_figure(plots.means_figure(analysis.rows, analysis.samples),
                                      output / plots.MEANS_FILE),
                    "mean speed and lap time per agent, 95 % bootstrap intervals"),
        ReportImage(plots.save_figure(plots.incidents_figure(analysis.rows),
                                      output / plots.INCIDENTS_FILE),
                    "incidents by kind, with the rate per 100 miles [95 % Garwood interval]"),
    ]


def write_plots(output: Path, episodes: list[dict[str, Any]], analysis: Analysis,
                options: PlotOptions) -> list[ReportImage]:
    """The plots as files, with their captions for the report."""
    images = summary_plots(output, analysis)
    seeds = [episode["seed"] for episode in episodes]
    seed = options.plot_seed if options.plot_seed is not None else (seeds[0] if seeds else 0)
    traces = profiles.traces_for_seed(episodes, seed, analysis.labels)
    for path in profiles.write_profiles(output, traces, options.limits, options.stop_lines_m,
                                        f"seed {seed}"):
        images.append(ReportImage(path, f"{path.stem.replace('_', ' ')}, seed {seed}"))
    if options.road is not None:
        images.append(ReportImage(plots.save_figure(
            incident_plots.incident_map_figure(options.road, episodes, analysis.labels),
            output / incident_plots.INCIDENT_MAP_FILE), "incidents on the loop, by agent"))
    return images
