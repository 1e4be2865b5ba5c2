"""A watchdog that ends a planner's process group when the process that started it dies.

    python sdc_gym/bridge/reaper.py GROUP PARENT

:class:`~sdc_gym.bridge.process.PlannerProcess` starts one beside each planner. Normally it
is stopped together with the planner and does nothing. If the process that started them is
killed (``kill -9``, an out-of-memory kill, a crashed worker) nobody would ever call
``stop()``, and the planner would keep its port and run on forever; the reaper notices that
it was orphaned (its parent process id changes) and ends the planner's group the way
``stop()`` does: SIGTERM, a grace period, SIGKILL.

Linux's ``PR_SET_PDEATHSIG`` would only reach the planner itself, not the children of a
planner started through a shell script, and fires when the parent *thread* exits; polling
the parent id reaches the whole group, on any POSIX system.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from typing import Final

POLL_S: Final = 0.2  # how often the parent is checked
GRACE_S: Final = 2.0  # between SIGTERM and SIGKILL, as PlannerProcess.stop


def group_alive(group: int) -> bool:
    """Whether any process of the process group ``group`` still exists."""
    try:
        os.killpg(group, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # exists, not ours to signal (cannot happen for our own planners)
    return True


def end_group(group: int, grace_s: float = GRACE_S) -> None:
    """SIGTERM to the group, up to ``grace_s`` for it to exit, then SIGKILL."""
    for signum in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(group, signum)
        except (ProcessLookupError, PermissionError):
            return
        deadline = time.monotonic() + grace_s
        while signum == signal.SIGTERM and time.monotonic() < deadline:
            if not group_alive(group):
                return
            time.sleep(0.05)


def watch(group: int, parent: int) -> None:
    """Return when the group is gone; end it first if ``parent`` stops being our parent."""
    while group_alive(group):
        if os.getppid() != parent:
            end_group(group)
            return
        time.sleep(POLL_S)


def main(argv: list[str] | None = None) -> int:
    """Watch the group ``argv[0]`` on behalf of the process ``argv[1]`` (our parent)."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 2 or not all(arg.isdigit() for arg in args):
        print("usage: reaper.py GROUP PARENT", file=sys.stderr)
        return 2
    # A Ctrl-C meant for the parent must not end us before the planner; the parent ends
    # us (SIGTERM) once it has stopped the planner itself.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    watch(int(args[0]), int(args[1]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
