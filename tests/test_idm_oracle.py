"""Our vectorized IDM against highway-env's IDMVehicle, the reference implementation.

highway-env measures the distance to the leader centre to centre; we measure the bumper
gap (see sdc_gym.traffic.idm). The formula is the same, so the oracle feeds both models the
*same* distance: highway-env vehicles are placed ``gap`` metres apart (centre to centre) and
our function gets ``gap`` with ``s0 = DISTANCE_WANTED``. The default mapping itself
(``s0 = DISTANCE_WANTED - LENGTH``) is checked separately.
"""

from __future__ import annotations

import numpy as np
import pytest
from highway_env.road.road import Road, RoadNetwork
from highway_env.vehicle.behavior import IDMVehicle
from highway_env.vehicle.controller import ControlledVehicle

from sdc_gym.traffic.idm import (
    IDMParameters,
    desired_gap,
    idm_acceleration,
    max_speed_for_gap,
)

RTOL = 1e-9
ATOL = 1e-9  # m/s^2: results near zero are differences of nearly equal terms


def _road() -> Road:
    # speed_limit=None: highway-env would otherwise clip the target speed to the lane's.
    network = RoadNetwork.straight_road_network(lanes=1, length=1e6, speed_limit=None)
    return Road(network=network, np_random=np.random.RandomState(0))


def _hw_class(params: IDMParameters) -> type[IDMVehicle]:
    """An IDMVehicle subclass carrying ``params`` (class constants in highway-env)."""
    return type(
        "OracleIDM",
        (IDMVehicle,),
        {
            "COMFORT_ACC_MAX": params.a_max,
            "COMFORT_ACC_MIN": -params.b,
            "TIME_WANTED": params.T,
            "DISTANCE_WANTED": params.s0,
            "DELTA": params.delta,
        },
    )


def _hw_acceleration(cls: type[IDMVehicle], road: Road, speed: float, target: float,
                     gap: float | None, leader_speed: float) -> float:
    """highway-env's acceleration for one situation; ``gap=None`` means no leader."""
    ego = cls(road, [100.0, 0.0], heading=0.0, speed=speed, enable_lane_change=False)
    ego.target_speed = target  # the constructor turns a falsy 0 into the current speed
    road.vehicles = [ego]
    front = None
    if gap is not None:
        front = cls(road, [100.0 + gap, 0.0], heading=0.0, speed=leader_speed)
        road.vehicles.append(front)
        found, _ = road.neighbour_vehicles(ego, ego.lane_index)
        assert found is front  # the oracle's own leader search agrees
    return float(ego.acceleration(ego_vehicle=ego, front_vehicle=front))


def _situations(rng: np.random.Generator, count: int) -> tuple[np.ndarray, ...]:
    speed = rng.uniform(0.0, 35.0, count)
    target = rng.uniform(0.5, 40.0, count)
    gap = rng.uniform(0.5, 150.0, count)
    leader = rng.uniform(0.0, 35.0, count)
    # Edge cases: standing cars, zero target speed (the not_zero guard), tiny gaps.
    speed[:10] = 0.0
    target[10:20] = 0.0
    target[20:25] = 0.005
    gap[25:35] = rng.uniform(0.001, 0.02, 10)
    leader[35:45] = speed[35:45]
    return speed, target, gap, leader


def test_defaults_map_highway_env_constants() -> None:
    p = IDMParameters()
    assert p.a_max == IDMVehicle.COMFORT_ACC_MAX
    assert p.b == -IDMVehicle.COMFORT_ACC_MIN
    assert p.T == IDMVehicle.TIME_WANTED
    assert p.delta == IDMVehicle.DELTA
    assert p.max_braking == IDMVehicle.ACC_MAX
    # highway-env's jam distance is centre to centre for its LENGTH-long cars.
    assert p.s0 == IDMVehicle.DISTANCE_WANTED - ControlledVehicle.LENGTH


@pytest.mark.parametrize("seed", range(4))
def test_matches_highway_env_acceleration(seed: int) -> None:
    rng = np.random.default_rng(seed)
    if seed == 0:
        params = IDMParameters(s0=IDMVehicle.DISTANCE_WANTED, floor_desired_gap=False,
                               max_braking=np.inf)
    else:  # random parameter sets, so no constant is hard-wired by accident
        params = IDMParameters(
            a_max=rng.uniform(0.5, 4.0), b=rng.uniform(1.0, 8.0), T=rng.uniform(0.5, 2.5),
            s0=rng.uniform(1.0, 12.0), delta=rng.uniform(2.0, 6.0),
            max_braking=np.inf, floor_desired_gap=False,
        )
    cls = _hw_class(params)
    road = _road()
    speed, target, gap, leader = _situations(rng, 200)
    expected = np.array([
        _hw_acceleration(cls, road, *args) for args in zip(speed, target, gap, leader, strict=True)
    ])
    ours = idm_acceleration(speed, target, gap, leader, params)
    np.testing.assert_allclose(ours, expected, rtol=RTOL, atol=ATOL)
    # No leader: gap = inf (and the leader speed is ignored, even if nan).
    free_expected = np.array([
        _hw_acceleration(cls, road, v, v0, None, 0.0) for v, v0 in zip(speed, target, strict=True)
    ])
    free = idm_acceleration(speed, target, np.inf, np.nan, params)
    np.testing.assert_allclose(free, free_expected, rtol=RTOL, atol=ATOL)


def test_clipping_matches_act() -> None:
    """IDMVehicle.act() clips to +-ACC_MAX; so does our max_braking (default 6)."""
    params = IDMParameters(s0=IDMVehicle.DISTANCE_WANTED, floor_desired_gap=False)
    road = _road()
    rng = np.random.default_rng(7)
    speed, target, gap, leader = _situations(rng, 150)
    expected = []
    for v, v0, g, vl in zip(speed, target, gap, leader, strict=True):
        ego = IDMVehicle(road, [100.0, 0.0], speed=v, enable_lane_change=False)
        ego.target_speed = v0
        front = IDMVehicle(road, [100.0 + g, 0.0], speed=vl)
        road.vehicles = [ego, front]
        ego.act()
        expected.append(ego.action["acceleration"])
    ours = idm_acceleration(speed, target, gap, leader, params)
    np.testing.assert_allclose(ours, expected, rtol=RTOL, atol=ATOL)
    assert ours.min() == -IDMVehicle.ACC_MAX  # the clip was exercised


def test_floor_keeps_desired_gap_at_least_s0() -> None:
    """With the floor (Treiber), s_star = s0 + max(0, dynamic term); highway-env lets
    s_star go below s0, even negative, and squaring a negative s_star brakes again the
    faster the leader pulls away. The two agree wherever the dynamic term is >= 0."""
    rng = np.random.default_rng(3)
    speed, target, gap, leader = _situations(rng, 500)
    floor = IDMParameters(max_braking=np.inf)
    raw = IDMParameters(max_braking=np.inf, floor_desired_gap=False)
    a_floor = idm_acceleration(speed, target, gap, leader, floor)
    a_raw = idm_acceleration(speed, target, gap, leader, raw)
    dynamic = desired_gap(speed, leader, raw) - raw.s0
    same = dynamic >= 0.0
    assert same.sum() > 100 and (~same).sum() > 50
    np.testing.assert_allclose(a_floor[same], a_raw[same], rtol=1e-12)  # (s0 + x) + y order
    # Elsewhere the floor uses s_star = s0 exactly.
    v, v0, s = speed[~same], np.maximum(target[~same], 0.01), np.maximum(gap[~same], 0.01)
    expected = floor.a_max * (1.0 - (v / v0) ** floor.delta) - floor.a_max * (floor.s0 / s) ** 2
    np.testing.assert_allclose(a_floor[~same], expected, rtol=1e-12, atol=1e-12)
    # highway-env's quirk: a leader pulling away fast enough makes it brake harder.
    quirk = idm_acceleration(20.0, 25.0, 30.0, [45.0, 60.0, 90.0], raw)
    assert quirk[2] < quirk[1] < quirk[0]
    assert np.all(np.diff(idm_acceleration(20.0, 25.0, 30.0, [45.0, 60.0, 90.0], floor)) == 0)


def test_overlap_and_free_road() -> None:
    p = IDMParameters()
    # Overlapping cars (gap <= 0) brake fully; a free road at the desired speed coasts.
    np.testing.assert_array_equal(idm_acceleration([20.0, 0.0], 25.0, [0.0, -3.0], 20.0, p),
                                  [-p.max_braking, -p.max_braking])
    assert idm_acceleration(25.0, 25.0, np.inf, 0.0, p) == 0.0
    assert idm_acceleration(0.0, 25.0, np.inf, 0.0, p) == p.a_max


def test_max_speed_for_gap_is_the_desired_gap_root() -> None:
    rng = np.random.default_rng(11)
    p = IDMParameters()
    gap = rng.uniform(p.s0, 120.0, 300)
    leader = rng.uniform(0.0, 35.0, 300)
    v = max_speed_for_gap(gap, leader, p)
    np.testing.assert_allclose(desired_gap(v, leader, p), gap, rtol=1e-9)
    # At that speed IDM brakes by at most a_max (the interaction term is <= 1).
    assert np.all(idm_acceleration(v, 1e3, gap, leader, p) >= -p.a_max - 1e-9)
    assert max_speed_for_gap(p.s0 - 1.0, 10.0, p) == 0.0
    assert max_speed_for_gap(np.inf, 10.0, p) == np.inf
