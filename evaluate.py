"""Evaluate driving agents on an sdc-gym env: lap times, incidents, plots, endurance.

    python evaluate.py                       # DEFAULT_AGENTS, default highway, 3 seeds, 1 lap
    python evaluate.py --seeds $(seq 0 19) --wide   # 20 seeds, every column
    python evaluate.py --agents lane_keeping --episodes 5 --laps 2 --workers 2
    python evaluate.py --seeds 3 5 8         # these seeds instead of --seed + --episodes
    python evaluate.py --config configs/highway_dense_traffic.yaml --output results/dense
    python evaluate.py --map ../shared/data/udacity/path_planning/highway_map.csv  # original map
    python evaluate.py --endurance 50        # 50 laps in ONE episode, driving on after incidents
    python evaluate.py --agent "external:./path_planning" --planner-cwd build \
        --planner-map ../data/highway_map.csv   # a planner for the original simulator
    python evaluate.py --seeds $(seq 0 999) --ray auto   # Ray tasks on a running cluster
    python evaluate.py compare results/A results/B   # two runs side by side
    python evaluate.py --scenario sdc_gym/scenarios/library   # pass/fail per scenario
    python evaluate.py --scenario results/latest/incidents.json  # replay every incident

Prints, in 80 columns, per agent the mean speed, mean lap time and incidents per 100 miles,
each with its 95 % interval (Student's t over seeds, marked when under 5 seeds are too few
to decide; Garwood's exact interval for counts), incidents by kind when there are any, and
one verdict per agent pair ("A faster than B by D mph [low, high], P(improvement) p";
"no clear difference" when the interval spans 0, with the seeds that difference would need
at 80 % power), then the seeds 0.5 mph needs at the spread measured.
``--wide`` prints every column in one table instead.

Each run gets a new folder results/<date>_<time> (results/latest links to the newest);
``--output DIR`` writes to DIR instead, refusing a non-empty one unless ``--overwrite``.
Written atomically:

    report.html        the whole run in one self-contained page (tables, verdicts, plots,
                       incident gallery): open it in a browser
    episodes.csv       one row per episode
    agents.csv         one row per agent, with the intervals (_ci_low, _ci_high)
    comparisons.csv    one row per agent pair: speed difference, P(improvement), verdict
    summary.json       the run's settings, the agents' rows, the comparisons and every
                       episode's summary (with its incident_log)
    traces.npz         per-step time, distance, speed, acceleration, jerk of every episode
                       (arrays "agent/seed/field"; sdc_evaluation.files.load_traces reads it)
    means.png          mean speed and lap time per agent with 95 % intervals
    incidents.png      incidents by kind per agent, with the rate per 100 miles
    profiles.png       speed, acceleration and jerk over distance, one seed (--plot-seed)
    speed_time.png     speed over time, the same seed (on the track: the light ahead)
    incident_map.png   the loop with each agent's incidents marked by kind
    incidents.json     a JSON array of incident reports (one per line): each incident with
                       the last seconds of the ego and nearby cars
    incident_gallery/  per incident, top-down snapshots at -3, -2, -1 and 0 s
    planner_logs/      the output of external planners (agents "external:COMMAND")
    stack_logs/        the output of capstone stacks (agents "capstone:COMMAND")

Episodes run in worker processes (``--workers``), or as Ray tasks with ``--ray``: on a
running cluster (``auto``, ``HOST:PORT``) or on a local one started for the run and shut
down at its end (docs/ray.md). An episode that raises, or whose worker dies, is reported
with its seed and reason (printed, and in ``summary.json``'s ``run.failures`` with its
traceback); the other episodes still run and are written, and the exit status is 1.

``--scenario PATH`` (a scenario file, a folder of them, or an incidents.json to replay)
runs every agent on each scenario and prints pass or fail with the reason, into
scenarios.csv and scenarios.json (:mod:`sdc_evaluation.scenario_runs`, ``docs/scenarios.md``).

Endurance mode drives ``N`` laps in one episode per (agent, seed) with
``terminate_on_collision`` off, so incidents are counted and the car drives on, and reports
the distance without incident (longest stretch and at the end, miles) and the wall time,
next to the seed planner's record of 276.53 miles.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import shlex
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
from rich.console import Console

from sdc_agents import capstone, external
from sdc_agents.registry import (
    AGENT_KINDS,
    AGENTS,
    POLICY_KINDS,
    check_agent_builds,
    check_agent_env,
    parse_agent_spec,
)
from sdc_configs import config_path
from sdc_evaluation import run_folders, statistics
from sdc_evaluation.analysis import analyse, terminal_output
from sdc_evaluation.compare import compare_main
from sdc_evaluation.episodes import EpisodeSpec
from sdc_evaluation.incident_plots import EgoShape
from sdc_evaluation.incident_reports import DEFAULT_HISTORY_S
from sdc_evaluation.outputs import OWNED_NAMES, PlotOptions, write_run
from sdc_evaluation.plots import Limits
from sdc_evaluation.profiles import stop_line_distances
from sdc_evaluation.runner import WORKER_THREAD_VARIABLES, run_episodes
from sdc_evaluation.scenario_runs import (
    SCENARIOS_CSV,
    SCENARIOS_JSON,
    run_scenarios,
    verdict_table,
    write_scenario_run,
)
from sdc_evaluation.tables import SEED_RECORD_MILES, endurance_table
from sdc_evaluation.warmup import warm_up
from sdc_gym.metrics import IncidentRules
from sdc_gym.ray import LOCAL
from sdc_gym.units import METERS_PER_MILE
from sdc_gym.validation.yaml_files import read_yaml

DEFAULT_ENV = "sdc_gym/HighwayLoop-v0"
COMMITTED_POLICY = "dqn_swa_highway"
"""The committed highway behavior policy shown by default, by name: DQN on
``HighwayLoopBehavior-v0`` with 3-step returns and averaged weights, faster than ``fsm_bold``
on the held-out seeds 1000-1039 (docs/rl.md); the model is
``agents/highway/policies/dqn_swa_highway.zip``, its training config and command in
``dqn_swa_highway.yaml`` beside it. The first committed policy, ``dqn_highway``, stays
loadable by name or as ``dqn:agents/highway/policies/dqn_highway.zip``."""
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
    data = read_yaml(path, "config file", SystemExit) or {}  # UTF-8, YAML 1.2 numbers
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
    parser.add_argument("--scenario", type=Path, default=None, metavar="PATH",
                        help="run every agent on each scenario of PATH (a scenario YAML "
                             "file, a folder of them, or an incidents.json to replay its "
                             "incidents) and report pass/fail with the reason "
                             "(docs/scenarios.md; default 1 seed)")
    external.add_external_arguments(parser)
    capstone.add_capstone_arguments(parser)
    parser.add_argument("--env", default=None,
                        help=f"env id (default: the config's, else {DEFAULT_ENV})")
    parser.add_argument("--config", type=config_path, default=None,
                        help="env config YAML: a path, or a packaged name (track_loop)")
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
    parser.add_argument("--output", default=None,
                        help="folder for the result files and plots (default: a new "
                             f"{run_folders.RESULTS_ROOT}/<date>_<time>, linked as "
                             f"{run_folders.RESULTS_ROOT}/{run_folders.LATEST}); an existing "
                             "non-empty folder needs --overwrite")
    parser.add_argument("--overwrite", action="store_true",
                        help="write into a non-empty --output folder, replacing the result "
                             "files of the run there (other files are kept)")
    parser.add_argument("--workers", type=int, default=None,
                        help="parallel worker processes (default: one per CPU core, "
                             f"{os.cpu_count() or 1} here); with --ray, the cores of the "
                             "local cluster")
    parser.add_argument("--ray", nargs="?", const=LOCAL, default=None, metavar="ADDRESS",
                        help="run the episodes as Ray tasks: on a running cluster "
                             "('auto': the one started here with `ray start`, or HOST:PORT), "
                             "or without ADDRESS on a local cluster started for the run "
                             "(needs the extra: pip install -e \".[ray]\")")
    add_report_arguments(parser)
    parser.add_argument("--plot-seed", type=int, default=None, metavar="SEED",
                        help="the seed whose speed profiles are drawn (default: the first)")
    parser.add_argument("--no-plots", action="store_true",
                        help="skip the PNG plots (report.html then has the tables only)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    external.check_external_arguments(parser, args)
    capstone.check_capstone_arguments(parser, args)
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
    if args.output is not None:
        if not args.output.strip():
            parser.error("--output must be a folder path, got an empty string")
        args.output = Path(args.output)
        if args.output.exists() and not args.output.is_dir():
            parser.error(f"--output {args.output} exists and is not a folder")
    elif args.overwrite:
        parser.error("--overwrite needs --output (without it each run gets a new folder)")
    check_report_arguments(parser, args)
    if args.ray is not None and args.ray != LOCAL and args.workers is not None:
        parser.error(f"--workers sets the cores of a local cluster; the cluster at --ray "
                     f"{args.ray} has its own: drop --workers")
    if args.ray is not None and not args.ray.strip():
        parser.error("--ray ADDRESS must be 'auto' or HOST:PORT (or no ADDRESS: a local "
                     "cluster), got an empty string")
    if args.seeds is None:
        episodes = args.episodes or (1 if args.endurance or args.scenario else
                                     DEFAULT_EPISODES)
        first = args.seed or 0
        args.seeds = list(range(first, first + episodes))
    else:
        args.seeds = list(dict.fromkeys(args.seeds))
    if args.plot_seed is not None and args.plot_seed not in args.seeds:
        parser.error(f"--plot-seed {args.plot_seed} is not among the run's seeds "
                     f"{args.seeds}")
    return args


def add_report_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of the printed tables and the statistics (a run and ``compare`` alike)."""
    parser.add_argument("--wide", action="store_true",
                        help="print every column in one table (about 200 columns) instead "
                             "of the 80-column tables")
    parser.add_argument("--bootstrap-resamples", type=int,
                        default=statistics.DEFAULT_RESAMPLES, metavar="N",
                        help="bootstrap resamples of the IQM's and P(improvement)'s "
                             "intervals (default "
                             f"{statistics.DEFAULT_RESAMPLES})")
    parser.add_argument("--bootstrap-seed", type=int, default=statistics.DEFAULT_SEED,
                        metavar="SEED", help="seed of the bootstrap (default "
                        f"{statistics.DEFAULT_SEED}): the same episodes always give the "
                        "same intervals")


def check_report_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    if args.bootstrap_resamples < 100:
        parser.error(f"--bootstrap-resamples must be >= 100, got {args.bootstrap_resamples}")


def statistics_settings(args: argparse.Namespace) -> statistics.Settings:
    return statistics.Settings(resamples=args.bootstrap_resamples, seed=args.bootstrap_seed)


def parse_compare_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="evaluate.py compare",
        description="Put evaluation runs side by side with the same statistics: each "
                    "agent of each run as 'run/agent', verdicts for the same agent across "
                    "runs (every pair when no agent is in two runs).")
    parser.add_argument("runs", nargs="+", type=Path, metavar="RUN",
                        help="run folders (with their summary.json), e.g. results/latest")
    parser.add_argument("--output", type=Path, default=None,
                        help="also write agents.csv, comparisons.csv, summary.json, the "
                             "plots and report.html to this folder")
    parser.add_argument("--overwrite", action="store_true",
                        help="write into a non-empty --output folder")
    add_report_arguments(parser)
    args = parser.parse_args(argv)
    check_report_arguments(parser, args)
    if len(args.runs) < 2:
        parser.error("give at least two run folders")
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


def agent_options(args: argparse.Namespace, run: external.AgentRun,
                  seed: int) -> dict[str, dict[str, Any]]:
    """The options of one episode's agent (an external planner's folder, port, log; a
    ``capstone:`` stack's)."""
    if external.is_external(run.spec):
        return {external.EXTERNAL_KIND: external.external_options(args, run, seed)}
    if capstone.is_capstone(run.spec):
        return {capstone.CAPSTONE_KIND: capstone.capstone_options(args, run.spec, seed)}
    return {}


def episode_specs(args: argparse.Namespace, env_id: str,
                  env_config: dict[str, Any]) -> list[EpisodeSpec]:
    """One episode per (agent, seed), with the incident and external planner options."""
    return [EpisodeSpec(run.spec, env_id, seed, (external.external_env_config(env_config)
                                                 if external.is_external(run.spec)
                                                 else env_config),
                        agent_options=agent_options(args, run, seed),
                        incident_history=args.incident_history,
                        stop_at_incident=args.stop_at_incident, name=run.name)
            for run in args.agent_runs for seed in args.seeds]


@dataclass(frozen=True)
class EnvProbe:
    """What the plots need from the env, read once before any worker starts."""

    road: Any  # the highway map or the track (None without one)
    rules: IncidentRules
    start_s: float
    ego_shape: EgoShape


def probe_env(env_id: str, env_config: dict[str, Any]) -> EnvProbe:
    """The env's road or track (for the incident map), rules and start.

    Also validates the config before any worker starts: a bad key fails here, once.
    """
    env = gym.make(env_id, config=env_config)
    try:
        unwrapped = env.unwrapped
        road = getattr(unwrapped, "road", None) or getattr(unwrapped, "track", None)
        start_s = getattr(unwrapped, "start_s", None)
        if start_s is None:
            start_s = getattr(road, "start_s", 0.0)
        return EnvProbe(road, getattr(unwrapped, "rules", IncidentRules()), float(start_s),
                        EgoShape.of_env(unwrapped))
    finally:
        env.close()


def _policy_build_error(env_id: str, env_config: dict[str, Any], specs: list[str]
                        ) -> str | None:
    """The first trained policy of ``specs`` that cannot be built on the env, as a message
    (None: every one builds). Runs in a child process: see :func:`check_policies_build`."""
    env = gym.make(env_id, config=env_config)
    try:
        for spec in specs:
            try:
                check_agent_builds(spec, env)
            except (ValueError, TypeError) as error:
                return f"--agents: {spec}: {error}"
    finally:
        env.close()
    return None


def check_policies_build(env_id: str, env_config: dict[str, Any], specs: list[str]) -> None:
    """Each trained policy of ``specs`` built once on the env, as every episode builds it
    (its model loaded, its spaces checked against the behavior env under it): a policy of
    another env or config is one error before any episode, not a failure in each.

    The build runs in a child process of its own: torch used in this process would be
    inherited half-initialised by the forked workers of the episode pool, and a worker's
    model load then hung on a futex (seen with two workers and two policies)."""
    if not any(parse_agent_spec(spec)[0] in POLICY_KINDS for spec in specs):
        return
    with ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context()) as pool:
        error = pool.submit(_policy_build_error, env_id, env_config, specs).result()
    if error is not None:
        raise SystemExit(error)


def output_folder(args: argparse.Namespace) -> Path:
    """The run's folder: ``--output`` (checked: never overwritten silently), else a new
    timestamped one under results/."""
    if args.output is not None:
        run_folders.prepare_output(args.output, args.overwrite,
                                   (*OWNED_NAMES, SCENARIOS_CSV, SCENARIOS_JSON))
        return args.output
    return run_folders.new_run_folder()


def main(argv: list[str] | None = None) -> dict[str, Any]:
    """Run the evaluation (or ``compare``); returns the per-agent rows, comparisons,
    episodes and files written."""
    # One math thread here too, before torch (and its OpenMP) can load in this process: an
    # OpenMP pool started here is inherited broken by the forked workers, whose first
    # policy load then hung on a futex (two workers, two [256, 256] policies).
    for variable in WORKER_THREAD_VARIABLES:
        os.environ.setdefault(variable, "1")
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["compare"]:
        compare = parse_compare_args(argv[1:])
        if compare.output is not None:
            run_folders.prepare_output(compare.output, compare.overwrite, OWNED_NAMES)
        return compare_main(compare.runs, Console(), compare.wide,
                            statistics_settings(compare), compare.output)
    args = parse_args(argv)
    env_id, env_config = env_settings(args)
    if args.agents is None:
        args.agents = list(DEFAULT_TRACK_AGENTS if env_id in TRACK_ENVS else DEFAULT_AGENTS)
    try:  # every agent can drive the env, before any episode starts
        for agent in args.agents:
            check_agent_env(agent, env_id)
    except ValueError as error:
        raise SystemExit(f"--agents: {error}") from None
    # Each agent under its name (an external planner repeated per folder: SPEC@FOLDER).
    args.agent_runs = external.agent_runs(args.agents, args.planner_cwd)
    specs_given = args.agents
    args.agents = [run.name for run in args.agent_runs]
    try:
        probe = probe_env(env_id, env_config)
    except (gym.error.Error, ValueError, TypeError) as error:
        raise SystemExit(f"cannot make {env_id} with config {env_config}: {error}") from None
    check_policies_build(env_id, env_config, specs_given)
    workers = external.fixed_port_workers(args, specs_given, args.workers or os.cpu_count()
                                          or 1)
    if capstone.fixed_port(args, specs_given):  # stacks on one port run one at a time
        workers = 1
    backend = None
    if args.ray is not None:
        if external.fixed_port_workers(args, specs_given, 2) == 1:
            raise SystemExit("--ray runs episodes in parallel, and external planners on a "
                             "fixed port would collide: put {port} in the command")
        backend = ray_backend(args.ray, args.workers)
    latest = args.output is None
    args.output = output_folder(args)
    if args.scenario is not None:
        return scenario_main(args, argv, env_id, env_config, latest, workers, backend)
    specs = episode_specs(args, env_id, env_config)
    console = Console()
    if args.wide and not console.is_terminal:  # logs: do not squeeze the wide table
        console = Console(width=260)

    if workers > 1 and backend is None and len(specs) > 1:
        warm_up(specs)  # compile once here, not in every worker (first run only)
    started = time.perf_counter()
    try:
        with external.planner_maps(args, args.agent_runs, probe.road):
            runs = run_episodes(specs, workers=workers, progress=not args.no_progress,
                                backend=backend)
    except ConnectionError as error:  # --ray ADDRESS with no cluster there
        raise SystemExit(f"--ray {args.ray}: {error}") from None
    wall = time.perf_counter() - started
    episodes, failures = runs.results, runs.failures
    if not episodes:
        raise SystemExit(f"every episode failed ({len(failures)}); nothing to analyse:\n"
                         + "\n".join(f"{failure.agent} seed {failure.seed}: {failure.reason}"
                                     for failure in failures))

    analysis = analyse(episodes, statistics_settings(args))
    laps = env_config["laps"]
    mode = f"endurance, {laps} laps in one episode" if args.endurance else f"{laps} lap(s)"
    seeds = " ".join(map(str, args.seeds))
    title = f"{env_id}: seed(s) {seeds} x {mode}"
    run = {"env_id": env_id, "env_config": env_config, "agents": args.agents,
           "seeds": args.seeds, "laps": laps, "endurance": bool(args.endurance),
           "command": shlex.join(["evaluate.py", *argv]), "wall_time": wall,
           "ray": args.ray, "failures": [failure.as_dict() for failure in failures]}
    settings = [("env", env_id), ("seeds", seeds), ("laps", mode),
                ("agents", " ".join(args.agents)), ("command", run["command"]),
                ("wall time", f"{wall:.1f} s, {len(episodes)} episode(s)")]
    settings += [(f"failed: {failure.agent} seed {failure.seed}", failure.reason)
                 for failure in failures]
    plot_options = None if args.no_plots else PlotOptions(
        probe.road, Limits.from_rules(probe.rules),
        stop_line_distances(probe.road, probe.start_s, laps), args.plot_seed, probe.ego_shape)
    files = write_run(args.output, episodes, analysis, title, settings, run, plot_options)
    if latest:
        run_folders.point_latest_at(args.output)

    terminal_output(console, analysis, title, args.wide)
    if args.endurance:
        console.print(endurance_table(episodes, f"endurance: {laps} laps, incidents counted, "
                                                "driving on", analysis.labels
                                       ).rich(console.width))
        best = max(episode["longest_distance_without_incident"] for episode in episodes)
        console.print(f"best distance without incident: {best / METERS_PER_MILE:.2f} miles "
                      f"(seed planner's record: {SEED_RECORD_MILES:.2f} miles)")
    for episode in episodes:  # faults of external planners, stops at an incident
        if episode.get("abort_message"):
            console.print(f"{episode['agent']} seed {episode['seed']} ended early, "
                          f"{episode['termination_reason']}: {episode['abort_message']}",
                          markup=False, highlight=False)
    where = f"{args.output}" + (f" (= {run_folders.RESULTS_ROOT / run_folders.LATEST})"
                                if latest else "")
    for failure in failures:  # raised, or their worker died: no result (summary.json: why)
        console.print(f"{failure.agent} seed {failure.seed} failed: {failure.reason}",
                      markup=False, highlight=False)
    failed = f" ({len(failures)} failed, listed above)" if failures else ""
    console.print(f"{len(episodes)} episode(s){failed} in {wall:.1f} s wall time; results in "
                  f"{where}: " + ", ".join(path.name for path in files),
                  markup=False, highlight=False)
    return {"rows": analysis.rows, "comparisons": analysis.comparisons,
            "episodes": episodes, "failures": failures, "files": files,
            "output": args.output}


def ray_backend(address: str, workers: int | None) -> Any:
    """The Ray backend for ``--ray`` (a clear error without the optional extra)."""
    try:
        from sdc_evaluation.ray_backend import RayBackend
        from sdc_gym.ray import START_A_CLUSTER, unreachable
    except ImportError as error:
        raise SystemExit(f"--ray needs Ray: pip install -e \".[ray]\" ({error})") from None
    problem = None if address == LOCAL else unreachable(address)
    if problem is not None:  # before any folder is made
        raise SystemExit(f"--ray {address}: {problem}; {START_A_CLUSTER}")
    return RayBackend(address, num_cpus=workers)


def scenario_main(args: argparse.Namespace, argv: list[str], env_id: str,
                  env_config: dict[str, Any], latest: bool, workers: int,
                  backend: Any) -> dict[str, Any]:
    """``--scenario``: every agent on each scenario; the verdicts printed and written."""
    started = time.perf_counter()
    runs = {run.name: run for run in args.agent_runs}
    rows, episodes, failures = run_scenarios(
        args.scenario, args.agents, args.seeds, env_id, env_config, workers,
        not args.no_progress, backend,
        agent_setup=lambda name, seed: (runs[name].spec,
                                        agent_options(args, runs[name], seed)),
        incident_history=args.incident_history)
    wall = time.perf_counter() - started
    run = {"env_id": env_id, "env_config": env_config, "agents": args.agents,
           "seeds": args.seeds, "scenario": str(args.scenario),
           "command": shlex.join(["evaluate.py", *argv]), "wall_time": wall,
           "ray": args.ray, "failures": [failure.as_dict() for failure in failures]}
    files = write_scenario_run(args.output, rows, episodes, run)
    if latest:
        run_folders.point_latest_at(args.output)
    console = Console()
    passed = sum(row["passed"] for row in rows)
    console.print(verdict_table(rows, f"{env_id}: scenarios of {args.scenario}"
                                ).rich(console.width))
    console.print(f"{passed} of {len(rows)} passed; {len(rows)} episode(s) in {wall:.1f} s "
                  f"wall time; results in {args.output}: "
                  + ", ".join(path.name for path in files), markup=False, highlight=False)
    return {"rows": rows, "episodes": episodes, "failures": failures, "files": files,
            "output": args.output}


def cli(argv: list[str] | None = None) -> int:
    """The command line's exit status: 1 when episodes failed (their results are still
    written), else 0 (``sdc-evaluate`` and ``python -m sdc_evaluation`` call this too)."""
    return 1 if main(argv).get("failures") else 0


if __name__ == "__main__":
    sys.exit(cli())
