"""Faults of the scripts: ``kill -9`` of ``evaluate.py --workers 2`` mid-run leaves no
process behind (pool workers, their planners, multiprocessing's helpers)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import yaml

from tests.processes import all_gone, descendants
from tests.test_bridge_external import STRAIGHT, external

ROOT = Path(__file__).resolve().parents[1]


def wait_for_descendants(pid: int, count: int, wait_s: float = 60.0) -> list[int]:
    deadline = time.monotonic() + wait_s
    while len(found := descendants(pid)) < count:
        assert time.monotonic() < deadline, f"only {found} below {pid} after {wait_s} s"
        time.sleep(0.1)
    return found


def test_kill_9_of_evaluate_with_workers_leaves_no_process(tmp_path):
    """Two workers, each driving an external planner (with its watchdog) on long episodes:
    the main process is killed without warning mid-run; within a few seconds every process
    that was below it is gone."""
    config = tmp_path / "long.yaml"
    config.write_text(yaml.safe_dump({"env": "sdc_gym/HighwayLoop-v0", "config": {
        "map": "oval", "traffic": {"car_count": 4}, "max_duration": 3000.0}}))
    agents = [external(*STRAIGHT), "lane_keeping"]
    evaluate = subprocess.Popen(
        [sys.executable, "evaluate.py", "--config", str(config), "--workers", "2",
         "--agents", *agents, "--seeds", "0", "1", "--laps", "50", "--no-progress",
         "--no-plots", "--output", str(tmp_path / "run")],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        # 2 workers, a planner and its watchdog (multiprocessing's resource tracker too).
        tree = wait_for_descendants(evaluate.pid, 4)
        time.sleep(1.0)  # mid-episode
        tree = descendants(evaluate.pid)
        assert evaluate.poll() is None  # still running: the episodes are long
        evaluate.kill()
        evaluate.wait()
        assert all_gone(tree, wait_s=5.0) == []
    finally:
        evaluate.kill()
        evaluate.wait()
