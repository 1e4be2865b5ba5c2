"""An episode's driving summary as TensorBoard scalars under ``driving/``.

The same figures for every framework, so that SB3 and RLlib runs show the same curves:
incidents per episode by kind and in all, success, distance, mean speed, and lap time
from the episodes that complete a lap (the committed config's 240 s training episodes,
about 3/4 of a lap, never do; every episode has its distance).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

PREFIX = "driving/"


def driving_metrics(summary: Mapping[str, Any]) -> Iterator[tuple[str, float]]:
    """``(name, value)`` pairs of one finished episode's ``info["summary"]``; each is
    averaged over the episodes of a logging interval."""
    incidents = summary.get("incidents", {})
    for kind, count in incidents.items():
        yield f"{PREFIX}{kind}_per_episode", count
    yield f"{PREFIX}incidents_per_episode", sum(incidents.values())
    yield f"{PREFIX}success", float(summary.get("is_success", False))
    for lap in summary.get("lap_times") or ():
        yield f"{PREFIX}lap_time_s", lap
    if summary.get("distance") is not None:
        yield f"{PREFIX}distance_m", summary["distance"]
    if summary.get("mean_speed_mph") is not None:
        yield f"{PREFIX}mean_speed_mph", summary["mean_speed_mph"]
