"""Highway maps in the original ``highway_map.csv`` format, for external planners.

One waypoint per line, ``x y s dx dy`` separated by spaces, as in the original's
``data/highway_map.csv``: (x, y) on the centre line in driving order, s the distance along
the waypoint polyline, (dx, dy) the unit normal to the right of travel. The planners
written for the original read this file from a path relative to their working directory
(the template: ``../data/highway_map.csv``) and build their splines through it, so a
planner drives any of our maps once the file is in place. ``load_highway_map`` (and the
env's ``map: <path>``) reads it back. The command line is
:mod:`sdc_gym.bridge.export_map`.
"""

from __future__ import annotations

import io
import os
from pathlib import Path
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
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path
