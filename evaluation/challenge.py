"""Timed runs on open roads (the Udacity-Bosch Challenge): the time, its interval, a verdict.

An episode on an open road with a ``distance_target`` ends with ``summary["goal"]``
(:mod:`sdc_gym.envs.road_ends`): whether and in which frame the target was driven. The
challenge's rules (udacity/Bosch-Challenge README) read it three ways, per run:

* ``finished in T s``: the target driven within the time limit, without incident;
* ``invalid: <kind> at <s> m``: the first incident of any kind ends the run (the
  challenge's simulator stopped there; the env does with ``stop_at_incident``);
* ``invalid: over <limit> s``: the time limit passed first (360 s in the challenge).

Per agent the table (:func:`sdc_evaluation.tables.challenge_table`) gives the runs
finished, the mean challenge time over the finished runs with its 95 % bootstrap interval
over seeds, and the best time; the verdict of each run is in ``episodes.csv``
(``challenge_verdict``) and in the table's caption.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from sdc_evaluation import statistics


def is_timed(run: dict[str, Any]) -> bool:
    """Whether ``run`` (an episode's summary) is a timed run to a distance target."""
    goal = run.get("goal")
    return isinstance(goal, dict) and goal.get("distance_target") is not None


def verdict(run: dict[str, Any]) -> str:
    """The run's reading by the challenge's rules (see the module docstring)."""
    goal = run["goal"]
    incidents = run.get("incident_log") or []
    if incidents:
        first = incidents[0]
        return f"invalid: {first['kind']} at {first['s']:.0f} m ({first['time']:.2f} s)"
    if goal["reached"]:
        return f"finished in {goal['time']:.2f} s"
    if run.get("termination_reason") == "road_end":
        return "invalid: the road ended before the target"
    return f"invalid: over {run.get('time', 0.0):.0f} s"


def finished(run: dict[str, Any]) -> bool:
    """Finished within the rules: the target reached, no incident on the way."""
    return bool(run["goal"]["reached"]) and not run.get("incident_log")


def columns(runs: Sequence[dict[str, Any]],
            settings: statistics.Settings = statistics.DEFAULT_SETTINGS) -> dict[str, Any]:
    """An agent's challenge columns: runs finished, the mean time of those with its
    interval, the best time."""
    times = np.array([run["goal"]["time"] for run in runs if finished(run)], dtype=np.float64)
    interval = statistics.mean_interval(times, "challenge_time", settings)
    return {"challenge_finished": len(times), "challenge_runs": len(runs),
            "challenge_time": interval.value, "challenge_time_ci": interval.ci(),
            "challenge_best_time": float(times.min()) if len(times) else None,
            "challenge_verdicts": [[run.get("seed"), verdict(run)] for run in runs]}


def lower_bound_time(distance: float, speed_limit: float, max_acceleration: float,
                     max_jerk: float) -> float:
    """The least time to drive ``distance`` m from rest without exceeding ``speed_limit``
    (m/s), ``max_acceleration`` (m/s^2) or ``max_jerk`` (m/s^3): the time-optimal launch
    (jerk at +J until the acceleration reaches A, A held, jerk at -J until it is 0 exactly
    at the limit), then the limit to the end.

    The launch lasts ``T = v/A + A/J`` (``2 sqrt(v/J)`` when A is never reached, v < A^2/J);
    its speed profile is point-symmetric about its middle, so it covers ``v T / 2`` and the
    whole run takes ``distance / v + T / 2``: the launch costs half its own duration. The
    Bosch Challenge's figures (4425.6 m, 50 mph = 22.352 m/s, the original's 10 m/s^2 and
    10 m/s^3): T = 3.235 s, the bound 197.996 + 1.618 = 199.61 s.
    """
    v, a, j = speed_limit, max_acceleration, max_jerk
    if min(distance, v, a, j) <= 0.0:
        raise ValueError(f"distance, speed_limit, max_acceleration and max_jerk must be > 0, "
                         f"got {distance}, {v}, {a}, {j}")
    launch = v / a + a / j if v >= a * a / j else 2.0 * (v / j) ** 0.5
    if v * launch / 2.0 > distance:
        raise ValueError(f"{distance} m is shorter than the launch to {v} m/s "
                         f"({v * launch / 2.0:.1f} m): the limit is never reached")
    return distance / v + launch / 2.0
