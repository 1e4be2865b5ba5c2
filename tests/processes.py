"""Process checks for the fault tests: is a process gone, what descends from a process."""

from __future__ import annotations

import time
from pathlib import Path


def process_state(pid: int) -> str | None:
    """The state letter of ``pid`` in /proc (``R``, ``S``, ``Z``, ...), ``None`` if gone."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return None


def is_alive(pid: int) -> bool:
    """A process that exists and is not a zombie (a zombie has exited: only its exit
    status waits for its parent)."""
    return process_state(pid) not in (None, "Z", "X")


def process_gone(pid: int, wait_s: float = 5.0) -> bool:
    """No such process, or only its zombie, within ``wait_s`` (a killed process exits
    when the kernel next schedules it, a moment after the signal)."""
    deadline = time.monotonic() + wait_s
    while is_alive(pid):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.01)
    return True


def all_gone(pids: list[int], wait_s: float = 5.0) -> list[int]:
    """The processes of ``pids`` still alive after ``wait_s`` (``[]``: all gone)."""
    deadline = time.monotonic() + wait_s
    while (alive := [pid for pid in pids if is_alive(pid)]) and time.monotonic() < deadline:
        time.sleep(0.02)
    return alive


def descendants(root: int) -> list[int]:
    """Live descendants of ``root``, from one scan of /proc."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except (FileNotFoundError, ProcessLookupError):
            continue
        if fields[0] not in ("Z", "X"):
            children.setdefault(int(fields[1]), []).append(int(entry.name))
    found, stack = [], [root]
    while stack:
        for child in children.get(stack.pop(), ()):
            found.append(child)
            stack.append(child)
    return found
