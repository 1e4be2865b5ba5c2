"""Highway maps: the original ``x y s dx dy`` format, lanes, and map selection by name or path.

A :class:`HighwayMap` is a reference line (the yellow centre line of the Udacity
highway) with ``lane_count`` lanes of ``lane_width`` metres to its right, lane ``i``
centred at ``d = (i + 0.5) * lane_width`` (2, 6, 10 m for the original's three 4 m lanes).

Loops and open roads
--------------------
A map is a *loop* (the original highway: the file runs once around and the road closes
from its last waypoint back to its first) or an *open road* (the Udacity-Bosch
Challenge's: one way from the first waypoint to the last). The kind comes from the road
itself, by the rule of :func:`~sdc_gym.validation.road_geometry.ends_meet` (the gap from
the last point to the first against the polyline's length and its longest step), or is
said outright with ``road="loop"`` / ``road="open"``; a file that contradicts what it is
said to be is refused with the reason. An open road's reference line is open
(:mod:`sdc_gym.geometry.open_line`: s from the first waypoint, no wrap, the road's end at
:attr:`HighwayMap.end_s`), and its ego starts at :data:`OPEN_START_S` in the middle lane,
at rest, facing along the road.
"""

from __future__ import annotations

import functools
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sdc_gym.geometry.coarse_frenet import CoarseFrenet
from sdc_gym.geometry.original_frenet import OriginalFrenet
from sdc_gym.geometry.reference_line import ReferenceLine, ReferenceLineError
from sdc_gym.validation.road_geometry import (
    check_loop_points,
    check_open_points,
    check_reference_line,
    ends_meet,
)
from sdc_gym.validation.text_files import read_text

# The original simulator's start state (middle lane, at rest, facing +x).
ORIGINAL_START_S = 124.8336
ORIGINAL_START_D = 6.164833
ORIGINAL_START_YAW = 0.0  # rad: the original's car stands facing +x until a path turns it
# Where the original's first telemetry puts the car on its map (to the digits it prints).
ORIGINAL_START_XY = (909.48, 1128.67)
_SAME_START_M = 0.01  # the coarse getXY of the start within this of it: the original map
# A loaded map keeps the original's start heading when its road runs this close to +x there
# (the original map's road heads -0.45 degrees at the start).
_ORIGINAL_HEADING_TOLERANCE = math.radians(5.0)
MIN_HIGHWAY_LOOP_M = 200.0  # a shorter loop has no room for traffic (spawn range 200 m)
MIN_OPEN_ROAD_M = 500.0
"""The shortest open road: room for the traffic's 200 m spawn range ahead of a start and
a run to an end (the Bosch Challenge's roads: 5.1 km)."""
ROAD_KINDS = ("auto", "loop", "open")
"""The ``road`` setting of a map: decided by the geometric rule, or said outright."""
OPEN_START_S = 5.0
"""m: where the ego starts on an open road, its centre 5 m past the first waypoint (its
rear bumper 2.65 m past it, on the road). The challenge's simulator is not public;
participants' planners (e.g. the walkthrough-based ones with the Bosch maps in their
``data/`` folders) start from rest in the middle lane at the road's beginning (their
first telemetry: ``s`` a few metres, ``d`` about 6, speed 0), which this reproduces."""
_END_NORMAL_TOLERANCE = math.radians(30.0)
"""A file's (dx, dy) at an open road's first or last row is replaced by the smooth line's
normal when it points more than this away from it (both Bosch files carry ``1 0`` there,
90 degrees off the road's normal ``0 -1``)."""
MIN_RADIUS_MARGIN_M = 2.0
"""A map file's smallest radius is the road's width plus this (14 m for 3 x 4 m lanes):
the lanes' offset lines stay smooth in a right-hand bend (the original's: 114 m)."""


class MapFormatError(ValueError):
    """A map file or map name that cannot be loaded; the message says which and why."""


@dataclass(frozen=True)
class HighwayMap:
    """A multi-lane highway: a loop, or an open road (``closed`` False).

    Attributes:
        name: built-in name or the file path it came from.
        waypoints: (n, 5) rows ``x y s dx dy`` in the original file format (s along the
            waypoint polyline, (dx, dy) the unit normal to the right of travel).
        reference: the smooth reference line (the centre line, d = 0).
        lane_count: number of lanes right of the centre line.
        lane_width: metres.
        start_s, start_d: the ego car's start in Frenet coordinates.
        start_yaw: the ego car's heading at the start (rad, counter-clockwise from +x);
            ``None``: along the road.
        closed: ``False`` for an open road (see the module docstring).
    """

    name: str
    waypoints: NDArray[np.float64]
    reference: ReferenceLine = field(repr=False)
    lane_count: int = 3
    lane_width: float = 4.0
    start_s: float = ORIGINAL_START_S
    start_d: float = ORIGINAL_START_D
    start_yaw: float | None = None
    closed: bool = True

    @property
    def length(self) -> float:
        """The period of s in metres: a loop's length along the smooth reference line; an
        open road's s never comes around within it (:mod:`sdc_gym.geometry.open_line`)."""
        return self.reference.length

    @property
    def end_s(self) -> float:
        """s of the road's end: an open road's last waypoint; a loop's length."""
        return self.reference.end_s

    @functools.cached_property
    def original_frenet(self) -> OriginalFrenet:
        """The original simulator's Frenet conversion over this map's waypoints (what its
        telemetry reports; see :mod:`sdc_gym.geometry.original_frenet`)."""
        return OriginalFrenet(self.waypoints, closed=self.closed)

    def start_heading(self) -> float:
        """The ego car's heading at the start (rad): :attr:`start_yaw`, else the road's."""
        if self.start_yaw is not None:
            return self.start_yaw
        return float(self.reference.heading(self.reference.wrap_s(self.start_s)))

    @property
    def road_width(self) -> float:
        return self.lane_count * self.lane_width

    def lane_center(self, lane: ArrayLike) -> NDArray[np.float64]:
        """d of the centre of lane(s) ``lane`` (0 = next to the centre line)."""
        return (np.asarray(lane, dtype=np.float64) + 0.5) * self.lane_width

    def lane_of(self, d: ArrayLike) -> NDArray[np.int64]:
        """Lane index holding offset(s) ``d``; -1 left of the road, ``lane_count`` right."""
        lane = np.floor(np.asarray(d, dtype=np.float64) / self.lane_width).astype(np.int64)
        return np.clip(lane, -1, self.lane_count)

    @classmethod
    def from_waypoints(
        cls,
        name: str,
        xy: ArrayLike,
        *,
        lane_count: int = 3,
        lane_width: float = 4.0,
        start_s: float | None = None,
        start_d: float | None = None,
        closed: bool = True,
    ) -> HighwayMap:
        """Build a map from centre-line points in driving order; fills s, dx, dy like the
        original file (s along the polyline, (dx, dy) the right normal of the smooth line).
        ``closed=False``: an open road (starting at :data:`OPEN_START_S` by default)."""
        xy = np.asarray(xy, dtype=np.float64)
        reference = ReferenceLine(xy, closed=closed)
        polyline_s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
        s_on_line, _ = reference.to_frenet(xy)
        normals = reference.normal(s_on_line)
        waypoints = np.column_stack([xy, polyline_s, normals])
        return cls(
            name=name,
            waypoints=waypoints,
            reference=reference,
            lane_count=lane_count,
            lane_width=lane_width,
            start_s=(ORIGINAL_START_S if closed else OPEN_START_S) if start_s is None
            else start_s,
            start_d=(lane_count // 2 + 0.5) * lane_width if start_d is None else start_d,
            closed=closed,
        )


def load_highway_map(path: str | os.PathLike[str], *, lane_count: int = 3,
                     lane_width: float = 4.0, road: str = "auto") -> HighwayMap:
    """Load a map in the original format: one waypoint per line, ``x y s dx dy``.

    ``road``: ``"auto"`` (a loop or an open road by the rule of
    :func:`~sdc_gym.validation.road_geometry.ends_meet`), ``"loop"`` or ``"open"`` (said
    outright; a file that is not what it is said to be is refused with the reason). An
    open road is checked by :func:`_load_open` (at least 3 rows, 500 m .. 100 km, simple,
    of sane radius).

    The smooth reference line goes through the (x, y) columns; s, dx, dy are kept as read
    (the coarse compatibility helpers use them). Raises :class:`MapFormatError` naming the
    file, line and problem for anything else: not UTF-8 text, not 5 numbers a line, s not
    increasing, (dx, dy) not a unit normal, and a loop that is not closed, is collinear,
    crosses itself, bends tighter than the road's width plus 2 m or is not 200 m .. 100 km
    long (:mod:`sdc_gym.validation.road_geometry`).
    """
    path = Path(path)
    text = read_text(path, "map file", MapFormatError)
    rows: list[list[float]] = []
    for line_number, line in enumerate(text.splitlines(), start=1):
        text_line = line.strip()
        if not text_line or text_line.startswith("#"):
            continue
        fields = text_line.replace(",", " ").split()
        if len(fields) != 5:
            hint = (" (4 fields: a track waypoint file x,y,z,yaw? It goes in TrackLoop-v0's "
                    "'track' key)" if len(fields) == 4 else "")
            raise MapFormatError(
                f"{path}:{line_number}: expected 5 numbers 'x y s dx dy', "
                f"got {len(fields)} field(s): {text_line!r}{hint}"
            )
        try:
            values = [float(value) for value in fields]
        except ValueError as error:
            raise MapFormatError(
                f"{path}:{line_number}: not a number in {text_line!r} ({error})"
            ) from None
        if not all(np.isfinite(values)):
            raise MapFormatError(f"{path}:{line_number}: non-finite value in {text_line!r}")
        rows.append(values)
    if road not in ROAD_KINDS:
        raise MapFormatError(f"{path}: road must be one of {list(ROAD_KINDS)}, got {road!r}")
    waypoints = np.asarray(rows, dtype=np.float64)
    is_open = road == "open" or (road == "auto" and len(rows) >= 3
                                 and not ends_meet(waypoints[:, :2]))
    if not is_open and len(rows) < 4:
        raise MapFormatError(
            f"{path}: a closed highway needs at least 4 waypoints, got {len(rows)}")
    if is_open and len(rows) < 3:
        raise MapFormatError(f"{path}: an open road needs at least 3 waypoints, got {len(rows)}")
    if np.any(np.diff(waypoints[:, 2]) <= 0):
        bad = int(np.flatnonzero(np.diff(waypoints[:, 2]) <= 0)[0]) + 2
        raise MapFormatError(f"{path}: s must increase along the file (it does not at row {bad})")
    normal_length = np.hypot(waypoints[:, 3], waypoints[:, 4])
    if np.any(np.abs(normal_length - 1.0) > 0.01):
        bad = int(np.flatnonzero(np.abs(normal_length - 1.0) > 0.01)[0]) + 1
        raise MapFormatError(f"{path}: (dx, dy) of row {bad} is not a unit normal")
    if is_open:
        return _load_open(path, waypoints, lane_count, lane_width)
    check_loop_points(waypoints[:, :2], str(path), MapFormatError,
                      min_length=MIN_HIGHWAY_LOOP_M)
    try:
        reference = ReferenceLine(waypoints[:, :2])
    except ReferenceLineError as error:
        raise MapFormatError(f"{path}: {error}") from None
    check_reference_line(reference, str(path), MapFormatError,
                         min_radius=lane_count * lane_width + MIN_RADIUS_MARGIN_M)
    # The original places the car where the template's coarse getXY puts (s, d) =
    # (124.8336, 6.164833): x = 909.48, y = 1128.67 on the original map. Start at that
    # point, expressed in the exact Frenet frame (s = 124.935, d = 6.098 there), facing +x
    # as the original's car does where the road runs (about) that way.
    start_xy = CoarseFrenet.from_waypoints(waypoints).get_xy(ORIGINAL_START_S, ORIGINAL_START_D)
    if math.dist(start_xy, ORIGINAL_START_XY) <= _SAME_START_M:
        start_xy = ORIGINAL_START_XY  # exactly where the original's car stands (getXY: 0.1 mm off)
    start_s, start_d = reference.to_frenet(np.asarray(start_xy))
    road_heading = float(reference.heading(start_s))
    start_yaw = (ORIGINAL_START_YAW if abs(math.remainder(road_heading - ORIGINAL_START_YAW,
                                                          math.tau))
                 <= _ORIGINAL_HEADING_TOLERANCE else None)
    return HighwayMap(
        name=str(path),
        waypoints=waypoints,
        reference=reference,
        lane_count=lane_count,
        lane_width=lane_width,
        start_s=float(start_s),
        start_d=float(start_d),
        start_yaw=start_yaw,
    )


def _load_open(path: Path, waypoints: NDArray[np.float64], lane_count: int,
               lane_width: float) -> HighwayMap:
    """The open road of ``waypoints`` (checked rows of ``path``): its open reference line,
    (dx, dy) of the end rows mended where the file's are no normal of the road, the start at
    :data:`OPEN_START_S` in the middle lane facing along the road."""
    check_open_points(waypoints[:, :2], str(path), MapFormatError, min_length=MIN_OPEN_ROAD_M)
    try:
        reference = ReferenceLine(waypoints[:, :2], closed=False)
    except ReferenceLineError as error:
        raise MapFormatError(f"{path}: {error}") from None
    check_reference_line(reference, str(path), MapFormatError,
                         min_radius=lane_count * lane_width + MIN_RADIUS_MARGIN_M)
    waypoints = mend_end_normals(waypoints, reference)
    return HighwayMap(name=str(path), waypoints=waypoints, reference=reference,
                      lane_count=lane_count, lane_width=lane_width, start_s=OPEN_START_S,
                      start_d=(lane_count // 2 + 0.5) * lane_width, start_yaw=None,
                      closed=False)


def mend_end_normals(waypoints: NDArray[np.float64],
                     reference: ReferenceLine) -> NDArray[np.float64]:
    """``waypoints`` with (dx, dy) of the first and last rows replaced by the smooth line's
    right normal there when the file's points more than 30 degrees away from it (the
    Bosch files' ``1 0``). The original's telemetry rule reads the road's direction at a
    waypoint from these columns (:mod:`sdc_gym.geometry.original_frenet`), so a wrong one
    at the first row would misjudge every point near the start."""
    mended = waypoints.copy()
    for row, s in ((0, 0.0), (len(waypoints) - 1, reference.end_s)):
        nx, ny = reference.normal(s)
        dx, dy = waypoints[row, 3:5]
        if dx * nx + dy * ny < math.cos(_END_NORMAL_TOLERANCE):
            mended[row, 3:5] = nx, ny
    return mended


def write_highway_map(highway: HighwayMap, path: str | os.PathLike[str]) -> None:
    """Write ``highway`` in the original ``x y s dx dy`` format (atomically)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    np.savetxt(tmp, highway.waypoints, fmt=["%.7g", "%.7g", "%.12g", "%.7g", "%.7g"])
    os.replace(tmp, path)
