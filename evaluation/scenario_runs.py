"""``evaluate.py --scenario PATH``: every agent on each scenario, pass or fail with the reason.

``PATH`` is a scenario file (YAML, ``docs/scenarios.md``), a folder of them (every
``*.yaml`` in it, in name order; ``sdc_gym/scenarios/library`` is the packaged library), or
an ``incidents.json`` of an earlier run, whose reports with a replay snapshot become replay
scenarios (:func:`sdc_gym.scenarios.replay.incident_scenario`), each run with the env config
of the run it came from. Every (scenario, agent, seed) is one episode; its verdict is the
scenario's (``summary["scenario"]``). Written atomically to the run's folder:
``scenarios.csv`` (one row per episode) and ``scenarios.json`` (the rows with every
episode's summary and incident log).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sdc_evaluation.episodes import REPORTS_KEY, EpisodeSpec
from sdc_evaluation.files import (
    INCIDENTS_FILE,
    atomic_write_text,
    csv_text,
    write_incident_reports,
)
from sdc_evaluation.incident_reports import DEFAULT_HISTORY_S
from sdc_evaluation.runner import EpisodeBackend, EpisodeFailure, run_episodes
from sdc_evaluation.tables import TableData
from sdc_gym.config import ConfigError
from sdc_gym.scenarios.replay import incident_scenario
from sdc_gym.validation.scenarios import load_scenario

SCENARIOS_CSV = "scenarios.csv"
SCENARIOS_JSON = "scenarios.json"
COLUMNS = ["scenario", "agent", "seed", "passed", "reason", "termination_reason", "time",
           "distance", "source"]


@dataclass(frozen=True)
class ScenarioCase:
    """One scenario to run: its name, what the env's ``scenario`` key gets (a file path or
    a mapping), where it came from, and env config keys of its own (a replay's run)."""

    name: str
    scenario: Any
    source: str
    env_config: dict[str, Any]


def scenario_cases(path: Path) -> list[ScenarioCase]:
    """The scenarios of ``path`` (see the module docstring), each checked now: a bad file
    fails before any episode runs, naming the file, line and key."""
    if path.is_dir():
        files = sorted(path.glob("*.yaml"))
        if not files:
            raise SystemExit(f"--scenario {path}: the folder has no *.yaml scenario files")
        cases = [_file_case(file) for file in files]
        names = [case.name for case in cases]
        twice = sorted({name for name in names if names.count(name) > 1})
        if twice:
            raise SystemExit(f"--scenario {path}: scenario names must differ (a verdict is "
                             f"found by its name); {twice} are in more than one file")
        return cases
    if not path.is_file():
        raise SystemExit(f"--scenario {path}: no such file or folder")
    if path.suffix == ".json":
        return _replay_cases(path)
    return [_file_case(path)]


def _file_case(path: Path) -> ScenarioCase:
    try:
        scenario = load_scenario(path)
    except ConfigError as error:
        raise SystemExit(str(error)) from None
    return ScenarioCase(scenario.name, str(path), str(path), {})


def _replay_cases(path: Path) -> list[ScenarioCase]:
    try:
        reports = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise SystemExit(f"--scenario {path}: not a readable incidents.json ({error})") from None
    if not isinstance(reports, list):
        raise SystemExit(f"--scenario {path}: expected a JSON array of incident reports")
    if not reports:
        raise SystemExit(f"--scenario {path}: no incidents to replay (the run that wrote it "
                         "had none)")
    cases = []
    for index, report in enumerate(reports):
        if not isinstance(report, dict) or report.get("replay") is None:
            continue  # an incident of an env without snapshots (the track's)
        try:
            scenario = incident_scenario(report)
        except ValueError as error:
            raise SystemExit(f"--scenario {path}: report {index}: {error}") from None
        scenario["name"] = f"{index}_{scenario['name']}"
        try:
            load_scenario(scenario)
        except ConfigError as error:
            raise SystemExit(f"--scenario {path}: report {index}: {error}") from None
        config = dict(report["replay"]["replay"]["source"].get("env_config") or {})
        cases.append(ScenarioCase(scenario["name"], scenario, f"{path}[{index}]", config))
    if not cases:
        raise SystemExit(f"--scenario {path}: no incident report has a replay snapshot "
                         "(reports of the highway envs have one)")
    return cases


AgentSetup = Callable[[str, int], tuple[str, dict[str, dict[str, Any]]]]
"""``setup(name, seed) -> (spec, agent_options)``: how the agent ``name`` is built for the
episode of ``seed`` (an external planner's folder and log); default: the name is the spec."""


def scenario_specs(cases: list[ScenarioCase], agents: list[str], seeds: list[int],
                   env_id: str, env_config: dict[str, Any],
                   agent_setup: AgentSetup | None = None,
                   incident_history: float = DEFAULT_HISTORY_S) -> list[EpisodeSpec]:
    """One episode per (scenario, agent, seed), with incident reports (``incidents.json``,
    so that a scenario's incidents can be replayed in turn), no stop."""
    specs = []
    for case in cases:
        for agent in agents:
            for seed in seeds:
                spec, options = agent_setup(agent, seed) if agent_setup else (agent, {})
                specs.append(EpisodeSpec(
                    spec, env_id, seed,
                    {**env_config, **case.env_config, "scenario": case.scenario},
                    agent_options=options, incident_history=incident_history,
                    name=agent))
    return specs


def verdict_rows(cases: list[ScenarioCase], episodes: list[dict[str, Any]], agents: list[str],
                 seeds: list[int], failures: list[EpisodeFailure] = ()
                 ) -> list[dict[str, Any]]:
    """One row per (scenario, agent, seed), in the specs' order; an episode that failed
    (raised, or its worker died) is a FAIL with the failure's reason."""
    found = {((episode.get("scenario") or {}).get("name"), episode["agent"],
              episode["seed"]): episode for episode in episodes}
    failed = {(failure.agent, failure.seed): failure.reason for failure in failures}
    rows = []
    for case in cases:
        for agent in agents:
            for seed in seeds:
                episode = found.get((case.name, agent, seed))
                if episode is None:
                    rows.append({"scenario": case.name, "agent": agent, "seed": seed,
                                 "passed": False, "reason": "the episode failed: "
                                 + failed.get((agent, seed), "no result"),
                                 "termination_reason": "failed", "time": 0.0,
                                 "distance": 0.0, "source": case.source})
                    continue
                verdict = episode["scenario"]
                rows.append({
                    "scenario": case.name, "agent": agent, "seed": seed,
                    "passed": bool(verdict["passed"]),
                    "reason": episode.get("abort_message") or verdict["reason"],
                    "termination_reason": episode.get("termination_reason", ""),
                    "time": round(float(episode.get("time", 0.0)), 3),
                    "distance": round(float(episode.get("distance", 0.0)), 1),
                    "source": case.source})
    return rows


def verdict_table(rows: list[dict[str, Any]], title: str) -> TableData:
    table = TableData(title=title)
    for header, left in (("scenario", True), ("agent", True), ("seed", False),
                         ("verdict", True), ("reason", True)):
        table.add_column(header, left)
    for row in rows:
        table.add_row(row["scenario"], row["agent"], str(row["seed"]),
                      "PASS" if row["passed"] else "FAIL", row["reason"])
    return table


def run_scenarios(path: Path, agents: list[str], seeds: list[int], env_id: str,
                  env_config: dict[str, Any], workers: int, progress: bool,
                  backend: EpisodeBackend | None = None, agent_setup: AgentSetup | None = None,
                  incident_history: float = DEFAULT_HISTORY_S
                  ) -> tuple[list[dict[str, Any]], list[dict[str, Any]], list[EpisodeFailure]]:
    """Run every agent on every scenario of ``path`` (worker processes, or ``backend``:
    Ray); the verdict rows, the episodes and the failures. ``agents`` are names, built
    by ``agent_setup`` (default: each name is its spec)."""
    cases = scenario_cases(path)
    specs = scenario_specs(cases, agents, seeds, env_id, env_config, agent_setup,
                           incident_history)
    runs = run_episodes(specs, workers=workers, progress=progress, backend=backend)
    return (verdict_rows(cases, runs.results, agents, seeds, runs.failures), runs.results,
            runs.failures)


def write_scenario_run(folder: Path, rows: list[dict[str, Any]],
                       episodes: list[dict[str, Any]], run: dict[str, Any]) -> list[Path]:
    """``scenarios.csv``, ``scenarios.json`` and ``incidents.json`` (the episodes' incident
    reports, ``[]`` without any) into ``folder`` (atomically)."""
    folder.mkdir(parents=True, exist_ok=True)
    csv_path, json_path = folder / SCENARIOS_CSV, folder / SCENARIOS_JSON
    atomic_write_text(csv_path, csv_text(rows, COLUMNS))
    keep = [{key: value for key, value in episode.items()
             if key not in ("trace", "incident_reports")} for episode in episodes]
    atomic_write_text(json_path, json.dumps({"run": run, "rows": rows, "episodes": keep},
                                            indent=1, default=str) + "\n")
    if not any(REPORTS_KEY in episode for episode in episodes):  # --incident-history 0
        return [csv_path, json_path]
    write_incident_reports(folder / INCIDENTS_FILE, episodes)
    return [csv_path, json_path, folder / INCIDENTS_FILE]
