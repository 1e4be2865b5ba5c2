"""Evaluate driving agents on an sdc-gym env: lap times, incidents, plots, endurance.

    python evaluate.py                       # DEFAULT_AGENTS, default highway, 3 seeds, 1 lap
    python evaluate.py --agents lane_keeping --episodes 5 --laps 2 --workers 2
    python evaluate.py --seeds 3 5 8         # these seeds instead of --seed + --episodes
    python evaluate.py --config configs/highway_dense_traffic.yaml --output results/dense
    python evaluate.py --map ../shared/data/udacity/path_planning/highway_map.csv  # original map
    python evaluate.py --endurance 50        # 50 laps in ONE episode, driving on after incidents
    python evaluate.py --agent "external:./path_planning" --planner-cwd build \
        --planner-map ../data/highway_map.csv   # a planner for the original simulator

Prints a table per agent (laps, mean and best lap time, mean speed, miles without incident,
incidents by kind, max acceleration and jerk) and writes to the output folder, atomically:

    episodes.csv       one row per episode
    summary.json       per-agent rows and every episode's summary (with its incident_log)
    traces.npz         per-step time, distance, speed, acceleration, jerk of every episode
                       (arrays "agent/seed/field"; agents.evaluation.load_traces reads it)
    profiles.png       speed (mph), acceleration and jerk over distance, first seed per agent
    lap_times.png      every lap time per agent over a box plot
    incident_map.png   the loop with each agent's incidents marked by kind
    incidents.json     each incident with the last seconds of the ego and nearby cars
    planner_logs/      the output of external planners (agents "external:COMMAND")

Endurance mode drives ``N`` laps in one episode per (agent, seed) with
``terminate_on_collision`` off, so incidents are counted and the car drives on, and reports
the distance without incident (longest stretch and at the end, miles) and the wall time,
next to the seed planner's record of 276.53 miles.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import yaml
from rich.console import Console

from agents import external
from agents.evaluation import (
    SEED_RECORD_MILES,
    EpisodeSpec,
    aggregate,
    endurance_table,
    results_table,
    run_episodes,
    write_incident_reports,
    write_results,
    write_traces,
)
from agents.incident_reports import DEFAULT_HISTORY_S
from agents.registry import AGENT_KINDS, AGENTS, parse_agent_spec
from sdc_gym.metrics import IncidentRules
from sdc_gym.units import METERS_PER_MILE

DEFAULT_ENV = "sdc_gym/HighwayLoop-v0"
COMMITTED_POLICY = "dqn:agents/highway/policies/dqn_highway.zip"
"""The committed highway behavior policy (DQN on ``HighwayLoopBehavior-v0``; its training
config and command are in ``dqn_highway.yaml`` beside it)."""
DEFAULT_AGENTS: tuple[str, ...] = ("fsm_conservative", "fsm_bold", COMMITTED_POLICY,
                                   "lane_keeping")
"""Agents compared on the highway when ``--agents`` is not given: the seed's planner in both
styles, the committed RL behavior policy in its place, and the lane-keeping baseline."""
DEFAULT_TRACK_AGENTS: tuple[str, ...] = ("dbw_ground_truth", "dbw_cnn")
"""Agents compared on the track loop when ``--agents`` is not given: the drive-by-wire stack
with the env's light states and with the committed CNN on the camera image."""
TRACK_ENVS = ("sdc_gym/TrackLoop-v0",)
DEFAULT_EPISODES = 3
SECONDS_PER_LAP = 1000.0
"""``max_duration`` per lap when the config does not set one (endurance and multi-lap runs
would otherwise be truncated by the env's default 600 s)."""


def load_config(path: Path | None) -> tuple[str | None, dict[str, Any]]:
    """A YAML file with optional ``env`` (an env id) and ``config`` (env config overrides)."""
    if path is None:
        return None, {}
    if not path.is_file():
        raise SystemExit(f"{path}: no such config file")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    except yaml.YAMLError as error:
        raise SystemExit(f"{path}: not valid YAML: {error}") from None
    if not isinstance(data, dict) or set(data) - {"env", "config"}:
        raise SystemExit(f"{path}: expected a mapping with keys 'env' and/or 'config'")
    config = data.get("config") or {}
    if not isinstance(config, dict):
        raise SystemExit(f"{path}: 'config' must be a mapping of env config keys")
    return data.get("env"), dict(config)


def agent_spec(text: str) -> str:
    """``--agents`` values: a registered name or a ``kind:argument`` spec."""
    try:
        parse_agent_spec(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return text


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--agents", "--agent", nargs="+", default=None, type=agent_spec,
                        metavar="AGENT",
                        help=f"agents to compare, of: {', '.join(sorted(AGENTS))}, or "
                             f"{' '.join(kind + ':ARGUMENT' for kind in sorted(AGENT_KINDS))} "
                             "(e.g. 'external:./path_planning') "
                             f"(default: {' '.join(DEFAULT_AGENTS)} on the highway, "
                             f"{' '.join(DEFAULT_TRACK_AGENTS)} on the track loop)")
    parser.add_argument("--incident-history", type=float, default=DEFAULT_HISTORY_S,
                        metavar="S", help="seconds of ego and nearby-car history in each "
                        f"incident report, incidents.json (default {DEFAULT_HISTORY_S:g}; "
                        "0: no reports)")
    parser.add_argument("--stop-at-incident", action="store_true",
                        help="end each episode at its first incident")
    external.add_external_arguments(parser)
    parser.add_argument("--env", default=None,
                        help=f"env id (default: the config's, else {DEFAULT_ENV})")
    parser.add_argument("--config", type=Path, default=None, help="YAML file in configs/")
    parser.add_argument("--map", default=None, metavar="NAME_OR_FILE",
                        help="highway map: a built-in name (default, oval) or a file in the "
                             "original x y s dx dy format, e.g. the Udacity highway_map.csv "
                             "(overrides the config's)")
    parser.add_argument("--episodes", type=int, default=None,
                        help=f"episodes (seeds) per agent (default {DEFAULT_EPISODES}, "
                             "1 with --endurance)")
    parser.add_argument("--seed", type=int, default=None,
                        help="first seed; seeds are seed, seed + 1, ... (default 0)")
    parser.add_argument("--seeds", type=int, nargs="+", default=None, metavar="SEED",
                        help="explicit seeds, e.g. --seeds 3 5 8 (instead of --seed/--episodes)")
    parser.add_argument("--laps", type=int, default=None,
                        help="laps per episode (default: the config's, else 1)")
    parser.add_argument("--endurance", type=int, default=None, metavar="N",
                        help="drive N laps in one episode per agent and seed, counting "
                             "incidents and driving on; reports miles without incident")
    # A str, not a Path: Path("") is "." and would silently write into the working folder.
    parser.add_argument("--output", default="results/latest",
                        help="folder for the result files and plots")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                        help="parallel worker processes (default: one per CPU core, "
                             f"{os.cpu_count() or 1} here)")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    external.check_external_arguments(parser, args)
    if not args.incident_history >= 0:
        parser.error(f"--incident-history must be >= 0 s, got {args.incident_history}")

    for name in ("episodes", "laps", "endurance", "workers"):
        value = getattr(args, name)
        if value is not None and value < 1:
            parser.error(f"--{name} must be >= 1, got {value}")
    if args.seeds is not None and (args.seed is not None or args.episodes is not None):
        parser.error("--seeds lists the seeds: do not combine it with --seed or --episodes")
    if args.endurance is not None and args.laps is not None:
        parser.error("--endurance N sets the laps (N in one episode): drop --laps")
    if not args.output.strip():
        parser.error("--output must be a folder path, got an empty string")
    args.output = Path(args.output)
    if args.output.exists() and not args.output.is_dir():
        parser.error(f"--output {args.output} exists and is not a folder")
    if args.agents is not None:
        args.agents = list(dict.fromkeys(args.agents))  # drop repeats, keep the order
    if args.seeds is None:
        episodes = args.episodes or (1 if args.endurance else DEFAULT_EPISODES)
        first = args.seed or 0
        args.seeds = list(range(first, first + episodes))
    else:
        args.seeds = list(dict.fromkeys(args.seeds))
    return args


def env_settings(args: argparse.Namespace) -> tuple[str, dict[str, Any]]:
    """The env id and config of the run: the YAML's, then the command line's overrides."""
    config_env, env_config = load_config(args.config)
    env_id = args.env or config_env or DEFAULT_ENV
    if args.map is not None:
        if env_id in TRACK_ENVS:
            raise SystemExit(f"--map is for the highway envs; {env_id} takes its track from "
                             "the config's 'track' key")
        env_config["map"] = args.map
    if args.endurance is not None:
        env_config["laps"] = args.endurance
        env_config["terminate_on_collision"] = False
        env_config["max_duration"] = SECONDS_PER_LAP * args.endurance
    else:
        env_config["laps"] = args.laps or env_config.get("laps", 1)
        env_config.setdefault("max_duration", SECONDS_PER_LAP * env_config["laps"])
    external.apply_reply_latency(args, env_config)
    return env_id, env_config


def episode_specs(args: argparse.Namespace, env_id: str,
                  env_config: dict[str, Any]) -> list[EpisodeSpec]:
    """One episode per (agent, seed), with the incident and external planner options."""
    return [EpisodeSpec(agent, env_id, seed, (external.external_env_config(env_config)
                                              if external.is_external(agent) else env_config),
                        agent_options=({external.EXTERNAL_KIND: external.external_options(
                            args, agent, seed)} if external.is_external(agent) else {}),
                        incident_history=args.incident_history,
                        stop_at_incident=args.stop_at_incident)
            for agent in args.agents for seed in args.seeds]


def probe_env(env_id: str, env_config: dict[str, Any]) -> tuple[Any, IncidentRules]:
    """The env's road or track (for the incident map, ``None`` without one) and rules.

    Also validates the config before any worker starts: a bad key fails here, once.
    """
    env = gym.make(env_id, config=env_config)
    try:
        unwrapped = env.unwrapped
        road = getattr(unwrapped, "road", None) or getattr(unwrapped, "track", None)
        return road, getattr(unwrapped, "rules", IncidentRules())
    finally:
        env.close()


def main(argv: list[str] | None = None) -> dict[str, Any]:
    """Run the evaluation; returns the per-agent rows, episodes and files written."""
    args = parse_args(argv)
    env_id, env_config = env_settings(args)
    if args.agents is None:
        args.agents = list(DEFAULT_TRACK_AGENTS if env_id in TRACK_ENVS else DEFAULT_AGENTS)
    try:
        road, rules = probe_env(env_id, env_config)
    except (gym.error.Error, ValueError, TypeError) as error:
        raise SystemExit(f"cannot make {env_id} with config {env_config}: {error}") from None
    specs = episode_specs(args, env_id, env_config)
    workers = external.fixed_port_workers(args, args.agents, args.workers)
    console = Console()
    if not console.is_terminal:  # logs and CI: do not squeeze the table into 80 columns
        console = Console(width=260)

    started = time.perf_counter()
    with external.planner_maps(args, road):
        episodes = run_episodes(specs, workers=workers, progress=not args.no_progress)
    wall = time.perf_counter() - started

    rows = aggregate(episodes)
    write_results(args.output, episodes, rows)
    files = [args.output / "summary.json", args.output / "episodes.csv"]
    if write_traces(args.output / "traces.npz", episodes):
        files.append(args.output / "traces.npz")
    if write_incident_reports(args.output / "incidents.json", episodes):
        files.append(args.output / "incidents.json")
    if not args.no_plots:
        from agents.plots import Limits, write_plots

        files += write_plots(args.output, episodes, road, Limits.from_rules(rules))

    laps = env_config["laps"]
    mode = f"endurance, {laps} laps in one episode" if args.endurance else f"{laps} lap(s)"
    seeds = " ".join(map(str, args.seeds))
    console.print(results_table(rows, f"{env_id}: seed(s) {seeds} x {mode}"))
    if args.endurance:
        console.print(endurance_table(episodes, f"endurance: {laps} laps, "
                                                "incidents counted, driving on"))
        best = max(episode["longest_distance_without_incident"] for episode in episodes)
        console.print(f"best distance without incident: {best / METERS_PER_MILE:.2f} miles "
                      f"(seed planner's record: {SEED_RECORD_MILES:.2f} miles)")
    for episode in episodes:  # faults of external planners, stops at an incident
        if episode.get("abort_message"):
            console.print(f"{episode['agent']} seed {episode['seed']} ended early, "
                          f"{episode['termination_reason']}: {episode['abort_message']}",
                          markup=False, highlight=False)
    console.print(f"{len(episodes)} episode(s) in {wall:.1f} s wall time; results: "
                  + ", ".join(str(path) for path in files))
    return {"rows": rows, "episodes": episodes, "files": files}


if __name__ == "__main__":
    main()
