"""Endurance of the seed's FSM and its variants: the distances driven between incidents.

    python benchmarks/study_fsm_endurance.py                    # 5 seeds x 10 laps each
    python benchmarks/study_fsm_endurance.py --laps 50 --seeds $(seq 1000 1009)

The seed's headline is 276.53 miles without incident at 47.3 mph: one long drive, one
number. Here every agent drives ``--laps`` laps in one episode per seed (``evaluate.py
--endurance``: collisions do not end the episode, incidents are counted and the car drives
on), and every stretch between two incidents is a sample of the incident-free distance.
The stretch from the last incident (or the start) to the end is censored: the car was
still clean when the run stopped. Prints per agent the miles, incidents, the longest
stretch, and the stretches' distribution (count, quantiles, how many censored), and draws
the stretches per agent (``stretches.png``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # evaluate.py beside it

import evaluate  # the project's evaluation entry point
from sdc_evaluation.files import load_summary, load_traces

AGENTS = ("fsm_conservative", "fsm_bold", "fsm_alert", "fsm_caution", "fsm_reverse",
          "fsm_hyper", "fsm_straight_braking", "fsm_reroute", "fsm_easing")
METERS_PER_MILE = 1609.344


def stretches(incident_times: list[float], time: np.ndarray, distance: np.ndarray
              ) -> tuple[list[float], float]:
    """The distances (m) between consecutive incidents of one episode, from its start,
    and the censored last stretch (from the last incident to the episode's end)."""
    at = np.interp(np.asarray(sorted(incident_times), dtype=np.float64), time, distance)
    marks = np.concatenate(([0.0], at))
    return list(np.diff(marks)), float(distance[-1] - marks[-1])


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--agents", nargs="+", default=list(AGENTS))
    parser.add_argument("--laps", type=int, default=10)
    parser.add_argument("--seeds", nargs="+", type=int, default=list(range(1000, 1005)))
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--output", type=Path, default=Path("results/study_fsm_endurance"))
    parser.add_argument("--tables-only", action="store_true",
                        help="print the tables of the run already in --output")
    args = parser.parse_args(argv)
    if args.laps < 1:
        parser.error(f"--laps must be at least 1, got {args.laps}")
    if not args.tables_only:
        evaluate.main(["--agents", *args.agents, "--endurance", str(args.laps),
                       "--seeds", *map(str, args.seeds), "--output", str(args.output),
                       "--workers", str(args.workers), "--overwrite", "--no-progress",
                       "--incident-history", "0"])
    summary = load_summary(args.output)
    traces = load_traces(args.output / "traces.npz")
    closed: dict[str, list[float]] = {agent: [] for agent in args.agents}
    censored: dict[str, list[float]] = {agent: [] for agent in args.agents}
    miles = dict.fromkeys(args.agents, 0.0)
    for episode in summary["episodes"]:
        agent, seed = episode["agent"], int(episode["seed"])
        trace = traces[agent, seed]
        done, last = stretches([entry["time"] for entry in episode["incident_log"]],
                               trace.time, trace.distance)
        closed[agent] += [d / METERS_PER_MILE for d in done]
        censored[agent].append(last / METERS_PER_MILE)
        miles[agent] += float(episode["distance"]) / METERS_PER_MILE

    print(f"\n{args.laps} laps in one episode on each of seeds "
          f"{args.seeds[0]}-{args.seeds[-1]} ({len(args.seeds)}); miles between incidents "
          f"(a stretch still clean at the end is censored: '>=')\n")
    print("| agent | miles | incidents | longest clean miles | miles between incidents: "
          "median [quartiles] | clean at the end (censored) |")
    print("|---|---:|---:|---:|---:|---:|")
    for agent in args.agents:
        done, open_ = closed[agent], censored[agent]
        longest = max(done + open_) if done or open_ else 0.0
        mark = ">= " if open_ and longest == max(open_) else ""
        quantiles = (f"{np.median(done):.2f} [{np.quantile(done, 0.25):.2f}, "
                     f"{np.quantile(done, 0.75):.2f}]" if done else "-")
        print(f"| {agent} | {miles[agent]:.1f} | {len(done)} | {mark}{longest:.1f} | "
              f"{quantiles} | {len(open_)}, shortest >= {min(open_):.1f} |")
    plot(closed, censored, args.output / "stretches.png")


def plot(closed: dict[str, list[float]], censored: dict[str, list[float]],
         path: Path) -> None:
    """The stretches per agent on a log axis: closed ones as dots, censored as triangles."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    figure, axes = plt.subplots(figsize=(8, 0.5 + 0.45 * len(closed)))
    for row, agent in enumerate(closed):
        axes.scatter([max(d, 1e-3) for d in closed[agent]], [row] * len(closed[agent]),
                     s=12, color="tab:red", label="ended by an incident" if row == 0 else None)
        axes.scatter(censored[agent], [row] * len(censored[agent]), marker=">", s=30,
                     color="tab:green", label="clean at the end" if row == 0 else None)
    axes.set_xscale("log")
    axes.set_yticks(range(len(closed)), list(closed))
    axes.set_xlabel("miles without incident")
    axes.axvline(276.53, color="gray", linestyle=":", label="the seed's 276.53 miles")
    axes.legend(loc="lower right", fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)


if __name__ == "__main__":
    main()
