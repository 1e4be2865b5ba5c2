"""What driving an external planner through the original's wire protocol costs.

    python benchmarks/bench_bridge.py [--frames 3 5] [--repeats 3] [--seed 0]

One lap of the default highway (default traffic) three ways, best of ``--repeats``:

* ``in-process agent``: the ``lane_keeping`` agent called directly (the usual baseline);
* ``in-process twin``: the test planner (``tests/planners/protocol_planner.py``, the same
  lane keeping behind the template's message handling) called in this process on the
  encoded telemetry text, its reply decoded: everything but the socket and the process;
* ``socket``: the same planner as a separate process, through the websocket bridge.

``overhead/exchange`` is (socket - twin) / exchanges: the websocket round trip and the
switches between the two processes, i.e. what any external planner pays on top of its
own thinking. The last line times the round trip alone, with a trivial planner (the
``straight`` brain) answering one fixed telemetry message. The original simulator runs
at 1 x real time (a lap takes the simulated lap time).
"""

from __future__ import annotations

import argparse
import shlex
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym

import sdc_gym  # noqa: F401  (registers the ids)
from sdc_agents.registry import make_agent
from sdc_gym.bridge import (
    PlannerOptions,
    PlannerSession,
    decode_reply,
    encode_telemetry,
    export_highway_map,
    lockstep_config,
)

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from tests.planners.protocol_planner import Planner, TelemetryLaneKeeper  # noqa: E402

PLANNER = ROOT / "tests" / "planners" / "protocol_planner.py"
HIGHWAY = "sdc_gym/HighwayLoop-v0"


def drive(config: dict[str, Any], seed: int,
          act: Callable[[Any, dict[str, Any]], Any]) -> tuple[float, int, dict[str, Any]]:
    """Wall time, env steps and summary of one episode driven by ``act(obs, info)``."""
    env = gym.make(HIGHWAY, config=config)
    observation, info = env.reset(seed=seed)
    steps = 0
    started = time.perf_counter()
    while True:
        observation, _, terminated, truncated, info = env.step(act(observation, info))
        steps += 1
        if terminated or truncated:
            break
    wall = time.perf_counter() - started
    env.close()
    return wall, steps, info["summary"]


def agent_lap(config: dict[str, Any], seed: int, _: Path) -> tuple[float, int, dict[str, Any]]:
    env = gym.make(HIGHWAY, config=config)
    agent = make_agent("lane_keeping", env)
    agent.reset()
    return drive(config, seed, lambda observation, _: agent.act(observation))


def twin_lap(config: dict[str, Any], seed: int, folder: Path) -> tuple[float, int, dict[str, Any]]:
    planner = Planner(TelemetryLaneKeeper(str(folder / "highway_map.csv")), "none", 0)
    return drive(config, seed, lambda _, info: decode_reply(
        planner.on_message(encode_telemetry(info["telemetry"]))))


def socket_lap(config: dict[str, Any], seed: int,
               folder: Path) -> tuple[float, int, dict[str, Any]]:
    command = shlex.join([sys.executable, str(PLANNER), "--port", "{port}"])
    # Started and connected before the clock starts: the start-up (about 1 s of Python
    # imports for this planner) is not part of the lap.
    with PlannerSession(command, planner_options(folder)) as planner:
        return drive(config, seed, lambda _, info: planner.exchange(info["telemetry"]))


def planner_options(folder: Path) -> PlannerOptions:
    return PlannerOptions(cwd=str(folder), log_path=str(folder / "planner.log"))


def telemetry_at_start() -> dict[str, Any]:
    env = gym.make(HIGHWAY)
    _, info = env.reset(seed=0)
    return dict(info["telemetry"])


def round_trip_ms(exchanges: int, folder: Path) -> float:
    """ms per exchange with a planner that does almost nothing."""
    telemetry = telemetry_at_start()
    command = shlex.join([sys.executable, str(PLANNER), "--port", "{port}",
                          "--brain", "straight"])
    with PlannerSession(command, planner_options(folder)) as planner:
        planner.exchange(telemetry)
        started = time.perf_counter()
        for _ in range(exchanges):
            planner.exchange(telemetry)
        return (time.perf_counter() - started) / exchanges * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, nargs="+", default=[3, 5],
                        help="physics frames per exchange (the reply latency)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_bridge_") as name:
        run(args, Path(name))


def run(args: argparse.Namespace, folder: Path) -> None:
    """The table, with the planner's map and output in ``folder``."""
    export_highway_map("default", folder)
    print(f"{'way':18} {'frames':>6} {'exchanges':>9} {'wall s':>7} {'ms/exchange':>11} "
          f"{'laps/min':>8} {'x real time':>11} {'incidents':>9}")
    for frames in args.frames:
        config = dict(lockstep_config(frames), max_duration=1000.0)
        walls: dict[str, float] = {}
        steps = 0
        for name, lap in (("in-process agent", agent_lap), ("in-process twin", twin_lap),
                          ("socket", socket_lap)):
            runs = [lap(config, args.seed, folder) for _ in range(args.repeats)]
            wall, steps, summary = min(runs, key=lambda result: result[0])
            walls[name] = wall
            print(f"{name:18} {frames:>6} {steps:>9} {wall:>7.2f} {wall / steps * 1e3:>11.3f} "
                  f"{60.0 / wall:>8.1f} {summary['time'] / wall:>11.0f} "
                  f"{summary['incident_total']:>9}")
        overhead = (walls["socket"] - walls["in-process twin"]) / steps * 1e3
        print(f"{'overhead/exchange':18} {frames:>6} {'':>9} {'':>7} {overhead:>11.3f}")
    trips = min(round_trip_ms(2000, folder) for _ in range(args.repeats))
    print(f"round trip alone (trivial planner, fixed telemetry): {trips:.3f} ms per exchange")


if __name__ == "__main__":
    main()
