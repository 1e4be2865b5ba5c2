"""The seed's FSM under planner latency, by queue length (issue 29's latency study).

    python benchmarks/study_fsm_latency.py                       # the default grid
    python benchmarks/study_fsm_latency.py --frames 1 8 --queues 50 --seeds 1000 1001

The seed says its planner "handles latency up to 150 milliseconds with a queue length of
50". Latency here is the bridge's reply latency, lock-step as the original simulator and
``evaluate.py --reply-latency``: each telemetry is answered ``N`` physics frames (0.02 s
each) later, the car consuming the old path meanwhile, and the next telemetry goes out
when the answer takes effect (``steps_per_action = latency_steps = N``). The queue length
is the number of points the planner sends each cycle (the env's ``path_points``, which
:meth:`MotionParameters.for_env <sdc_gym.stack.highway.motion.MotionParameters.for_env>`
makes the queue).

For every (latency, queue) cell, one run of the project's evaluation (``evaluate.py``:
Student's t over seeds for the mean speed, Garwood's exact interval for incidents) of both
styles on the same seeds, one lap each. Prints a Markdown table per style (mean mph,
incidents per 100 miles with their interval, collisions, max acceleration and jerk) and,
per style and queue, the first latency with any incident: where the style starts to fail.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # evaluate.py beside it

from study_fsm_variants import interval, read_rows  # beside this script

import evaluate  # the project's evaluation entry point

STYLES = ("fsm_conservative", "fsm_bold")
FRAME_MS = 20


def write_config(folder: Path, frames: int, queue: int) -> Path:
    """An env config with the reply latency ``frames`` and the queue ``queue``."""
    path = folder / f"latency_{frames}_queue_{queue}.yaml"
    config = {"env": "sdc_gym/HighwayLoop-v0",
              "config": {"steps_per_action": frames, "latency_steps": frames,
                         "path_points": queue}}
    path.write_text(yaml.safe_dump(config), encoding="utf-8")
    return path


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", nargs="+", type=int, default=[1, 3, 5, 8, 10, 15, 25],
                        help="reply latencies in 20 ms frames (default 20-500 ms)")
    parser.add_argument("--queues", nargs="+", type=int, default=[10, 25, 50])
    parser.add_argument("--seeds", nargs="+", type=int, default=[1000, 1001, 1002])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--output", type=Path, default=Path("results/study_fsm_latency"))
    parser.add_argument("--tables-only", action="store_true",
                        help="print the tables of the runs already in --output")
    args = parser.parse_args(argv)
    args.frames, args.queues = sorted(set(args.frames)), sorted(set(args.queues))
    for name, values in (("--frames", args.frames), ("--queues", args.queues)):
        if min(values) < 1:
            parser.error(f"{name} must be at least 1, got {min(values)}")
    args.output.mkdir(parents=True, exist_ok=True)
    cells: dict[tuple[int, int], dict[str, dict[str, str]]] = {}
    for queue in args.queues:
        for frames in args.frames:
            run = args.output / f"latency_{frames}_queue_{queue}"
            if not args.tables_only:
                config = write_config(args.output, frames, queue)
                evaluate.main(["--agents", *STYLES, "--config", str(config),
                               "--seeds", *map(str, args.seeds), "--output", str(run),
                               "--workers", str(args.workers), "--overwrite",
                               "--no-progress", "--no-plots", "--incident-history", "0"])
            cells[frames, queue] = {row["agent"]: row for row in read_rows(run / "agents.csv")}

    print(f"\nseeds {', '.join(map(str, args.seeds))}, one lap each; latency = the reply "
          f"latency (ms), queue = points sent per cycle\n")
    for style in STYLES:
        print(f"\n`{style}`\n")
        print("| queue | latency ms | mean mph [95% CI] | incidents / 100 mi [95% CI] | "
              "collisions | max accel m/s^2 | max jerk m/s^3 |")
        print("|---:|---:|---:|---:|---:|---:|---:|")
        for (frames, queue), rows in cells.items():
            row = rows[style]
            print(f"| {queue} | {frames * FRAME_MS} | {interval(row, 'mean_speed_mph')} | "
                  f"{interval(row, 'incidents_per_100_miles', 1)} | "
                  f"{row['incidents_collision']} | {float(row['max_acceleration']):.2f} | "
                  f"{float(row['max_jerk']):.2f} |")
    print("\n| style | queue | first latency with an incident (ms) | its incidents |")
    print("|---|---:|---:|---|")
    for style in STYLES:
        for queue in args.queues:
            first = next(((frames, cells[frames, queue][style]) for frames in args.frames
                          if int(cells[frames, queue][style]["incident_total"]) > 0), None)
            if first is None:
                print(f"| {style} | {queue} | none up to {max(args.frames) * FRAME_MS} | |")
                continue
            frames, row = first
            kinds = ", ".join(f"{key[len('incidents_'):]} {row[key]}" for key in row
                              if key.startswith("incidents_") and key != "incidents_per_100_miles"
                              and "_ci_" not in key and row[key] not in ("", "0"))
            print(f"| {style} | {queue} | {frames * FRAME_MS} | {kinds} |")


if __name__ == "__main__":
    main()
