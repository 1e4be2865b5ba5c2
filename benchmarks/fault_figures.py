"""The figures of docs/guarantees.md: how fast faults are cleaned up, how big a flooded log
gets. Each fault is staged for real, ``--repeats`` times, and the worst case is printed.

    .venv/bin/python benchmarks/fault_figures.py --repeats 5

* planner tree: ``kill -9`` of a process owning a planner that left a ``setsid``
  grandchild: seconds until every process of the tree is gone;
* evaluate: ``kill -9`` of ``evaluate.py --workers 2`` mid-run (two workers, an external
  planner with its watchdog): seconds until every process below it is gone;
* flood: a planner printing random bytes as fast as it can, log limit 1 MiB: seconds
  until its episode ended ``log_flooded``, and the log's size.
"""

from __future__ import annotations

import argparse
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sdc_evaluation.episodes import EpisodeSpec, run_episode  # noqa: E402
from tests.processes import descendants, is_alive  # noqa: E402

PLANNER = ROOT / "tests" / "planners" / "protocol_planner.py"
OVAL = {"map": "oval", "traffic": {"car_count": 4}}


def planner(*arguments: str) -> str:
    return shlex.join([sys.executable, str(PLANNER), "--port", "{port}", "--brain",
                       "straight", *arguments])


def gone_after(pids: list[int], limit_s: float = 30.0) -> float:
    started = time.monotonic()
    while any(is_alive(pid) for pid in pids):
        if time.monotonic() - started > limit_s:
            return float("inf")
        time.sleep(0.005)
    return time.monotonic() - started


def planner_tree(folder: Path) -> float:
    log = folder / "tree.log"
    code = ("import time\nfrom sdc_gym.bridge.process import PlannerProcess\n"
            f"p = PlannerProcess({planner('--spawn', 'setsid')!r}, log_path={str(log)!r})\n"
            "p.start()\nprint(p.pid, flush=True)\ntime.sleep(60)\n")
    owner = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True,
                             cwd=ROOT)
    owner.stdout.readline()
    while "spawned " not in (log.read_text() if log.exists() else ""):
        time.sleep(0.02)
    tree = descendants(owner.pid)
    owner.kill()
    owner.wait()
    owner.stdout.close()
    return gone_after(tree)


def evaluate_kill(folder: Path) -> tuple[float, int]:
    config = folder / "long.yaml"
    config.write_text("env: sdc_gym/HighwayLoop-v0\nconfig: {map: oval, max_duration: 3000.0}\n")
    run = subprocess.Popen(
        [sys.executable, "evaluate.py", "--config", str(config), "--workers", "2", "--agents",
         "external:" + planner(), "lane_keeping", "--seeds", "0", "1", "--laps", "50",
         "--no-progress", "--no-plots", "--output", str(folder / f"run{time.time_ns()}")],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    while len(descendants(run.pid)) < 4:
        time.sleep(0.05)
    time.sleep(1.0)
    tree = descendants(run.pid)
    run.kill()
    run.wait()
    return gone_after(tree), len(tree)


def flood(folder: Path) -> tuple[float, int]:
    log = folder / f"flood{time.time_ns()}.log"
    spec = EpisodeSpec("external:" + planner("--fault", "flood", "--after", "3"),
                       "sdc_gym/HighwayLoop-v0", 0, {**OVAL, "max_duration": 60.0},
                       trace_points=0, agent_options={"external": {
                           "cwd": str(folder), "log_path": str(log), "log_limit": 1 << 20,
                           "reply_timeout": 30.0}})
    started = time.monotonic()
    result = run_episode(spec)
    assert result["termination_reason"] == "log_flooded", result["termination_reason"]
    return time.monotonic() - started, log.stat().st_size


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        trees = [planner_tree(folder) for _ in range(args.repeats)]
        kills = [evaluate_kill(folder) for _ in range(args.repeats)]
        floods = [flood(folder) for _ in range(args.repeats)]
    print(f"planner tree after kill -9 of its owner: all gone in <= {max(trees):.2f} s "
          f"(median {sorted(trees)[len(trees) // 2]:.2f} s, {args.repeats} runs)")
    worst = max(seconds for seconds, _ in kills)
    print(f"evaluate.py --workers 2 after kill -9: {kills[0][1]} processes below it, all gone "
          f"in <= {worst:.2f} s ({args.repeats} runs)")
    print(f"flooding planner: episode ended log_flooded in <= {max(s for s, _ in floods):.2f} s"
          f", log <= {max(size for _, size in floods):,} bytes of the 1,048,576 limit")


if __name__ == "__main__":
    main()
