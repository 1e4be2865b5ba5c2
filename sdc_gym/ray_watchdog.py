"""The watchdog of a local Ray cluster: its processes end with the process that started it.

    python -m sdc_gym.ray_watchdog OWNER

:func:`sdc_gym.ray.ray_session` starts a local cluster with ``ray.init`` (GCS, raylet,
dashboard and runtime-env agents, workers: descendants of the owner) and this process
beside it. ``ray.shutdown`` ends them on a normal exit or Ctrl-C, and Ray's fate sharing
ends the GCS, the raylet and the workers when the owner is killed (``kill -9``), but not
the raylet's agents: measured here, they outlived a killed owner by more than 10 s,
retrying to report the raylet's death to the dead GCS. So this watchdog records, every
:data:`SCAN_S`, the owner's descendants that are Ray's (their command line names Ray),
with their start times, and SIGKILLs those still alive when

* the owner dies (our parent process id changes: we are re-parented);
* the owner closes our standard input (the end of the session, after ``ray.shutdown``:
  whatever is left of the cluster then);

a start time that no longer matches is a new process that reused the id, and is spared.
Processes of the owner that are not Ray's (a process pool, a planner) are not touched.
"""

from __future__ import annotations

import os
import select
import signal
import sys
import time
from typing import Final

from sdc_gym.bridge.reaper import descendants

SCAN_S: Final = 0.5  # how often the owner's Ray processes are recorded
POLL_S: Final = 0.1  # how often the owner and the control pipe are checked
RAY_MARKERS: Final = (b"ray::", b"/ray/", b"raylet", b"gcs_server")


def start_time(pid: int) -> int | None:
    """The process's start time (clock ticks after boot, ``/proc/PID/stat`` field 22), or
    None when it is gone."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as handle:
            stat = handle.read()
    except OSError:
        return None
    return int(stat[stat.rfind(b")") + 2:].split()[19])


def is_ray(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as handle:
            command = handle.read()
    except OSError:
        return False
    return any(marker in command for marker in RAY_MARKERS)


def record(owner: int, seen: dict[int, int]) -> None:
    """Add the owner's live Ray descendants to ``seen`` (pid -> start time)."""
    for pid in descendants(owner):
        if pid not in seen and is_ray(pid):
            started = start_time(pid)
            if started is not None:
                seen[pid] = started


def end(seen: dict[int, int]) -> None:
    """SIGKILL every recorded process still alive (and still the one recorded)."""
    for pid, started in seen.items():
        if start_time(pid) == started:
            try:
                os.kill(pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass


def watch(owner: int) -> None:
    """Record the owner's Ray processes until it dies or closes our stdin, then end them."""
    seen: dict[int, int] = {}
    control = sys.stdin.fileno()
    next_scan = 0.0
    try:
        while os.getppid() == owner:
            if time.monotonic() >= next_scan:
                record(owner, seen)
                next_scan = time.monotonic() + SCAN_S
            readable, _, _ = select.select([control], [], [], POLL_S)
            if readable and not os.read(control, 4096):
                return  # the session's end: the owner closed the pipe
    finally:
        end(seen)


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1 or not args[0].isdigit():
        print("usage: python -m sdc_gym.ray_watchdog OWNER", file=sys.stderr)
        return 2
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the owner's Ctrl-C is the owner's
    watch(int(args[0]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
