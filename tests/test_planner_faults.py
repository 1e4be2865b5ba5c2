"""Planner faults the bridge must survive with nothing left behind: a planner that starts a
process outside its process group (``setsid``, or a daemon's orphaned grandchild), ended
after a normal episode and after ``kill -9`` of the process that owns it; and a planner
that floods its output (the log stays under its limit, the episode ends ``log_flooded``).
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from sdc_gym.bridge.planner_log import CappedLog
from tests.processes import all_gone, descendants, is_alive
from tests.test_bridge_external import OVAL, STRAIGHT, external, planner_command, run

ROOT = Path(__file__).resolve().parents[1]
SHORT = {**OVAL, "max_duration": 1.2}  # 20 exchanges


def spawned_pid(log: Path, wait_s: float = 10.0) -> int:
    deadline = time.monotonic() + wait_s
    while "spawned " not in (log.read_text() if log.exists() else ""):
        assert time.monotonic() < deadline, "the planner never started its process"
        time.sleep(0.05)
    return int(log.read_text().split("spawned ")[1].split()[0])


@pytest.mark.parametrize("spawn", ["setsid", "daemon"])
def test_a_process_that_escapes_the_group_is_ended_after_a_normal_episode(spawn, tmp_path):
    log = tmp_path / "planner.log"
    result = run(external(*STRAIGHT, "--spawn", spawn), SHORT, cwd=str(tmp_path),
                 log_path=str(log))
    assert result["termination_reason"] == "max_duration" and result["env_steps"] == 20
    escaped = spawned_pid(log)
    # The process group alone would have missed it: it has a session of its own.
    assert all_gone([result["planner_pid"], escaped]) == []


@pytest.mark.parametrize("spawn", ["setsid", "daemon"])
def test_kill_9_of_the_owner_ends_the_planners_whole_tree(spawn, tmp_path):
    """Nobody calls ``stop()``: the watchdog (the planner's parent, a subreaper) sees its
    owner die and ends every descendant, the escaped one included."""
    log = tmp_path / "planner.log"
    owner_code = (
        "import time\n"
        "from sdc_gym.bridge.process import PlannerProcess\n"
        f"planner = PlannerProcess({planner_command(*STRAIGHT, '--spawn', spawn)!r}, "
        f"log_path={str(log)!r})\n"
        "planner.start()\n"
        "print(planner.pid, planner.reaper_pid, flush=True)\n"
        "time.sleep(60)\n")
    owner = subprocess.Popen([sys.executable, "-c", owner_code], stdout=subprocess.PIPE,
                             text=True, cwd=ROOT)
    try:
        planner_pid, reaper_pid = map(int, owner.stdout.readline().split())
        escaped = spawned_pid(log)
        tree = descendants(owner.pid)
        assert {planner_pid, reaper_pid, escaped} <= set(tree)  # all below the owner
        assert is_alive(escaped)
        owner.kill()
        owner.wait()
        started = time.monotonic()
        assert all_gone(tree, wait_s=10.0) == []
        # SIGTERM first: a planner that exits on it is gone well within the grace period.
        assert time.monotonic() - started < 5.0
    finally:
        owner.kill()
        owner.stdout.close()


def test_a_flooding_planner_ends_its_episode_and_its_log_stays_under_the_limit(tmp_path):
    log = tmp_path / "planner.log"
    limit = 1 << 20
    started = time.monotonic()
    result = run(external(*STRAIGHT, "--fault", "flood", "--after", "3"), OVAL,
                 cwd=str(tmp_path), log_path=str(log), log_limit=limit, reply_timeout=30.0)
    assert time.monotonic() - started < 20.0  # ended by the flood, not the reply time-out
    assert result["termination_reason"] == "log_flooded"
    assert f"log limit of {limit} bytes" in result["abort_message"]
    assert result["env_steps"] == 3  # the good replies were driven, the metrics kept
    assert all_gone([result["planner_pid"]]) == []
    data = log.read_bytes()
    assert len(data) <= limit
    assert data.startswith(b"Listening to port")  # the beginning is kept ...
    marker = data.index(b"[sdc_gym: the planner's output passed the log limit")
    assert len(data) - marker > limit // 8  # ... and the last part after the marker


def test_a_capped_log_keeps_everything_under_the_limit_and_head_and_tail_past_it(tmp_path):
    import os

    for total, limit in ((3000, 4096), (100_000, 4096)):
        read, write = os.pipe()
        flooded: list[int] = []
        log = CappedLog(read, tmp_path / f"{total}.log", limit,
                        on_flood=lambda calls=flooded: calls.append(1))
        payload = b"".join(b"%06d\n" % i for i in range(total // 7 + 1))[:total]
        for start in range(0, total, 4096):  # a pipe holds 64 KiB: write as it drains
            os.write(write, payload[start:start + 4096])
        os.close(write)
        log.close()
        data = (tmp_path / f"{total}.log").read_bytes()
        if total < limit:
            assert data == payload and not log.flooded and not flooded
        else:
            assert log.flooded and flooded == [1] and len(data) <= limit
            head, _, rest = data.partition(b"\n[sdc_gym:")
            assert payload.startswith(head) and len(head) > limit // 2
            tail = rest.split(b"follow]\n", 1)[1]
            assert payload.endswith(tail) and len(tail) == limit // 4
            dropped = int(rest.split(b"; ")[1].split()[0])
            assert len(head) + dropped + len(tail) == total  # every byte accounted for
