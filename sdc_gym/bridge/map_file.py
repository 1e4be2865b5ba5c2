"""Highway maps in the original ``highway_map.csv`` format, for external planners.

One waypoint per line, ``x y s dx dy`` separated by spaces, as in the original's
``data/highway_map.csv``: (x, y) on the centre line in driving order, s the distance along
the waypoint polyline, (dx, dy) the unit normal to the right of travel. The planners
written for the original read this file from a path relative to their working directory
(the template: ``../data/highway_map.csv``) and build their splines through it, so a
planner drives any of our maps once the file is in place. ``load_highway_map`` (and the
env's ``map: <path>``) reads it back. The command line is
:mod:`sdc_gym.bridge.export_map`.

:class:`PlannerMap` puts the env's map where a planner reads its own for the length of a
run and leaves the planner's file as it found it: it writes only when the file there
holds different numbers, and restores the planner's bytes (or removes the file it
created) when the run ends.
"""

from __future__ import annotations

import io
import os
from pathlib import Path
from types import TracebackType
from typing import Final

import numpy as np

from sdc_gym.road.builtin_highways import get_highway_map
from sdc_gym.road.highway_map import HighwayMap

MAP_FILE_NAME: Final = "highway_map.csv"
"""The original's file name, used when the output is a folder."""
_FORMAT: Final = ["%.7g", "%.7g", "%.12g", "%.7g", "%.7g"]  # as write_highway_map


def map_text(highway: HighwayMap) -> str:
    """The map's waypoints as the original file's text."""
    buffer = io.StringIO()
    np.savetxt(buffer, highway.waypoints, fmt=_FORMAT)
    return buffer.getvalue()


def map_file_path(output: str | os.PathLike[str]) -> Path:
    """``output`` itself when it names a ``.csv`` file, else ``output/highway_map.csv``."""
    path = Path(output).expanduser()
    if path.suffix.lower() == ".csv" and not path.is_dir():
        return path
    return path / MAP_FILE_NAME


def export_highway_map(highway: HighwayMap | str, output: str | os.PathLike[str], *,
                       keep_original: bool = False) -> Path:
    """Write ``highway`` (a :class:`HighwayMap`, a built-in name or a map file) in the
    original format to ``output`` (a ``.csv`` file, or a folder for ``highway_map.csv``);
    returns the file written.

    The write is atomic (a temporary file renamed over the target) and skipped when the
    file already holds exactly this map, so parallel episodes may export concurrently.
    ``keep_original``: a different file already there is first renamed to ``<name>.orig``
    (once), so exporting into a planner's data folder never loses its own map.
    """
    if isinstance(highway, str):
        highway = get_highway_map(highway)
    path = map_file_path(output)
    text = map_text(highway)
    if path.is_file():
        if path.read_text(encoding="utf-8", errors="replace") == text:
            return path
        backup = path.with_name(path.name + ".orig")
        if keep_original and not backup.exists():
            os.replace(path, backup)
    _write_atomically(path, text.encode("utf-8"))
    return path


# A map file "holds the same map" when its numbers match ours to the printed precision
# (7 significant digits for x, y, dx, dy).
_SAME_MAP_RTOL: Final = 1e-6
_SAME_MAP_ATOL: Final = 1e-6


def same_map_numbers(text: str, highway: HighwayMap) -> bool:
    """Whether a map file's ``text`` holds ``highway``'s waypoints (numerically)."""
    try:
        rows = np.loadtxt(io.StringIO(text.replace(",", " ")), ndmin=2)
    except ValueError:
        return False
    return rows.shape == highway.waypoints.shape and bool(np.allclose(
        rows, highway.waypoints, rtol=_SAME_MAP_RTOL, atol=_SAME_MAP_ATOL))


def _write_atomically(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


class PlannerMap:
    """The env's map in a planner's map file for the duration of a ``with`` block.

    ``output`` is a ``.csv`` file or a folder (``highway_map.csv`` in it). On entry the
    file is left alone when it already holds these numbers; otherwise the planner's bytes
    are kept in memory and the map is written (atomically). On exit they are written
    back, or the file is removed if there was none. Nested or repeated uses of the same
    file (a run, then its episodes) see the map already there and change nothing.
    """

    def __init__(self, highway: HighwayMap | str, output: str | os.PathLike[str]) -> None:
        self.highway = get_highway_map(highway) if isinstance(highway, str) else highway
        self.path = map_file_path(output)
        self._saved: bytes | None = None
        self._wrote = False

    def __enter__(self) -> Path:
        path = self.path
        if path.is_file():
            original = path.read_bytes()
            if same_map_numbers(original.decode("utf-8", "replace"), self.highway):
                return path
            self._saved = original
        _write_atomically(path, map_text(self.highway).encode("utf-8"))
        self._wrote = True
        return path

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.restore()

    def restore(self) -> None:
        """Put the planner's file back as it was (safe to call twice)."""
        if not self._wrote:
            return
        self._wrote = False
        if self._saved is not None:
            _write_atomically(self.path, self._saved)
            self._saved = None
        else:
            self.path.unlink(missing_ok=True)
