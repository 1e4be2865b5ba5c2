"""A planner's output, captured from a pipe into a log file of bounded size.

A planner may print anything, as fast as it likes (the audit's garbage printer wrote 4 GB
in 7 s). :class:`CappedLog` reads the planner's pipe on a thread and writes the file as it
comes, up to ``limit`` bytes. Past that the planner has *flooded*: the file keeps its
beginning (the planner's start-up lines) and, when the log is closed, ends with a line
saying how much was dropped followed by the last ``tail`` bytes (kept in memory in a ring
of chunks), so the file never exceeds ``limit`` bytes and shows how the planner started
and what it printed last. ``on_flood`` is called once, on the reader thread, when the
limit is passed (:class:`~sdc_gym.bridge.process.PlannerProcess` then ends the planner, and
the episode ends with the reason ``log_flooded``).
"""

from __future__ import annotations

import collections
import os
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Final

DEFAULT_LOG_LIMIT_BYTES: Final = 256 * 1024 * 1024
"""A planner's log file is at most this big (256 MiB: hours of a chatty planner's debug
lines; a planner printing garbage reaches it in well under a second)."""
TAIL_FRACTION: Final = 0.25  # of the limit, kept from the end of a flooded log
MAX_TAIL_BYTES: Final = 4 * 1024 * 1024  # ... but at most this much, held in memory
READ_CHUNK: Final = 1 << 16


class CappedLog:
    """Drains the pipe ``fd`` into ``path`` on a thread; see the module docstring.

    Args:
        fd: the read end of the planner's output pipe (closed at its end of file).
        path: the log file (overwritten).
        limit: the file's largest size in bytes (>= 1024).
        on_flood: called once from the reader thread when the output passes ``limit``.
    """

    def __init__(self, fd: int, path: Path, limit: int = DEFAULT_LOG_LIMIT_BYTES,
                 on_flood: Callable[[], None] | None = None) -> None:
        if limit < 1024:
            raise ValueError(f"the planner log limit must be >= 1024 bytes, got {limit}")
        self.path = path
        self.limit = limit
        self.tail_limit = min(int(limit * TAIL_FRACTION), MAX_TAIL_BYTES)
        self.total = 0  # bytes the planner wrote
        self.flooded = False
        self._fd = fd
        self._file = path.open("wb", buffering=0)  # every chunk on disk at once
        self._written = 0
        self._tail: collections.deque[bytes] = collections.deque()
        self._tail_size = 0
        self._lock = threading.Lock()
        self._on_flood = on_flood
        self._thread = threading.Thread(target=self._drain, name=f"planner log {path.name}",
                                        daemon=True)
        self._thread.start()

    def _drain(self) -> None:
        try:
            while chunk := os.read(self._fd, READ_CHUNK):
                self._feed(chunk)
        except OSError:
            pass
        finally:
            os.close(self._fd)  # here, never while this thread might still read it

    def _feed(self, chunk: bytes) -> None:
        flood_now = False
        with self._lock:
            self.total += len(chunk)
            self._tail.append(chunk)
            self._tail_size += len(chunk)
            while self._tail_size - len(self._tail[0]) >= self.tail_limit:
                self._tail_size -= len(self._tail.popleft())
            if not self.flooded and not self._file.closed:
                room = self.limit - self._written
                self._file.write(chunk[:room])  # the file holds the first `limit` bytes
                self._written += min(len(chunk), room)
                if len(chunk) > room:
                    self.flooded = flood_now = True
        if flood_now and self._on_flood is not None:
            self._on_flood()

    def tail_text(self, lines: int) -> str:
        """The last ``lines`` lines printed so far (from memory)."""
        with self._lock:
            data = b"".join(self._tail)[-8192:]
        return "\n".join(data.decode("utf-8", "replace").splitlines()[-lines:])

    def flush(self) -> None:
        with self._lock:
            if not self._file.closed:
                self._file.flush()

    def close(self, timeout: float = 5.0) -> None:
        """Wait for the pipe's end (every writer gone), then finish the file: a flooded
        log becomes its beginning, a line on what was dropped, and the kept tail."""
        self._thread.join(timeout)
        with self._lock:
            if self._file.closed:
                return
            if self.flooded:
                tail = b"".join(self._tail)[-self.tail_limit:]
                marker = (f"\n[sdc_gym: the planner's output passed the log limit of "
                          f"{self.limit} bytes ({self.total} written); "
                          f"{{dropped}} bytes dropped here, the last {len(tail)} follow]\n")
                head = self.limit - len(tail) - len(marker) - 32  # room for the numbers
                dropped = self.total - head - len(tail)
                self._file.seek(head)
                self._file.truncate()
                self._file.write(marker.format(dropped=dropped).encode())
                self._file.write(tail)
            self._file.close()
