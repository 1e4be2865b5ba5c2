"""Reference line, Frenet conversions, the original map, built-in maps, coarse helpers."""

from __future__ import annotations

import numpy as np
import pytest

from sdc_gym.geometry.coarse_frenet import CoarseFrenet
from sdc_gym.geometry.reference_line import ReferenceLine, ReferenceLineError
from sdc_gym.road.builtin_highways import get_highway_map
from sdc_gym.road.highway_map import HighwayMap, MapFormatError, load_highway_map, write_highway_map


def circle(radius: float, count: int, clockwise: bool = False) -> np.ndarray:
    angles = np.linspace(0, 2 * np.pi, count, endpoint=False)
    if clockwise:
        angles = -angles
    return np.column_stack([radius * np.cos(angles), radius * np.sin(angles)])


def test_circle_length_curvature_and_frenet_are_exact():
    line = ReferenceLine(circle(200.0, 60))
    # A periodic cubic spline through 60 points on a circle is within 1e-5 of it.
    assert line.length == pytest.approx(2 * np.pi * 200.0, rel=2e-5)
    s = np.linspace(0, line.length, 500, endpoint=False)
    assert np.allclose(line.curvature(s), 1 / 200.0, rtol=1e-3)
    # Counter-clockwise: the right-hand normal points outward, so d = r - R.
    s_out, d_out = line.to_frenet(np.array([[0.0, 210.0], [0.0, 190.0]]))
    assert d_out == pytest.approx([10.0, -10.0], abs=1e-3)
    assert s_out[0] == pytest.approx(s_out[1], abs=1e-4)


def test_clockwise_loop_has_negative_curvature():
    line = ReferenceLine(circle(100.0, 40, clockwise=True))
    assert np.all(line.curvature(np.linspace(0, line.length, 50)) < 0)


def test_parameter_is_arc_length():
    line = ReferenceLine(circle(300.0, 24) * [1.0, 0.5])  # an ellipse: non-uniform speed
    s = np.linspace(0, line.length, 20001)
    chords = np.hypot(*np.diff(line.position(s), axis=0).T)
    assert chords.sum() == pytest.approx(line.length, rel=1e-8)
    assert np.allclose(chords, s[1] - s[0], rtol=5e-6)


def test_original_map_length_and_lanes(original_highway):
    highway = original_highway
    assert len(highway.waypoints) == 181
    assert highway.reference.polyline_length == pytest.approx(6945.554, abs=0.01)
    assert highway.length == pytest.approx(6945.554, rel=1e-3)
    radius = 1 / np.abs(highway.reference.curvature(np.linspace(0, highway.length, 20000)))
    assert radius.min() == pytest.approx(112, abs=5)
    # The original puts lane centres at waypoint + d * (dx, dy); ours agree within 1 cm.
    for lane, lane_d in enumerate((2.0, 6.0, 10.0)):
        points = highway.waypoints[:, :2] + lane_d * highway.waypoints[:, 3:5]
        _, d = highway.reference.to_frenet(points)
        assert np.abs(d - lane_d).max() < 0.01
        assert highway.lane_center(lane) == lane_d
    # The waypoints lie on the line, and their s agrees with the file's polyline s.
    s, d = highway.reference.to_frenet(highway.waypoints[:, :2])
    assert np.abs(d).max() < 1e-3
    assert np.abs(highway.reference.s_difference(s, highway.waypoints[:, 2])).max() < 2.0


def test_frenet_round_trip_global_and_warm_started(original_highway):
    line = original_highway.reference
    rng = np.random.default_rng(3)
    s = rng.uniform(0, line.length, 2000)
    d = rng.uniform(-2, 14, 2000)
    xy = line.to_xy(s, d)
    s_global, d_global = line.to_frenet(xy)
    assert np.abs(line.s_difference(s_global, s)).max() < 1e-7
    assert np.abs(d_global - d).max() < 1e-7
    # A moving car: warm start from a nearby s; a wrong guess falls back to global search.
    for guess in (s + 2.0, s - 5.0, s + 3000.0):
        s_local, d_local = line.to_frenet(xy, s_guess=guess)
        assert np.abs(line.s_difference(s_local, s)).max() < 1e-7
        assert np.abs(d_local - d).max() < 1e-7


def test_s_wraps_at_the_seam(original_highway):
    line = original_highway.reference
    assert line.s_difference(5.0, line.length - 5.0) == pytest.approx(10.0)
    assert line.s_difference(line.length - 5.0, 5.0) == pytest.approx(-10.0)
    s, _ = line.to_frenet(line.to_xy(np.array([line.length - 0.5, 0.5]), np.array([6.0, 6.0])))
    assert s == pytest.approx([line.length - 0.5, 0.5], abs=1e-7)


def test_default_highway_has_the_original_character():
    highway = get_highway_map("default")
    assert highway.lane_count == 3 and highway.lane_width == 4.0
    assert 6800 < highway.length < 7000
    s = np.linspace(0, highway.length, 40000, endpoint=False)
    curvature = highway.reference.curvature(s)
    assert 100 < 1 / np.abs(curvature).max() < 120  # smallest radius about 110 m
    # Counter-clockwise: total turning +2 pi; some right-hand bends; long straights.
    assert np.sum(curvature) * (s[1] - s[0]) == pytest.approx(2 * np.pi, rel=1e-4)
    assert (curvature < -1e-4).mean() > 0.05
    assert (np.abs(curvature) < 1e-4).mean() > 0.3
    # Deterministic: rebuilt from scratch gives the same points.
    from sdc_gym.road.builtin_highways import _DEFAULT_LAYOUT
    from sdc_gym.road.layout import sample_layout

    first, again = sample_layout(_DEFAULT_LAYOUT, 20.0), sample_layout(_DEFAULT_LAYOUT, 20.0)
    assert np.array_equal(first, again)


def test_map_selection_by_name_or_path_and_round_trip(tmp_path):
    assert get_highway_map("default") is get_highway_map("default")
    oval = get_highway_map("oval")
    path = tmp_path / "oval.csv"
    write_highway_map(oval, path)
    loaded = get_highway_map(str(path))
    assert loaded.length == pytest.approx(oval.length, rel=1e-6)
    with pytest.raises(MapFormatError, match="neither a built-in"):
        get_highway_map("no_such_map")
    with pytest.raises(MapFormatError, match="built-in name"):
        get_highway_map("")


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("1 2 3 4\n", "expected 5 numbers"),
        ("1 2 x 0 1\n" * 5, "not a number"),
        ("0 0 0 0 -1\n10 0 10 0 -1\n", "at least 4 waypoints"),
        ("0 0 0 0 -1\n10 0 10 0 -1\n10 10 5 1 0\n0 10 30 0 1\n", "s must increase"),
        ("0 0 0 0 -1\n10 0 10 0 -1\n10 10 20 1 1\n0 10 30 0 1\n", "not a unit normal"),
        ("0 0 0 0 -1\n0 0 10 0 -1\n10 10 20 1 0\n0 10 30 0 1\n", "coincide"),
        ("0 0 0 0 -1\nnan 0 10 0 -1\n10 10 20 1 0\n0 10 30 0 1\n", "non-finite"),
    ],
)
def test_malformed_map_files_give_clear_errors(tmp_path, content, message):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(MapFormatError, match=message):
        load_highway_map(path)


def test_reference_line_rejects_bad_waypoints():
    with pytest.raises(ReferenceLineError, match="at least 4"):
        ReferenceLine(np.zeros((3, 2)))
    with pytest.raises(ReferenceLineError, match="shape"):
        ReferenceLine(np.zeros((10, 3)))


def test_coarse_helpers_match_the_template_semantics(original_highway):
    coarse = CoarseFrenet.from_waypoints(original_highway.waypoints, sign_point=(1000.0, 2000.0))
    wp = original_highway.waypoints
    # On a waypoint, heading along the road: s is the chord sum up to it, d is 0.
    heading = np.arctan2(wp[11, 1] - wp[10, 1], wp[11, 0] - wp[10, 0])
    s, d = coarse.get_frenet(wp[10, 0] + 0.01 * np.cos(heading),
                             wp[10, 1] + 0.01 * np.sin(heading), heading)
    chord_sum = np.hypot(np.diff(wp[:11, 0]), np.diff(wp[:11, 1])).sum()
    assert s == pytest.approx(chord_sum + 0.01, abs=1e-6)
    assert abs(d) < 1e-6
    # getXY 5 m past a waypoint with d = 6: along its chord, 6 m to the right of it.
    x, y = coarse.get_xy(wp[10, 2] + 5.0, 6.0)
    along = np.array([np.cos(heading), np.sin(heading)])
    right = np.array([np.sin(heading), -np.cos(heading)])
    assert np.allclose([x, y], wp[10, :2] + 5.0 * along + 6.0 * right, atol=1e-6)
    # Round trip on the middle lane is coarse but close (this is why the env uses splines).
    _, d2 = coarse.get_frenet(x, y, heading)
    assert d2 == pytest.approx(6.0, abs=0.05)
    assert coarse.closest_waypoint(wp[42, 0] + 1.0, wp[42, 1]) == 42
    # Next waypoint: standing just past waypoint 42 facing along the road -> 43.
    h42 = np.arctan2(wp[43, 1] - wp[42, 1], wp[43, 0] - wp[42, 0])
    assert coarse.next_waypoint(wp[42, 0] + np.cos(h42), wp[42, 1] + np.sin(h42), h42) == 43


def test_from_waypoints_fills_the_original_columns():
    highway = HighwayMap.from_waypoints("c", circle(150.0, 48))
    normals = highway.waypoints[:, 3:5]
    assert np.allclose(np.hypot(*normals.T), 1.0)
    # Counter-clockwise circle: the right normal points away from the centre.
    assert np.all(np.sum(normals * highway.waypoints[:, :2], axis=1) > 0)


def test_scalar_and_vectorized_projection_agree(original_highway, monkeypatch):
    import sdc_gym.geometry.reference_line as module

    line = original_highway.reference
    rng = np.random.default_rng(5)
    s = rng.uniform(0, line.length, 10)
    xy = line.to_xy(s, rng.uniform(0, 12, 10))
    small = line.to_frenet(xy, s_guess=s + 0.3)
    monkeypatch.setattr(module, "_SCALAR_BATCH_LIMIT", 0)
    vectorized = line.to_frenet(xy, s_guess=s + 0.3)
    for a, b in zip(small, vectorized, strict=True):
        assert np.abs(a - b).max() < 1e-9


def test_few_point_paths_equal_the_array_methods_bit_for_bit(original_highway):
    """line_frames_few and project_few (direct paths on Python floats / one kernel call)
    give the array methods' bits: frames at random s over three laps either way and at the
    seam, projections from good guesses and from guesses so far off that the local search
    loses the points (project()'s global redo)."""
    line = original_highway.reference
    rng = np.random.default_rng(11)
    s = np.concatenate([rng.uniform(-3 * line.length, 3 * line.length, 4000),
                        [0.0, -0.0, line.length, np.nextafter(line.length, 0.0), -1e-300]])
    arrays = np.stack(line.line_frames(s), axis=-1)
    few = np.array(line.line_frames_few(s.tolist()))
    assert few.shape == arrays.shape
    assert np.array_equal(few.view(np.int64), arrays.view(np.int64))
    one = np.array([line.line_frames_few([value])[0] for value in s[:500].tolist()])
    assert np.array_equal(one.view(np.int64), arrays[:500].view(np.int64))
    with pytest.raises(IndexError), np.errstate(invalid="ignore"):  # as line_frames fails
        line.line_frames_few([float("nan")])

    xy = line.to_xy(s[:300], rng.uniform(-10.0, 10.0, 300))
    for offset in (0.0, 3.0, 400.0):
        guesses = s[:300] + offset
        expected = line.project(xy[:, 0], xy[:, 1], guesses)
        got = line.project_few(xy.tolist(), guesses.tolist())
        for a, b in zip(got, expected, strict=True):
            assert np.array_equal(np.array(a).view(np.int64), b.view(np.int64))
        single = [line.project_few([point], [guess])
                  for point, guess in zip(xy[:50].tolist(), guesses[:50].tolist(), strict=True)]
        assert [pair[0][0] for pair in single] == expected[0][:50].tolist()
        assert [pair[1][0] for pair in single] == expected[1][:50].tolist()
