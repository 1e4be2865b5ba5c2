"""Export any of our highway maps in the original ``highway_map.csv`` format.

    python -m sdc_gym.bridge.export_map --map default --output ~/CarND-Path-Planning-Project/data/
    python -m sdc_gym.bridge.export_map --map oval --output /tmp/oval_map.csv

``--map`` is a built-in map or a map file; ``--output`` (required: there is no default
place, so nothing lands in the folder a command happens to run from) a ``.csv`` file or a
folder to write ``highway_map.csv`` into, relative to the working folder: the planner's
own data folder, from which the original's planners load it (usually ``../data/``
relative to their build folder). The line printed names the file written, as an absolute
path. See :mod:`sdc_gym.bridge.map_file`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sdc_gym.bridge.map_file import MAP_FILE_NAME, export_highway_map
from sdc_gym.road.builtin_highways import BUILTIN_HIGHWAYS, get_highway_map
from sdc_gym.road.highway_map import MapFormatError


def main(argv: list[str] | None = None) -> Path:
    parser = argparse.ArgumentParser(
        prog="python -m sdc_gym.bridge.export_map", description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--map", default="default",
                        help=f"a built-in map ({', '.join(BUILTIN_HIGHWAYS)}) or a map file in "
                             "the original format (default: default)")
    parser.add_argument("--output", required=True,
                        help=f"a .csv file, or a folder to write {MAP_FILE_NAME} into")
    args = parser.parse_args(argv)
    try:
        highway = get_highway_map(args.map)
    except MapFormatError as error:
        parser.error(str(error))
    path = export_highway_map(highway, args.output)
    print(f"wrote {path.absolute()}: {len(highway.waypoints)} waypoints, loop "
          f"{highway.length:.1f} m along the smooth centre line ({highway.name}, "
          f"{highway.lane_count} lanes of {highway.lane_width:g} m)")
    return path


if __name__ == "__main__":
    main()
