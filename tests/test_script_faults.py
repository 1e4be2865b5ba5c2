"""Faults of the scripts: ``kill -9`` of ``evaluate.py --workers 2`` mid-run leaves no
process behind (pool workers, their planners, multiprocessing's helpers)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest
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


@pytest.mark.parametrize("content, fragment", [
    (b"\x00\x01binary", "is binary, not text"),
    ("config: {map: caf\xe9}\n".encode("latin-1"), r"is not UTF-8 text \(byte 0xe9"),
    (b"config: [unclosed\n", "is not valid YAML"),
    (b"- a list\n", "expected a mapping"),
])
def test_bad_yaml_files_are_clear_errors_in_both_scripts(tmp_path, content, fragment):
    import evaluate
    import train

    path = tmp_path / "bad.yaml"
    path.write_bytes(content)
    with pytest.raises(SystemExit, match=fragment) as raised:
        evaluate.main(["--config", str(path), "--output", str(tmp_path / "e")])
    assert str(path) in str(raised.value)
    with pytest.raises(SystemExit, match=fragment) as raised:
        train.main(["--config", str(path), "--output", str(tmp_path / "t")])
    assert str(path) in str(raised.value)
    assert not (tmp_path / "e").exists() and not (tmp_path / "t").exists()


def test_evaluate_names_a_bad_env_config_before_any_worker(tmp_path):
    import evaluate

    path = tmp_path / "run.yaml"
    path.write_text(yaml.safe_dump({"config": {"traffic": {"car_count": 10**6}}}))
    with pytest.raises(SystemExit, match=r"'traffic.car_count' must be an int in \[0, 1000\]"):
        evaluate.main(["--config", str(path), "--workers", "2", "--output",
                       str(tmp_path / "run")])
