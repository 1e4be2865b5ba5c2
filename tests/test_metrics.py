"""Known-answer tests of the shared driving metrics (block rule, incidents, laps)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from sdc_gym.metrics import INCIDENT_KINDS, DrivingMetrics, Incident, IncidentRules

DT = 0.02
RULES = IncidentRules()


def feed(
    metrics: DrivingMetrics,
    xy: np.ndarray,
    s: np.ndarray,
    d: np.ndarray,
    speed: np.ndarray,
    ids: np.ndarray | None = None,
    chunk: int = 1,
) -> list[Incident]:
    """Record a trajectory ``chunk`` steps per call; return the incidents record() returned."""
    found: list[Incident] = []
    for i in range(0, len(speed), chunk):
        sl = slice(i, i + chunk)
        found += metrics.record(xy[sl], s[sl], d[sl], speed[sl], None if ids is None else ids[sl])
    return found


def straight(speeds: np.ndarray, x0: float = 0.0, d: float = 6.0) -> tuple[np.ndarray, ...]:
    """A straight drive along +x whose step displacement is speed * dt."""
    speeds = np.asarray(speeds, dtype=float)
    x = x0 + np.cumsum(speeds * DT)
    xy = np.stack([x, np.zeros_like(x)], axis=1)
    return xy, x.copy(), np.full(len(x), d), speeds


def circle(
    n: int, radius: float, speed: float, s0: float = 0.0, direction: float = 1.0
) -> tuple[np.ndarray, ...]:
    """``n`` steps at constant speed exactly on a circle; s is arc length, wrapped."""
    length = 2.0 * math.pi * radius
    arc = s0 + direction * speed * DT * np.arange(1, n + 1)
    theta = arc / radius
    xy = np.stack([radius * np.cos(theta), radius * np.sin(theta)], axis=1)
    return xy, np.mod(arc, length), np.full(n, 6.0), np.full(n, speed)


def straight_metrics(speed0: float = 20.0) -> DrivingMetrics:
    m = DrivingMetrics(RULES, loop_length=1.0e6)
    m.reset(0.0, 0.0, 0.0, 6.0, speed0)
    return m


# ---------------------------------------------------------------- block rule
def test_constant_speed_on_circle_gives_v2_over_r() -> None:
    radius, v = 100.0, 20.0
    m = DrivingMetrics(RULES, loop_length=2.0 * math.pi * radius)
    m.reset(radius, 0.0, 0.0, 6.0, v)
    xy, s, d, speed = circle(500, radius, v)  # 10 s = 50 blocks
    for i in range(0, 500, 10):  # one block per call: read each block's values
        assert m.record(xy[i : i + 10], s[i : i + 10], d[i : i + 10], speed[i : i + 10]) == []
        assert m.last_normal_acceleration == pytest.approx(v**2 / radius, rel=0.005)
        assert m.last_tangential_acceleration == 0.0
    assert m.incident_counts["acceleration"] == 0
    assert m.max_acceleration == pytest.approx(4.0, rel=0.005)
    assert m.max_jerk < 1e-6
    # Raw per-step acceleration on the circle is the centripetal one too.
    assert m.max_raw_acceleration == pytest.approx(4.0, rel=0.005)


def test_constant_acceleration_then_acceleration_incident() -> None:
    m = straight_metrics(speed0=0.0)
    t = np.arange(1, 151) * DT
    speed1 = 3.0 * t  # 3 m/s^2 from rest for 3 s
    xy, s, d, _ = straight(speed1)
    xy[:, 0] = s = 0.5 * 3.0 * t**2  # exact positions of uniform acceleration
    for i in range(0, 150, 10):
        m.record(xy[i : i + 10], s[i : i + 10], d[i : i + 10], speed1[i : i + 10])
        if i > 0:
            assert m.last_tangential_acceleration == pytest.approx(3.0, abs=1e-6)
    assert m.last_normal_acceleration == 0.0
    assert m.incident_counts["acceleration"] == 0
    assert m.last_raw_acceleration == pytest.approx(3.0, rel=1e-6)

    t2 = np.arange(1, 51) * DT  # then 12 m/s^2 for 1 s: 9 -> 21 m/s
    speed2 = 9.0 + 12.0 * t2
    x2 = 13.5 + 9.0 * t2 + 0.5 * 12.0 * t2**2
    xy2 = np.stack([x2, np.zeros_like(x2)], axis=1)
    found = feed(m, xy2, x2, np.full(50, 6.0), speed2, chunk=5)
    assert [inc.kind for inc in found] == ["acceleration"]
    assert found[0].value >= 10.0
    assert m.incident_counts == {k: int(k == "acceleration") for k in INCIDENT_KINDS}
    assert m.last_tangential_acceleration == pytest.approx(12.0, abs=1e-6)
    assert m.last_raw_acceleration == pytest.approx(12.0, rel=1e-6)


def test_stop_dead_is_an_acceleration_incident() -> None:
    m = straight_metrics(20.0)
    speeds = np.r_[np.full(25, 20.0), np.zeros(25)]
    found = feed(m, *straight(speeds), chunk=5)
    assert [inc.kind for inc in found] == ["acceleration"]
    # Block 3 (steps 21-30) has mean speed 10: AccT = (10 - 20) / 0.2 = -50.
    assert found[0].step == 30
    assert found[0].value == pytest.approx(50.0)
    assert m.max_raw_acceleration == pytest.approx(1000.0, rel=1e-6)
    assert m.max_raw_jerk == pytest.approx(1000.0 / DT, rel=1e-6)
    assert m.last_raw_acceleration == 0.0


def test_jerk_from_window_means() -> None:
    # Windows of 1 s: constant 20 m/s, brake at 12 m/s^2, constant, constant, accelerate
    # at 12 m/s^2, constant. Speed is constant within each 0.2 s block, so every block
    # total is exactly 0 or 12 and the window jerks are 0, +12, -12, 0, +12, -12.
    block_speeds = [20.0] * 5
    for profile in (-12.0, 0.0, 0.0, 12.0, 0.0):
        for _ in range(5):
            block_speeds.append(block_speeds[-1] + profile * 0.2)
    speeds = np.repeat(block_speeds, 10)
    m = straight_metrics(20.0)
    jerks = []
    xy, s, d, _ = straight(speeds)
    found = []
    for i in range(0, len(speeds), 50):  # one window per call
        found += m.record(xy[i : i + 50], s[i : i + 50], d[i : i + 50], speeds[i : i + 50])
        jerks.append(m.last_jerk)
    assert jerks == pytest.approx([0.0, 12.0, -12.0, 0.0, 12.0, -12.0], abs=1e-9)
    jerk_incidents = [inc for inc in found if inc.kind == "jerk"]
    # +12 then -12 in consecutive windows is one event; the second brake is another.
    assert [inc.step for inc in jerk_incidents] == [100, 250]
    assert [inc.value for inc in jerk_incidents] == pytest.approx([12.0, 12.0])
    assert m.max_jerk == pytest.approx(12.0)
    assert m.incident_counts["acceleration"] == 2
    assert m.incident_counts["speed"] == 0


def test_jerk_below_limit_is_no_incident() -> None:
    block_speeds = [20.0] * 5 + [20.0 - 1.9 * (i + 1) for i in range(5)]  # 9.5 m/s^2
    speeds = np.repeat(block_speeds, 10)
    m = straight_metrics(20.0)
    feed(m, *straight(speeds), chunk=5)
    assert m.last_jerk == pytest.approx(9.5)
    assert m.incident_counts["jerk"] == 0
    assert m.incident_counts["acceleration"] == 0


# ---------------------------------------------------------------- per-step incidents
def test_speed_limit() -> None:
    speeds = np.r_[np.full(10, 22.0), np.full(3, 22.4), np.full(10, 22.0), np.full(2, 22.4)]
    m = straight_metrics(22.0)
    found = feed(m, *straight(speeds), chunk=4)
    assert [(inc.kind, inc.step, inc.value) for inc in found] == [
        ("speed", 11, 22.4),
        ("speed", 24, 22.4),
    ]
    for v in (22.35, 22.352):  # the limit itself is allowed (strictly above is speeding)
        m = straight_metrics(v)
        assert feed(m, *straight(np.full(50, v)), chunk=3) == []
        assert m.max_speed == v


@pytest.mark.parametrize(("steps", "expected"), [(150, 0), (151, 1), (400, 1)])
def test_lane_straddle(steps: int, expected: int) -> None:
    m = straight_metrics()
    found = feed(m, *straight(np.full(steps, 20.0), d=4.0), chunk=5)
    assert m.incident_counts["lane"] == expected
    if expected:
        assert found[0].step == 151
        assert found[0].value == pytest.approx(151 * DT)


def test_lane_straddle_run_restarts_after_leaving_the_band() -> None:
    d = np.r_[np.full(151, 8.0), np.full(5, 10.0), np.full(150, 3.5), np.full(1, 6.0)]
    xy, s, _, speed = straight(np.full(len(d), 20.0))
    m = straight_metrics()
    feed(m, xy, s, d, speed, chunk=7)
    assert m.incident_counts["lane"] == 1
    m = DrivingMetrics(IncidentRules(straddle_bands=()), loop_length=1.0e6)
    m.reset(0.0, 0.0, 0.0, 6.0, 20.0)
    feed(m, xy, s, d, speed, chunk=7)
    assert m.incident_counts["lane"] == 0


def test_off_road_and_collisions() -> None:
    xy, s, d, speed = straight(np.full(5, 20.0))
    d[2] = 0.5
    ids = np.array([-1, 3, 3, -1, 3])
    m = straight_metrics()
    found = feed(m, xy, s, d, speed, ids, chunk=5)
    assert [(inc.kind, inc.step, inc.value) for inc in found] == [
        ("collision", 2, 3.0),
        ("off_road", 3, 0.5),
        ("collision", 5, 3.0),
    ]
    assert found[1].d == 0.5 and found[1].x == pytest.approx(3 * 20.0 * DT)
    # A contact continuing across calls is still one; a different car is a new one.
    m = straight_metrics()
    feed(m, xy, s, np.full(5, 6.0), speed, np.array([7, 7, 7, 9, 9]), chunk=1)
    assert m.incident_counts["collision"] == 2
    assert m.incident_counts["off_road"] == 0


def test_off_road_upper_edge_counts_once_per_excursion() -> None:
    d = np.r_[np.full(3, 11.3), np.full(3, 10.0), np.full(3, 11.2), np.full(2, 12.0)]
    xy, s, _, speed = straight(np.full(len(d), 20.0))
    m = straight_metrics()
    feed(m, xy, s, d, speed, chunk=2)
    assert m.incident_counts["off_road"] == 2  # 11.2 is on the road (strict bound)


# ---------------------------------------------------------------- laps and distances
def test_laps_on_a_circle() -> None:
    radius, v = 100.0, 20.0
    length = 2.0 * math.pi * radius
    n = int(2.5 * length / v / DT)
    m = DrivingMetrics(RULES, loop_length=length)
    s0 = 100.0
    m.reset(radius * math.cos(s0 / radius), radius * math.sin(s0 / radius), s0, 6.0, v)
    feed(m, *circle(n, radius, v, s0=s0), chunk=5)
    assert m.laps_completed == 2
    assert m.lap_times == pytest.approx([length / v] * 2, abs=DT)
    assert m.progress == pytest.approx(n * v * DT, rel=1e-9)
    # Chords are a hair shorter than the arc.
    assert m.distance == pytest.approx(n * v * DT, rel=1e-6)
    summary = m.summary()
    assert summary["laps"] == 2 and summary["mean_lap_time"] == pytest.approx(length / v, abs=DT)
    assert summary["mean_speed"] == pytest.approx(v, rel=1e-6)


def test_driving_backwards_never_completes_a_lap() -> None:
    radius, v = 100.0, 20.0
    length = 2.0 * math.pi * radius
    n = int(2.5 * length / v / DT)
    m = DrivingMetrics(RULES, loop_length=length)
    s0 = 100.0
    m.reset(radius * math.cos(s0 / radius), radius * math.sin(s0 / radius), s0, 6.0, v)
    feed(m, *circle(n, radius, v, s0=s0, direction=-1.0), chunk=5)
    assert m.laps_completed == 0
    assert m.lap_times == []
    assert m.progress == pytest.approx(-n * v * DT, rel=1e-9)
    assert m.summary()["mean_lap_time"] is None


def test_distance_without_incident() -> None:
    m = straight_metrics()
    xy, s, d, speed = straight(np.full(171, 20.0))  # 0.4 m per step
    d[50] = 0.5  # off road at step 51
    d[150] = 0.5  # and at step 151
    feed(m, xy[:50], s[:50], d[:50], speed[:50], chunk=5)
    assert m.distance_without_incident == pytest.approx(20.0)
    assert m.longest_distance_without_incident == pytest.approx(20.0)
    feed(m, xy[50:51], s[50:51], d[50:51], speed[50:51])
    assert m.distance_without_incident == 0.0
    assert m.longest_distance_without_incident == pytest.approx(20.4)
    feed(m, xy[51:], s[51:], d[51:], speed[51:], chunk=7)
    assert m.incident_counts["off_road"] == 2
    assert m.distance_without_incident == pytest.approx(20 * 0.4)
    assert m.longest_distance_without_incident == pytest.approx(100 * 0.4)
    assert m.distance == pytest.approx(171 * 0.4)


# ---------------------------------------------------------------- invariance and reports
def rich_trajectory(n: int = 4000) -> tuple[np.ndarray, ...]:
    """Speeds over the limit, a stop-dead, lane weaving, a long straddle, off-road, contacts."""
    radius = 120.0
    t = np.arange(1, n + 1) * DT
    speed = 15.0 + 8.0 * np.sin(2.0 * math.pi * t / 17.0)
    speed[2000:2100] = 0.0
    arc = 30.0 + np.cumsum(speed * DT)
    theta = arc / radius
    xy = np.stack([radius * np.cos(theta), radius * np.sin(theta)], axis=1)
    d = 6.0 + 4.5 * np.sin(2.0 * math.pi * t / 9.0)
    d[1000:1200] = 4.0
    d[3000:3020] = 12.5
    ids = np.full(n, -1)
    ids[500:510] = 4
    ids[510:515] = 8
    ids[700] = 4
    return xy, np.mod(arc, 2.0 * math.pi * radius), d, speed, ids


def test_chunking_invariance() -> None:
    radius = 120.0
    traj = rich_trajectory()
    results = []
    for chunk in (1, 3, 5, 7):
        m = DrivingMetrics(RULES, loop_length=2.0 * math.pi * radius)
        m.reset(radius * math.cos(0.25), radius * math.sin(0.25), 30.0, 6.0, 15.0)
        found = feed(m, *traj, chunk=chunk)
        assert found == m.incidents
        results.append((m.summary(), m.incidents, m.step_info(), m.lap_times))
    # The trajectory really exercises every rule.
    summary = results[0][0]
    assert all(summary["incidents"][kind] > 0 for kind in INCIDENT_KINDS), summary
    assert summary["laps"] >= 1
    for other in results[1:]:
        assert other == results[0]


def test_step_info_and_summary_are_plain_python() -> None:
    m = DrivingMetrics(RULES, loop_length=2.0 * math.pi * 120.0)
    m.reset(120.0 * math.cos(0.25), 120.0 * math.sin(0.25), 30.0, 6.0, 15.0)
    assert json.dumps(m.summary())  # no steps yet: no division by zero, no laps
    xy, s, d, speed, ids = rich_trajectory()
    keys = None
    for i in range(0, len(speed), 5):
        m.record(xy[i : i + 5], s[i : i + 5], d[i : i + 5], speed[i : i + 5], ids[i : i + 5])
        info = m.step_info()
        keys = keys or list(info)
        assert list(info) == keys
        assert all(type(v) in (int, float) for v in info.values()), info
    assert {f"incidents_{k}" for k in INCIDENT_KINDS} <= set(keys)
    assert info["incidents"] == sum(info[f"incidents_{k}"] for k in INCIDENT_KINDS) > 0
    summary = m.summary()
    assert json.loads(json.dumps(summary)) == summary
    assert set(summary["incidents"]) == set(INCIDENT_KINDS)
    assert json.dumps([inc.as_dict() for inc in m.incidents])


def test_reset_clears_the_episode_and_record_needs_reset() -> None:
    with pytest.raises(RuntimeError):
        DrivingMetrics(RULES, loop_length=100.0).record(
            np.zeros((1, 2)), np.zeros(1), np.zeros(1), np.zeros(1)
        )
    m = straight_metrics()
    feed(m, *straight(np.r_[np.full(25, 20.0), np.zeros(25)]))
    assert m.incident_counts["acceleration"] == 1
    m.reset(0.0, 0.0, 0.0, 6.0, 20.0)
    assert m.steps == 0 and m.distance == 0.0 and m.incidents == []
    assert m.incident_counts == dict.fromkeys(INCIDENT_KINDS, 0)
    assert m.max_raw_acceleration == 0.0


def test_rules_are_validated_and_frozen() -> None:
    with pytest.raises(ValueError):
        IncidentRules(straddle_bands=((4.8, 3.2),))
    with pytest.raises(ValueError):
        IncidentRules(road_d_min=5.0, road_d_max=1.0)
    with pytest.raises(AttributeError):
        RULES.speed_limit = 30.0  # type: ignore[misc]
    assert RULES.block_seconds == pytest.approx(0.2)
    assert RULES.jerk_window_seconds == pytest.approx(1.0)
