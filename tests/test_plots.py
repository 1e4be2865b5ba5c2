"""agents.plots and the trace recorder: figures show what they are given, files are PNGs."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.collections import PathCollection

from agents.evaluation import TRACE_KEY, EpisodeTrace, TraceRecorder
from agents.plots import (
    INCIDENT_MAP_FILE,
    LAP_TIME_FILE,
    PROFILE_FILE,
    Limits,
    incident_map_figure,
    lap_time_figure,
    minmax_indices,
    profile_figure,
    write_plots,
)
from sdc_gym.metrics import IncidentRules
from sdc_gym.road.builtin_highways import get_highway_map

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def oval():
    return get_highway_map("oval")


def fake_trace(n: int = 400, spike: int = 123) -> EpisodeTrace:
    time = np.arange(n) * 0.06
    speed = np.minimum(time * 2.0, 21.0)
    acceleration = np.full(n, 2.0)
    acceleration[spike] = 12.5
    jerk = np.sin(time)
    return EpisodeTrace(time, np.cumsum(speed) * 0.06, speed, acceleration, jerk)


def episode(agent: str, seed: int, lap_times: list[float], log: list[dict] | None = None,
            trace: EpisodeTrace | None = None) -> dict:
    result = {"agent": agent, "seed": seed, "lap_times": lap_times, "incident_log": log or []}
    if trace is not None:
        result[TRACE_KEY] = trace
    return result


def incident(kind: str, x: float, y: float) -> dict:
    return {"kind": kind, "time": 12.0, "step": 600, "x": x, "y": y, "s": 0.0, "d": 6.0,
            "value": 1.0}


def test_limits_follow_the_incident_rules():
    limits = Limits.from_rules(IncidentRules())
    assert limits.speed_mph == pytest.approx(50.0)
    assert (limits.acceleration, limits.jerk) == (10.0, 10.0)


def test_minmax_decimation_keeps_spikes_and_ends():
    values = np.zeros(100_000)
    values[54_321] = 99.0
    values[77_777] = -5.0
    keep = minmax_indices(values, 1000)
    assert len(keep) <= 1002
    assert {0, 54_321, 77_777, 99_999} <= set(keep.tolist())
    assert np.all(np.diff(keep) > 0)
    assert len(minmax_indices(values[:500], 1000)) == 500  # short: every sample


def test_trace_recorder_caps_points_evenly_and_keeps_the_last_step():
    recorder = TraceRecorder(max_points=64)
    for step in range(1001):
        recorder.add({"time": step * 0.06, "distance": float(step), "speed": 1.0,
                      "acceleration": 0.0, "jerk": 0.0})
    trace = recorder.finish()
    assert 32 <= len(trace) <= 65
    steps = trace.distance
    assert steps[0] == 0.0 and steps[-1] == 1000.0
    assert len(set(np.diff(steps[:-1]).tolist())) == 1  # evenly spaced before the last
    short = TraceRecorder(max_points=64)
    for step in range(10):
        short.add({"time": 0.0, "distance": float(step), "speed": 0.0, "acceleration": 0.0,
                   "jerk": 0.0})
    assert short.finish().distance.tolist() == list(range(10))


def test_profile_figure_has_three_panels_a_line_per_agent_and_the_limits():
    figure = profile_figure({"a (seed 0)": fake_trace(), "b (seed 0)": fake_trace(300)},
                            Limits())
    speed, acceleration, jerk = figure.axes
    assert len(figure.axes) == 3
    dashed = [[line.get_ydata()[0] for line in ax.get_lines() if line.get_linestyle() == "--"]
              for ax in figure.axes]
    assert dashed[0] == pytest.approx([50.0])
    assert dashed[1] == [10.0] and sorted(dashed[2]) == [-10.0, 10.0]
    solid = [line for line in acceleration.get_lines() if line.get_linestyle() == "-"]
    assert [line.get_label() for line in solid] == ["a (seed 0)", "b (seed 0)"]
    assert max(solid[0].get_ydata()) == 12.5  # the spike is drawn
    assert max(speed.get_lines()[0].get_ydata()) == pytest.approx(21.0 * 2.2369362920544)
    assert jerk.get_xlabel() == "distance (km)"


def test_profile_figure_decimates_long_traces():
    figure = profile_figure({"long": fake_trace(50_000, spike=33_333)}, max_points=2000)
    line = figure.axes[1].get_lines()[0]
    assert len(line.get_xdata()) <= 2002 and max(line.get_ydata()) == 12.5


def test_lap_time_figure_plots_every_lap_as_a_point():
    episodes = [episode("a", 0, [80.0, 78.0]), episode("a", 1, [79.0]),
                episode("b", 0, [70.0]), episode("c", 0, [])]
    ax = lap_time_figure(episodes).axes[0]
    points = [c for c in ax.collections if isinstance(c, PathCollection)]
    assert sorted(p[1] for c in points for p in c.get_offsets().tolist()) == [
        70.0, 78.0, 79.0, 80.0]
    assert [tick.get_text() for tick in ax.get_xticklabels()] == ["a", "b", "c"]


def test_incident_map_marks_a_known_incident(oval):
    x, y = oval.reference.to_xy(700.0, 6.0)
    log = [incident("collision", float(x), float(y))]
    figure = incident_map_figure(oval, [episode("a", 0, [], log), episode("b", 0, [])])
    assert len([ax for ax in figure.axes if ax.get_visible()]) == 2
    marks = [c for c in figure.axes[0].collections if c.get_label().startswith("collision")]
    assert len(marks) == 1 and marks[0].get_label() == "collision (1)"
    assert marks[0].get_offsets().tolist() == [pytest.approx([x, y])]
    assert not [c for c in figure.axes[1].collections if isinstance(c, PathCollection)]
    # The loop is drawn: lines through the centre line and the outer road edge.
    lines = figure.axes[0].get_lines()
    assert len(lines) >= 1 + oval.lane_count + 1  # centre, lane lines, edge, start mark


def test_incident_map_groups_kinds(oval):
    log = [incident("jerk", 300.0, 95.0), incident("speed", 310.0, 95.0),
           incident("jerk", 320.0, 95.0)]
    ax = incident_map_figure(oval, [episode("a", 0, [], log)]).axes[0]
    labels = sorted(c.get_label() for c in ax.collections if isinstance(c, PathCollection))
    assert labels == ["jerk (2)", "speed (1)"]


def test_write_plots_writes_three_png_files(tmp_path, oval):
    episodes = [episode("a", 0, [80.0], [incident("lane", 300.0, 95.0)], fake_trace()),
                episode("a", 1, [79.0], trace=fake_trace()), episode("b", 0, [75.0])]
    written = write_plots(tmp_path, episodes, oval)
    assert [path.name for path in written] == [PROFILE_FILE, LAP_TIME_FILE, INCIDENT_MAP_FILE]
    for path in written:
        data = path.read_bytes()
        assert data.startswith(PNG_MAGIC) and len(data) > 5000
    assert not list(tmp_path.glob(".*.tmp"))
    # Without traces or a road, only the lap-time plot.
    other = tmp_path / "other"
    assert [p.name for p in write_plots(other, [episode("b", 0, [75.0])])] == [LAP_TIME_FILE]
