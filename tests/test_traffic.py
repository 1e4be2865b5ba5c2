"""Traffic model: known answers for determinism, safety, spawning, lane changes, kinematics.

The ego car here is scripted (it "drives steadily"): it never reacts to traffic, so any
contact with it is its own business; the checks below are about traffic among itself,
except where a test is about traffic reacting to the ego.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from sdc_gym.road.highway_map import HighwayMap, load_highway_map
from sdc_gym.traffic import (
    MPH,
    TRUCK,
    VEHICLE_TYPES,
    HighwayTraffic,
    TrafficConfig,
    TrafficSamples,
    spawn_probabilities,
)

DT = 0.02
ORIGINAL_MAP = (
    Path(__file__).resolve().parents[2] / "shared/data/udacity/path_planning/highway_map.csv"
)


@cache
def highway() -> HighwayMap:
    """The original highway when available (curves down to ~112 m radius), else an oval."""
    if ORIGINAL_MAP.is_file():
        return load_highway_map(ORIGINAL_MAP)
    t = np.linspace(0.0, 2.0 * np.pi, 240, endpoint=False)
    return HighwayMap.from_waypoints("oval", np.column_stack([1500 * np.cos(t), 400 * np.sin(t)]))


def footprints_overlap(x: np.ndarray, y: np.ndarray, heading: np.ndarray,
                       length: np.ndarray, width: np.ndarray) -> np.ndarray:
    """``(steps, n)`` poses and ``(n,)`` sizes -> ``(steps, n, n)``: do oriented rectangles
    i and j overlap? Separating-axis test on the four edge normals; diagonal False."""
    dx = x[:, None, :] - x[:, :, None]
    dy = y[:, None, :] - y[:, :, None]
    c, s = np.cos(heading), np.sin(heading)
    ci, si, cj, sj = c[:, :, None], s[:, :, None], c[:, None, :], s[:, None, :]
    li, wi = 0.5 * length[None, :, None], 0.5 * width[None, :, None]
    lj, wj = 0.5 * length[None, None, :], 0.5 * width[None, None, :]
    overlap = np.ones(dx.shape, dtype=bool)
    for ax, ay in ((ci, si), (-si, ci), (cj, sj), (-sj, cj)):
        reach_i = li * np.abs(ci * ax + si * ay) + wi * np.abs(ci * ay - si * ax)
        reach_j = lj * np.abs(cj * ax + sj * ay) + wj * np.abs(cj * ay - sj * ax)
        overlap &= np.abs(dx * ax + dy * ay) < reach_i + reach_j
    idx = np.arange(x.shape[1])
    overlap[:, idx, idx] = False
    return overlap


def ego_pose(road: HighwayMap, s: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, ...]:
    """World x, y, heading of a scripted ego driving along its lane."""
    xy = road.reference.to_xy(s, d)
    return xy[..., 0], xy[..., 1], road.reference.heading(s)


def drive(traffic: HighwayTraffic, ego_s: float, ego_d: float, speed: float | np.ndarray,
          seconds: float, chunk: int = 25) -> Iterator[tuple[TrafficSamples, np.ndarray]]:
    """Scripted ego at constant (or per-chunk) speed; yields samples and the ego's s."""
    chunks = round(seconds / (chunk * DT))
    speeds = np.broadcast_to(np.asarray(speed, dtype=float), (chunks,))
    steps = np.arange(1, chunk + 1)
    for k in range(chunks):
        s = ego_s + speeds[k] * DT * steps
        ego_s = float(s[-1])
        yield traffic.advance(chunk, s, np.full(chunk, ego_d), np.full(chunk, speeds[k])), s


def relative_s(traffic: HighwayTraffic, s: np.ndarray, ego_s: float | np.ndarray) -> np.ndarray:
    return traffic.road.reference.s_difference(s, ego_s)


# --------------------------------------------------------------------------- determinism
def _trajectory(seed: int, chunks: list[int]) -> list[np.ndarray]:
    road = highway()
    traffic = HighwayTraffic(road, TrafficConfig(rogue=True, rogue_rate=3.0))
    traffic.reset(np.random.default_rng(seed), road.start_s, road.start_d, 0.0)
    out, ego_s, v = [], road.start_s, 0.0
    for steps in chunks:
        v_steps = np.minimum(v + 0.1 * np.arange(1, steps + 1), 22.0)
        s = ego_s + np.cumsum(v_steps) * DT
        ego_s, v = float(s[-1]), float(v_steps[-1])
        smp = traffic.advance(steps, s, np.full(steps, road.start_d), v_steps)
        out += [smp.s, smp.d, smp.speed, smp.x, smp.y, smp.heading, smp.vx, smp.vy,
                traffic.spawn_count.copy(), traffic.type_index.copy(), traffic.target_lane.copy()]
    return out


def test_same_seed_is_bit_identical_and_seeds_differ() -> None:
    chunks = [5] * 600  # one simulated minute
    a, b, c = _trajectory(3, chunks), _trajectory(3, chunks), _trajectory(4, chunks)
    assert all(np.array_equal(u, v) for u, v in zip(a, b, strict=True))
    assert not np.array_equal(a[-11], c[-11])


def test_chunking_does_not_change_the_motion() -> None:
    """Decisions fall on the same physics steps however advance() is chunked."""
    runs = [_trajectory(9, chunks) for chunks in ([5] * 40, [40] * 5, [3, 17, 1, 79, 100])]
    finals = [np.concatenate([r[-11][-1], r[-10][-1], r[-9][-1]]) for r in runs]  # s, d, v
    for other in finals[1:]:
        np.testing.assert_allclose(other, finals[0], rtol=0, atol=1e-9)


# --------------------------------------------------------------------------- safety
@pytest.mark.parametrize(("cars", "seeds", "minutes"), [(12, 20, 3.0), (50, 3, 1.0)])
def test_no_traffic_collisions(cars: int, seeds: int, minutes: float) -> None:
    road = highway()
    for seed in range(seeds):
        traffic = HighwayTraffic(road, TrafficConfig(car_count=cars))
        ego_d = (2.0, 6.0, 10.0)[seed % 3]
        traffic.reset(np.random.default_rng(seed), road.start_s, ego_d, 21.0)
        for k, (smp, _) in enumerate(drive(traffic, road.start_s, ego_d, 21.0, minutes * 60)):
            hit = footprints_overlap(smp.x, smp.y, smp.heading, traffic.length, traffic.width)
            assert not hit.any(), f"seed {seed}: cars {np.argwhere(hit)[0][1:]} touch, chunk {k}"


def test_merging_from_both_sides_is_resolved() -> None:
    """Two cars wanting the middle lane at the same instant from lanes 0 and 2: one goes,
    the other sees it there and stays; nobody touches."""
    road = highway()
    traffic = HighwayTraffic(road, TrafficConfig(lane_change_max_braking_imposed=np.inf))
    s0 = 2000.0
    traffic.reset_to(np.random.default_rng(0), s0 - 120.0, -6.0, 15.0,
                     s=[s0, s0, s0 + 40, s0 + 40], lane=[0, 2, 0, 2],
                     speed=[20.0, 20.0, 12.0, 12.0], desired_speed=[26.0, 26.0, 12.0, 12.0])
    started = []
    for smp, _ in drive(traffic, s0 - 120.0, -6.0, 15.0, 12.0, chunk=5):
        hit = footprints_overlap(smp.x, smp.y, smp.heading, traffic.length, traffic.width)
        assert not hit.any()
        into_middle = traffic.target_lane[:2] == 1
        started.append(into_middle.copy())
        if into_middle.all():  # both may go only once they no longer overlap +-20 m in s
            assert abs(relative_s(traffic, traffic.s[0], traffic.s[1])) >= 20.0 - 2.0
    first = next(k for k, st in enumerate(started) if st.any())
    assert started[first].sum() == 1  # exactly one went at that decision


# --------------------------------------------------------------------------- spawning
def test_spawn_speeds_depend_on_the_side() -> None:
    road = highway()
    lo_a, hi_a = 40.0 * MPH, 50.0 * MPH
    lo_b, hi_b = 50.0 * MPH, 60.0 * MPH
    ahead = behind = respawned = 0
    for seed in range(10):
        traffic = HighwayTraffic(road, TrafficConfig())
        traffic.reset(np.random.default_rng(seed), road.start_s, 6.0, 0.0)
        rel = relative_s(traffic, traffic.s, road.start_s)
        v0 = traffic.desired_speed
        assert np.all((v0[rel > 0] >= lo_a) & (v0[rel > 0] <= hi_a))
        assert np.all((v0[rel < 0] >= lo_b) & (v0[rel < 0] <= hi_b))
        ahead, behind = ahead + (rel > 0).sum(), behind + (rel < 0).sum()
        spawns = traffic.spawn_count.copy()
        # An ego much faster, then much slower than traffic: recycling on both sides.
        speeds = np.r_[np.full(40, 30.0), np.full(40, 8.0)]
        for _, ego_s in drive(traffic, road.start_s, 6.0, speeds, 80.0, chunk=50):
            for i in np.flatnonzero(traffic.spawn_count != spawns):
                respawned += 1
                side = relative_s(traffic, traffic.s[i], ego_s[-1])
                lo, hi = (lo_a, hi_a) if side > 0 else (lo_b, hi_b)
                assert lo <= traffic.desired_speed[i] <= hi
            spawns = traffic.spawn_count.copy()
            assert np.array_equal(traffic.ids, np.arange(traffic.n))  # fixed slots
    assert ahead > 20 and behind > 20 and respawned > 50


def test_recycling_keeps_cars_near_the_ego_without_overlap() -> None:
    road = highway()
    config = TrafficConfig()
    traffic = HighwayTraffic(road, config)
    traffic.reset(np.random.default_rng(1), road.start_s, 6.0, 25.0)
    ego_d, ego_len, ego_w = 6.0, config.ego_length, config.ego_width
    # Fast (cars fall behind), stopped dead (cars run away, queue behind), slow.
    speeds = np.r_[np.full(600, 30.0), np.zeros(600), np.full(600, 12.0)]  # per 0.1 s
    spawns = traffic.spawn_count.copy()
    respawns = same_side = 0
    reappeared = {"ahead": [], "behind": []}  # s from the ego at the end of the chunk
    last_rel = relative_s(traffic, traffic.s, road.start_s)
    for smp, ego_s in drive(traffic, road.start_s, ego_d, speeds, 180.0, chunk=5):
        rel = relative_s(traffic, smp.s, ego_s[:, None])
        # Recycling runs at decisions (0.2 s), two cars at most: a car running away at
        # up to 30 m/s relative can be 6 m past the range (12 m if it waits a turn).
        assert np.abs(rel).max() <= config.spawn_range + 12.0
        renewed = traffic.spawn_count != spawns
        for offset in rel[-1, renewed]:
            reappeared["ahead" if offset > 0 else "behind"].append(abs(offset))
        same_side += int(np.sum(np.sign(rel[-1, renewed]) == np.sign(last_rel[renewed])))
        last_rel = rel[-1]
        # Newcomers (and everyone) keep clear of each other and of the ego.
        ex, ey, eh = ego_pose(road, ego_s, np.full(len(ego_s), ego_d))
        x = np.column_stack([smp.x, ex])
        y = np.column_stack([smp.y, ey])
        h = np.column_stack([smp.heading, eh])
        hit = footprints_overlap(x, y, h, np.r_[traffic.length, ego_len],
                                 np.r_[traffic.width, ego_w])
        new = np.r_[traffic.spawn_count != spawns, False]  # the ego (last) is not new
        assert not hit[:, new].any() and not hit[:, :-1, :-1].any()
        respawns += int(new.sum())
        spawns = traffic.spawn_count.copy()
    assert respawns > 20
    # The original's coin: both sides, whichever way the cars left (they fall behind
    # while the ego is fast and run away ahead while it stands); within the bands (+- the
    # distance the car and the ego drift apart within the 0.1 s chunk).
    ahead, behind = np.array(reappeared["ahead"]), np.array(reappeared["behind"])
    assert len(ahead) >= 0.25 * respawns and len(behind) >= 0.25 * respawns
    assert same_side >= 0.25 * respawns  # not always on the other side of the ego
    lo, hi = config.respawn_ahead
    assert np.all((ahead > lo - 4.0) & (ahead < hi + 4.0))
    lo, hi = config.respawn_behind
    assert np.all((behind > lo - 4.0) & (behind < hi + 4.0))


# --------------------------------------------------------------------------- lane changes
def _lane_change_run(ego_offset: list[float], seconds: float,
                     sustain: float = 1.0) -> list[int]:
    """Car 0 in lane 0 behind a slow car 1; the ego in lane 1 holds ``ego_offset[k]`` metres
    (in s) from car 0 during decision interval k (0.1 s: decisions every 5 frames here).
    Returns car 0's target lane per decision."""
    road = highway()
    config = TrafficConfig(lane_change_max_braking_imposed=np.inf, lane_change_sustain=sustain,
                           decision_period=5)
    traffic = HighwayTraffic(road, config)
    s0 = 3000.0
    traffic.reset_to(np.random.default_rng(0), s0 + ego_offset[0], 6.0, 20.0,
                     s=[s0, s0 + 40.0], lane=[0, 0], speed=[20.0, 12.0],
                     desired_speed=[26.0, 12.0])
    targets = []
    steps = np.arange(1, 6)
    for k in range(round(seconds / 0.1)):
        offset = ego_offset[min(k, len(ego_offset) - 1)]
        # The ego moves with car 0 (its acceleration is held, so this is nearly exact).
        ego_s = traffic.s[0] + offset + traffic.speed[0] * DT * steps
        traffic.advance(5, ego_s, np.full(5, 6.0), np.full(5, traffic.speed[0]))
        targets.append(int(traffic.target_lane[0]))
    return targets


@pytest.mark.parametrize("offset", [-15.0, -19.5, 15.0])
def test_no_lane_change_into_a_lane_occupied_within_20_m(offset: float) -> None:
    assert set(_lane_change_run([offset], 8.0)) == {0}


@pytest.mark.parametrize("offset", [-20.5, -30.0])
def test_lane_change_after_the_sustain_time_when_clear(offset: float) -> None:
    targets = _lane_change_run([offset], 4.0)
    # Wish first seen at the decision at t = 0; it must hold 1.0 s: the change starts at the
    # decision at t = 1.0 s, which runs at the start of the 11th 0.1 s advance.
    assert targets.index(1) == 10


def test_lane_change_waits_for_the_gap_to_stay_clear() -> None:
    blocked = 30  # decisions (3 s) with the ego beside, then it drops back
    targets = _lane_change_run([-15.0] * blocked + [-40.0], 8.0, sustain=1.5)
    assert set(targets[:blocked]) == {0}
    # The decision in interval `blocked` still saw the ego at -15 (the latest sample before
    # it); the first clear one is the next, and 1.5 s later the change starts.
    assert targets.index(1) == blocked + 1 + 15


# --------------------------------------------------------------------------- kinematics
def test_frenet_kinematics_on_a_circle() -> None:
    radius, v, d = 300.0, 20.0, 10.0
    t = np.linspace(0.0, 2.0 * np.pi, 200, endpoint=False)
    road = HighwayMap.from_waypoints("circle", np.column_stack([radius * np.cos(t),
                                                               radius * np.sin(t)]))
    traffic = HighwayTraffic(road, TrafficConfig(lateral_wander=0.0))
    traffic.reset_to(np.random.default_rng(0), 50.0, -6.0, v, s=[50.0], lane=[2], speed=[v])
    kappa = float(road.reference.curvature(50.0))
    assert kappa == pytest.approx(1.0 / radius, rel=1e-4)  # counter-clockwise: left turn
    travelled = 0.0
    last = 50.0
    for smp, _ in drive(traffic, 50.0, -6.0, v, 20.0, chunk=50):
        travelled += float(np.sum(np.diff(np.r_[last, smp.s[:, 0]]) % road.length))
        last = float(smp.s[-1, 0])
        np.testing.assert_allclose(np.hypot(smp.vx, smp.vy), v, rtol=1e-5)
        np.testing.assert_allclose(smp.speed, v, rtol=1e-12)
        np.testing.assert_allclose(np.hypot(smp.x, smp.y), radius + d, atol=1e-3)
        np.testing.assert_allclose(smp.heading, np.arctan2(smp.vy, smp.vx), atol=1e-12)
    # The outer lane is longer: s (on the centre line) advances at v / (1 + kappa d).
    assert travelled == pytest.approx(20.0 * v / (1.0 + kappa * d), rel=1e-5)


def test_world_pose_matches_the_reference_line() -> None:
    road = highway()
    traffic = HighwayTraffic(road, TrafficConfig(car_count=20))
    traffic.reset(np.random.default_rng(2), road.start_s, 6.0, 20.0)
    now = traffic.samples_now()
    *_, (smp, _) = drive(traffic, road.start_s, 6.0, 20.0, 30.0)
    xy = road.reference.to_xy(smp.s, smp.d)
    np.testing.assert_allclose(smp.x, xy[..., 0], atol=1e-3)
    np.testing.assert_allclose(smp.y, xy[..., 1], atol=1e-3)
    # State arrays = the last sample; samples_now() reproduces it.
    again = traffic.samples_now()
    for name in ("s", "d", "speed", "x", "y", "heading", "vx", "vy"):
        np.testing.assert_allclose(getattr(traffic, name), getattr(smp, name)[-1], atol=1e-9)
        np.testing.assert_allclose(getattr(again, name)[0], getattr(smp, name)[-1], atol=1e-9)
        assert getattr(now, name).shape == (1, traffic.n)
    lanes = np.floor(traffic.d / road.lane_width).astype(int)
    np.testing.assert_array_equal(traffic.lane, np.clip(lanes, 0, road.lane_count - 1))


# --------------------------------------------------------------------------- the ego
def _behind_stopped_ego(lane_changes: bool) -> tuple[HighwayTraffic, list[float], list[bool]]:
    road = highway()
    config = TrafficConfig(lane_change_min_gain=0.2 if lane_changes else np.inf)
    traffic = HighwayTraffic(road, config)
    ego_s, ego_d = 4000.0, 6.0
    traffic.reset_to(np.random.default_rng(0), ego_s, ego_d, 0.0, s=[ego_s - 150.0],
                     lane=[1], speed=[25.0])
    gaps, touching = [], []
    ex, ey, eh = ego_pose(road, np.array([ego_s]), np.array([ego_d]))
    for smp, _ in drive(traffic, ego_s, ego_d, 0.0, 40.0):
        steps = len(smp.s)
        hit = footprints_overlap(
            np.column_stack([smp.x, np.full(steps, ex)]),
            np.column_stack([smp.y, np.full(steps, ey)]),
            np.column_stack([smp.heading, np.full(steps, eh)]),
            np.r_[traffic.length, config.ego_length], np.r_[traffic.width, config.ego_width])
        touching.append(bool(hit.any()))
        kappa = road.reference.curvature(smp.s[:, 0])
        gap = (relative_s(traffic, ego_s, smp.s[:, 0]) * (1.0 + kappa * smp.d[:, 0])
               - 0.5 * (traffic.length[0] + config.ego_length))
        gaps += gap.tolist()
    return traffic, gaps, touching


def test_traffic_stops_behind_a_stopped_ego() -> None:
    traffic, gaps, touching = _behind_stopped_ego(lane_changes=False)
    assert not any(touching)
    assert min(gaps) > 0.0
    assert traffic.speed[0] < 0.05
    assert 4.0 < gaps[-1] < 7.0  # IDM settles at the jam distance s0 = 5 m
    assert traffic.lane[0] == 1


def test_traffic_passes_a_stopped_ego_without_touching_it() -> None:
    traffic, _, touching = _behind_stopped_ego(lane_changes=True)
    assert not any(touching)
    assert traffic.lane[0] != 1 or traffic.speed[0] < 0.05


# --------------------------------------------------------------------------- rogue mode
def _rogue_events(config: TrafficConfig) -> tuple[int, int, HighwayTraffic]:
    """(hard-braking episodes, cut-ins) measured from outside: a deceleration beyond
    4.5 m/s^2, and a lane change started with someone in the target lane within 20 m."""
    road = highway()
    traffic = HighwayTraffic(road, config)
    ego_d = -6.0  # off the road: the ego disturbs nobody
    traffic.reset(np.random.default_rng(4), road.start_s, ego_d, 20.0)
    braking = np.zeros(traffic.n, dtype=bool)
    hard = cut_ins = 0
    prev = (traffic.spawn_count.copy(), traffic.speed.copy(), traffic.s.copy(),
            traffic.lane.copy(), traffic.target_lane.copy())
    for smp, _ in drive(traffic, road.start_s, ego_d, 20.0, 120.0, chunk=5):
        spawns, speed, s, lane, target = prev
        same = traffic.spawn_count == spawns
        decel = -np.diff(np.vstack([speed, smp.speed]), axis=0) / DT
        now_braking = same & (decel.max(axis=0) > 4.5)
        hard += int((now_braking & ~braking).sum())
        braking = now_braking
        for i in np.flatnonzero(same & (traffic.target_lane != target)):
            k = traffic.target_lane[i]
            there = (lane == k) | (target == k)
            there[i] = False
            cut_ins += int(np.any(there & (np.abs(relative_s(traffic, s, s[i])) < 20.0)))
        hit = footprints_overlap(smp.x, smp.y, smp.heading, traffic.length, traffic.width)
        assert not hit.any()  # even rogue traffic does not crash into itself
        prev = (traffic.spawn_count.copy(), smp.speed[-1].copy(), traffic.s.copy(),
                traffic.lane.copy(), traffic.target_lane.copy())
    return hard, cut_ins, traffic


def test_rogue_mode_brakes_hard_and_cuts_in_default_does_not() -> None:
    hard, cut_ins, traffic = _rogue_events(TrafficConfig())
    assert (hard, cut_ins) == (0, 0)
    assert (traffic.rogue_brake_count, traffic.rogue_cut_in_count) == (0, 0)
    hard, cut_ins, traffic = _rogue_events(TrafficConfig(rogue=True, rogue_rate=4.0))
    assert hard >= 10 and cut_ins >= 5
    assert traffic.rogue_brake_count >= 10 and traffic.rogue_cut_in_count >= 5


# --------------------------------------------------------------------------- configuration
def test_vehicle_types_and_mix() -> None:
    lengths = {t.name: t.length for t in VEHICLE_TYPES}
    assert lengths["motorcycle"] < lengths["car"] < lengths["suv"] < lengths["truck"]
    np.testing.assert_allclose(spawn_probabilities().sum(), 1.0)
    with pytest.raises(ValueError):
        spawn_probabilities((1.0, 2.0))
    road = highway()
    mix = tuple(1.0 if i == TRUCK else 0.0 for i in range(len(VEHICLE_TYPES)))
    traffic = HighwayTraffic(road, TrafficConfig(vehicle_mix=mix, car_count=8))
    traffic.reset(np.random.default_rng(0), road.start_s, 6.0)
    assert np.all(traffic.type_index == TRUCK)
    assert np.all(traffic.length == VEHICLE_TYPES[TRUCK].length)


@pytest.mark.parametrize("bad", [
    {"car_count": -1}, {"density": 0.0}, {"decision_period": 0},
    {"respawn_ahead": (100.0, 50.0)}, {"respawn_behind": (-5.0, 50.0)},
    {"respawn_ahead_probability": 1.5}, {"vehicle_mix": (1.0, -1.0, 0.0, 0.0)},
])
def test_config_validation(bad: dict) -> None:
    with pytest.raises(ValueError):
        TrafficConfig(**bad)


def test_density_and_impossible_placement() -> None:
    road = highway()
    spreads = []
    for density in (0.75, 3.0):
        traffic = HighwayTraffic(road, TrafficConfig(density=density))
        traffic.reset(np.random.default_rng(0), road.start_s, 6.0)
        spreads.append(np.abs(relative_s(traffic, traffic.s, road.start_s)).max())
    assert spreads[1] < 0.5 * spreads[0]
    with pytest.raises(ValueError, match="cannot place"):
        HighwayTraffic(road, replace(TrafficConfig(), car_count=200)).reset(
            np.random.default_rng(0), road.start_s, 6.0)
