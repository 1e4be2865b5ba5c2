"""Evaluate driving agents on an sdc-gym env and print lap time and violations.

    python evaluate.py                       # lane-keeping driver, default highway, 3 seeds
    python evaluate.py --agents lane_keeping --episodes 5 --laps 2 --workers 2
    python evaluate.py --config configs/highway_dense_traffic.yaml --output results/dense

Writes ``episodes.csv`` and ``summary.json`` (atomically) to the output folder.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import yaml
from rich.console import Console

from agents.evaluation import (
    EpisodeSpec,
    aggregate,
    results_table,
    run_episodes,
    write_results,
)
from agents.registry import AGENTS


def load_config(path: Path | None) -> tuple[str | None, dict[str, Any]]:
    """A YAML file with optional ``env`` (an env id) and ``config`` (env config overrides)."""
    if path is None:
        return None, {}
    data = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    if not isinstance(data, dict) or set(data) - {"env", "config"}:
        raise SystemExit(f"{path}: expected a mapping with keys 'env' and/or 'config'")
    return data.get("env"), dict(data.get("config") or {})


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--agents", nargs="+", default=["lane_keeping"],
                        choices=sorted(AGENTS), help="agents to compare")
    parser.add_argument("--env", default=None,
                        help="env id (default: the config's, else sdc_gym/HighwayLoop-v0)")
    parser.add_argument("--config", type=Path, default=None, help="YAML file in configs/")
    parser.add_argument("--episodes", type=int, default=3, help="episodes (seeds) per agent")
    parser.add_argument("--seed", type=int, default=0, help="first seed")
    parser.add_argument("--laps", type=int, default=1, help="laps per episode")
    parser.add_argument("--output", type=Path, default=Path("results/latest"),
                        help="folder for episodes.csv and summary.json")
    parser.add_argument("--workers", type=int, default=1, help="parallel worker processes")
    args = parser.parse_args(argv)
    if args.episodes < 1 or args.laps < 1 or args.workers < 1:
        parser.error("--episodes, --laps and --workers must be >= 1")
    if not str(args.output).strip():
        parser.error("--output must be a folder path, got an empty string")
    return args


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    config_env, env_config = load_config(args.config)
    env_id = args.env or config_env or "sdc_gym/HighwayLoop-v0"
    env_config["laps"] = args.laps
    specs = [EpisodeSpec(agent, env_id, args.seed + i, env_config)
             for agent in args.agents for i in range(args.episodes)]
    episodes = run_episodes(specs, workers=args.workers)
    rows = aggregate(episodes)
    write_results(args.output, episodes, rows)
    console = Console()
    if not console.is_terminal:  # logs and CI: do not squeeze the table into 80 columns
        console = Console(width=200)
    console.print(results_table(rows, f"{env_id}: {args.episodes} seed(s) x {args.laps} lap(s)"))
    console.print(f"results: {args.output / 'summary.json'}, {args.output / 'episodes.csv'}")


if __name__ == "__main__":
    main()
