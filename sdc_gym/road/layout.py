"""Closed road layouts made of straights and circular arcs: closure and sampling.

The built-in highways (:mod:`sdc_gym.road.builtin_highways`) and tracks
(:mod:`sdc_gym.road.builtin_tracks`) are described as a table of segments, driven
counter-clockwise from the origin heading along +x:

* ``("straight", length_m)``, or ``("straight", None)`` for a *free* straight whose length
  is solved so that the loop closes;
* ``("arc", radius_m, turn_degrees)``, positive turning left.

A layout must turn +360 degrees in total. It has either no free straight (then it must
close by itself) or exactly two, whose lengths are the solution of a 2 x 2 linear system:
the end point of the layout is linear in the straight lengths, so two free straights of
different directions can always bring it back to the start (positive lengths are checked).
"""

from __future__ import annotations

import math

import numpy as np

from sdc_gym.geometry.fixed_order import solve_2x2

Segment = tuple[str, float | None] | tuple[str, float, float]
"""``("straight", length m | None = solved for closure)`` or ``("arc", radius m, turn deg)``."""


def closing_lengths(layout: tuple[Segment, ...]) -> list[float]:
    """Lengths (m) of the free straights that close the loop, in layout order (none or two).

    Raises ``ValueError`` when the layout does not turn 360 degrees, does not close, has
    one or more than two free straights, or would need a non-positive straight.
    """
    heading = 0.0
    displacement = np.zeros(2)
    free_directions: list[np.ndarray] = []
    for segment in layout:
        if segment[0] == "straight":
            direction = np.array([math.cos(heading), math.sin(heading)])
            if segment[1] is None:
                free_directions.append(direction)
            else:
                displacement += segment[1] * direction
        else:
            _, radius, degrees = segment
            turn = math.radians(degrees)
            end = heading + turn
            side = np.sign(turn)
            displacement += radius * side * np.array(
                [math.sin(end) - math.sin(heading), math.cos(heading) - math.cos(end)]
            )
            heading = end
    if not np.isclose(heading, 2 * np.pi):
        raise ValueError(f"layout turns {np.degrees(heading):.3f} deg, a CCW loop needs 360")
    if not free_directions:
        if not np.allclose(displacement, 0.0, atol=1e-6):
            raise ValueError(f"layout does not close: it ends at {displacement}")
        return []
    if len(free_directions) != 2:
        raise ValueError("a layout needs none or exactly two free straights to close")
    # A fixed-order solve, not np.linalg.solve: LAPACK's last bit depends on the processor.
    lengths = solve_2x2(np.column_stack(free_directions), -displacement)
    if min(lengths) <= 0:
        raise ValueError(f"layout cannot close with positive straights: {lengths}")
    return [float(length) for length in lengths]


def sample_layout(layout: tuple[Segment, ...], spacing: float) -> np.ndarray:
    """(n, 2) points along the closed layout roughly every ``spacing`` m (last != first).

    Each straight gets ``max(round(length / spacing), 1)`` equal steps and each arc
    ``max(round(arc length / spacing), 2)``, so every joint is a sample.
    """
    free = iter(closing_lengths(layout))
    position = np.zeros(2)
    heading = 0.0
    points = [position.copy()]
    for segment in layout:
        if segment[0] == "straight":
            length = next(free) if segment[1] is None else segment[1]
            count = max(round(length / spacing), 1)
            direction = np.array([math.cos(heading), math.sin(heading)])
            for k in range(1, count + 1):
                points.append(position + direction * length * k / count)
            position = position + direction * length
        else:
            _, radius, degrees = segment
            turn = math.radians(degrees)
            side = np.sign(turn)
            centre = position + radius * side * np.array([-math.sin(heading), math.cos(heading)])
            count = max(round(radius * abs(turn) / spacing), 2)
            for k in range(1, count + 1):
                angle = heading + turn * k / count
                points.append(
                    centre + radius * side * np.array([math.sin(angle), -math.cos(angle)]))
            heading += turn
            position = points[-1]
    return np.asarray(points[:-1])  # the last point is the first again
