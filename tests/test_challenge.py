"""The Bosch Challenge's reading of timed runs: verdicts, columns, the lower bound."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats

from sdc_evaluation import challenge
from sdc_gym.units import METERS_PER_MILE


def _run(seed: int, reached: bool, time: float | None, incidents=(), reason="distance_target",
         run_time: float = 200.0) -> dict:
    return {"agent": "fsm_bold", "seed": seed, "time": run_time, "termination_reason": reason,
            "incident_log": [dict(kind=k, s=s, time=t) for k, s, t in incidents],
            "goal": {"kind": "distance_target", "distance_target": 4425.6, "end_s": 5106.0,
                     "reached": reached, "time": time, "driven": 4425.6 if reached else 10.0}}


def test_verdicts_read_the_challenges_rules() -> None:
    assert challenge.verdict(_run(0, True, 203.14)) == "finished in 203.14 s"
    assert challenge.verdict(_run(1, False, None, [("collision", 1234.4, 61.0)],
                                  "stop_at_incident")) == "invalid: collision at 1234 m (61.00 s)"
    assert challenge.verdict(_run(2, False, None, reason="max_duration",
                                  run_time=360.0)) == "invalid: over 360 s"
    columns = challenge.columns([_run(0, True, 200.0), _run(1, True, 210.0),
                                 _run(2, False, None, reason="max_duration")])
    assert columns["challenge_finished"] == 2 and columns["challenge_runs"] == 3
    assert columns["challenge_time"] == 205.0 and columns["challenge_best_time"] == 200.0
    # Student t over the finished runs (the project's intervals): 205 +- t(0.975, 1) * 5.
    half = scipy.stats.t.ppf(0.975, 1) * 5.0
    assert columns["challenge_time_ci"] == pytest.approx((205.0 - half, 205.0 + half))


def test_lower_bound_is_the_time_optimal_launch_then_the_limit() -> None:
    # 2.75 miles are 4425.70 m; the challenge's figure is 4425.6 m (the presets use it).
    assert 2.75 * METERS_PER_MILE == pytest.approx(4425.6, abs=0.1)
    target = 4425.6
    limit = 50.0 * 0.44704
    bound = challenge.lower_bound_time(target, limit, 10.0, 10.0)
    assert bound == pytest.approx(199.614, abs=1e-3)
    # The same by integrating the profile: jerk +10 for 1 s, acceleration 10 held, jerk -10
    # for 1 s, then the limit.
    dt = 1e-5
    hold = limit / 10.0 - 10.0 / 10.0  # 1.2352 s at 10 m/s^2 between the two 1 s ramps
    jerk = np.concatenate([np.full(100_000, 10.0), np.zeros(round(hold / dt)),
                           np.full(100_000, -10.0)])
    accel = np.cumsum(jerk) * dt
    speed = np.cumsum(accel) * dt
    assert speed[-1] == pytest.approx(limit, abs=1e-3)
    covered = speed.sum() * dt
    launch = len(jerk) * dt
    assert bound == pytest.approx(launch + (target - covered) / limit, abs=2e-3)
    with pytest.raises(ValueError, match="shorter than the launch"):
        challenge.lower_bound_time(10.0, limit, 10.0, 10.0)
