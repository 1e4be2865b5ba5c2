"""The evaluation's figures and the trace recorder: figures show what they are given."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.collections import PathCollection

from sdc_evaluation.episodes import TRACE_KEY, EpisodeTrace, TraceRecorder
from sdc_evaluation.incident_plots import incident_map_figure
from sdc_evaluation.plots import Limits, incidents_figure, means_figure, minmax_indices
from sdc_evaluation.profiles import (
    profile_figure,
    speed_time_figure,
    stop_line_distances,
    traces_for_seed,
)
from sdc_evaluation.summary import agent_samples, aggregate
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
    dashed = [[line.get_ydata()[0] for line in ax.get_lines()
               if line.get_linestyle() == "--" and line.get_color() == "black"]
              for ax in figure.axes]
    assert dashed[0] == pytest.approx([50.0])
    assert dashed[1] == [10.0] and sorted(dashed[2]) == [-10.0, 10.0]
    drawn = [line for line in acceleration.get_lines() if line.get_label()[0] != "_"]
    assert [line.get_label() for line in drawn] == ["a (seed 0)", "b (seed 0)"]
    # Distinguishable where they coincide: other line style, thinner line.
    assert drawn[0].get_linestyle() == "-" and drawn[1].get_linestyle() == "--"
    assert drawn[1].get_linewidth() < drawn[0].get_linewidth()
    assert max(drawn[0].get_ydata()) == 12.5  # the spike is drawn
    assert max(speed.get_lines()[0].get_ydata()) == pytest.approx(21.0 * 2.2369362920544)
    assert jerk.get_xlabel() == "distance (km)"


def test_profile_figure_decimates_long_traces():
    figure = profile_figure({"long": fake_trace(50_000, spike=33_333)}, max_points=2000)
    line = figure.axes[1].get_lines()[0]
    assert len(line.get_xdata()) <= 2002 and max(line.get_ydata()) == 12.5


def test_trace_recorder_keeps_the_light_only_near_its_stop_line():
    recorder = TraceRecorder(max_points=64)
    for distance_to_line, state in ((250.0, 2), (99.0, 0), (5.0, 1), (300.0, 0)):
        recorder.add({"time": 0.0, "distance": 0.0, "speed": 0.0, "acceleration": 0.0,
                      "jerk": 0.0, "light_state_ahead": state,
                      "stop_line_distance": distance_to_line})
    assert recorder.finish().light_state_near.tolist() == [4.0, 0.0, 1.0, 4.0]


def test_traces_for_the_chosen_seed_and_twins_named():
    a, b = fake_trace(), fake_trace(300)
    episodes = [episode("a", 0, [], trace=a), episode("a", 1, [], trace=b),
                episode("b", 1, [], trace=fake_trace(300)), episode("c", 1, [], trace=a)]
    traces = traces_for_seed(episodes, 1, {"a": "A"})
    assert list(traces) == ["A", "b (= A)", "c"]
    assert traces["A"] is b


def light_trace() -> EpisodeTrace:
    trace = fake_trace(400)
    states = np.full(400, 4.0)
    states[100:150] = 0.0  # red while driving up to a line
    return EpisodeTrace(trace.time, trace.distance, trace.speed, trace.acceleration,
                        trace.jerk, light_state_near=states)


def test_profiles_mark_stop_lines_and_light_states():
    trace = light_trace()
    figure = profile_figure({"dbw": trace}, stop_lines_m=[100.0, 300.0, 1e6])
    strip, speed = figure.axes[0], figure.axes[1]
    assert len(figure.axes) == 4  # the light strip, speed, acceleration, jerk
    verticals = sorted(line.get_xdata()[0] for line in speed.get_lines()
                       if line.get_linestyle() == ":")
    assert verticals == pytest.approx([0.1, 0.3])  # beyond the trace: not drawn
    red = [bars for bars in strip.collections
           if np.allclose(bars.get_facecolor()[0][:3], (0.839, 0.153, 0.157), atol=0.01)]
    ((start, width),) = [(path.vertices[:, 0].min(), np.ptp(path.vertices[:, 0]))
                         for bars in red for path in bars.get_paths()]
    assert start == pytest.approx(trace.distance[100] / 1000.0)
    assert start + width == pytest.approx(trace.distance[150] / 1000.0)
    over_time = speed_time_figure({"dbw": trace}).axes[1]
    (line,) = [line for line in over_time.get_lines() if line.get_label() == "dbw"]
    assert line.get_xdata()[-1] == pytest.approx(trace.time[-1] / 60.0)
    assert over_time.get_xlabel() == "time (min)"


def test_stop_lines_along_the_laps_from_the_start():
    class Track:
        length = 1000.0
        stop_line_s = np.array([900.0, 100.0])

    assert stop_line_distances(Track(), 150.0, 2) == [750.0, 950.0, 1750.0, 1950.0]
    assert stop_line_distances(get_highway_map("oval"), 0.0, 1) == []


def run_rows(episodes):
    return aggregate(episodes), agent_samples(episodes)


def summary_episode(agent: str, seed: int, mph: float, lap: float, incidents: int = 0):
    return {"agent": agent, "seed": seed, "laps": 1, "lap_times": [lap], "distance": 1609.344,
            "mean_speed_mph": mph, "longest_distance_without_incident": 1609.344,
            "incidents": {"collision": incidents, "speed": 2 * incidents},
            "max_acceleration": 1.0, "max_jerk": 1.0, "is_success": True, "wall_time": 1.0}


def test_means_figure_shows_each_mean_with_its_interval_and_every_episode():
    episodes = [summary_episode("slow", s, 40.0 + s, 300.0 - s) for s in range(4)]
    episodes += [summary_episode("fast", s, 45.0 + s, 280.0 - s) for s in range(4)]
    rows, samples = run_rows(episodes)
    speed, laps = means_figure(rows, samples).axes
    ticks = {tick.get_position()[1]: tick.get_text() for tick in speed.get_yticklabels()}
    assert ticks == {1: "slow", 0: "fast"}  # the run's first agent on top
    bars = [c for c in speed.containers]  # one errorbar per agent, first on top
    (slow_x,), (slow_y,) = bars[0].lines[0].get_data()
    assert (slow_x, slow_y) == (pytest.approx(41.5), 1)
    low, high = rows[0]["mean_speed_mph_ci"]
    segment = bars[0].lines[2][0].get_segments()[0]
    assert segment[:, 0] == pytest.approx([low, high])
    dots = [c for c in speed.collections if c.get_label() == "episodes"]
    assert sorted(dots[0].get_offsets()[:, 0]) == [40.0, 41.0, 42.0, 43.0]
    assert laps.get_xlabel() == "lap time (s)"


def test_incidents_figure_stacks_kinds_and_labels_the_rate():
    rows, _ = run_rows([summary_episode("a", 0, 40.0, 300.0, incidents=1),
                        summary_episode("b", 0, 40.0, 300.0)])
    ax = incidents_figure(rows).axes[0]
    widths = {patch.get_label(): [] for patch in ax.containers}
    for container in ax.containers:
        widths[container.get_label()] = [bar.get_width() for bar in container]
    assert widths == {"collision": [1.0, 0.0], "speed": [2.0, 0.0]}
    texts = [text.get_text() for text in ax.texts]
    assert texts[0].startswith("3 in 1.0 mi: 300 [") and texts[1].startswith("0 in 1.0 mi")


def test_incident_map_marks_a_known_incident(oval):
    x, y = oval.reference.to_xy(700.0, 6.0)
    log = [incident("collision", float(x), float(y))]
    figure = incident_map_figure(oval, [episode("a", 0, [], log), episode("b", 0, [])])
    assert len(figure.axes) == 2
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


@pytest.mark.parametrize("agents, rows", [(4, [2, 2]), (5, [3, 2]), (3, [3])])
def test_incident_map_has_no_empty_panel_and_titles_that_fit(oval, agents, rows):
    names = [f"agent_with_a_long_name_{i}" for i in range(agents)]
    figure = incident_map_figure(oval, [episode(name, 0, []) for name in names])
    assert len(figure.axes) == agents  # one panel per agent, none empty or hidden
    figure.canvas.draw()
    renderer = figure.canvas.get_renderer()
    tops = sorted({round(ax.get_position().y1, 3) for ax in figure.axes}, reverse=True)
    assert [sum(round(ax.get_position().y1, 3) == top for ax in figure.axes)
            for top in tops] == rows
    for ax, name in zip(figure.axes, names, strict=True):
        title = ax.title.get_window_extent(renderer)
        assert ax.get_title().splitlines()[0] == name
        assert figure.bbox.x0 <= title.x0 and title.x1 <= figure.bbox.x1
        assert title.y1 <= figure.bbox.y1


def strip_report(oval, seconds: float) -> dict:
    """The ego in the middle lane at 10 m/s, car 7 20 m ahead of it in the same lane and
    car 8 10 m behind in the left lane, sampled every 0.06 s for ``seconds``."""
    from sdc_evaluation.incident_plots import SNAPSHOT_OFFSETS_S  # noqa: F401

    times = np.round(np.arange(0.0, seconds + 1e-9, 0.06), 4)
    s_ego = 75.0 + 10.0 * times  # on a straight (s 50-200 m)
    ego_xy = oval.reference.to_xy(s_ego, 6.0)
    yaw = oval.reference.heading(s_ego)
    cars = []
    for car_id, ahead, d in ((7, 20.0, 6.0), (8, -10.0, 2.0)):
        xy = oval.reference.to_xy(s_ego + ahead, d)
        heading = oval.reference.heading(s_ego + ahead)
        cars.append({"id": car_id, "time": times.tolist(), "x": xy[:, 0].tolist(),
                     "y": xy[:, 1].tolist(), "vx": (10 * np.cos(heading)).tolist(),
                     "vy": (10 * np.sin(heading)).tolist(), "s": (s_ego + ahead).tolist(),
                     "d": [d] * len(times)})
    history = {"time": times.tolist(),
               "ego": {"x": ego_xy[:, 0].tolist(), "y": ego_xy[:, 1].tolist(),
                       "s": s_ego.tolist(), "d": [6.0] * len(times), "yaw": yaw.tolist(),
                       "speed": [10.0] * len(times)},
               "cars": cars}
    return {"agent": "a", "seed": 3, "kind": "collision", "time": float(times[-1]),
            "s": float(s_ego[-1]), "d": 6.0, "value": 1.0, "history": history}


def test_incident_strip_draws_the_cars_around_the_ego_at_minus_3_to_0_s(oval):
    from matplotlib.patches import Polygon

    from sdc_evaluation.incident_plots import incident_strip_figure

    figure = incident_strip_figure(strip_report(oval, 3.0), oval, "a")
    assert [ax.get_title() for ax in figure.axes] == ["-3 s", "-2 s", "-1 s", "0 s: collision"]
    for ax in figure.axes:
        centres = sorted(tuple(np.round(patch.get_xy()[:4].mean(axis=0), 1))
                         for patch in ax.patches if isinstance(patch, Polygon))
        # In the ego's frame: car 8 10 m behind one lane to the left (+4 m), the ego at
        # the origin, car 7 20 m ahead in its lane.
        assert [c[0] for c in centres] == pytest.approx([-10.0, 0.0, 20.0], abs=0.3)
        assert [c[1] for c in centres] == pytest.approx([4.0, 0.0, 0.0], abs=0.3)
    early = incident_strip_figure(strip_report(oval, 1.5), oval, "a")
    assert [ax.texts[0].get_text() if ax.texts else "" for ax in early.axes[:2]] == [
        "before the episode's start"] * 2


def test_gallery_writes_one_strip_per_incident_up_to_its_limit(tmp_path, oval):
    from sdc_evaluation.incident_plots import write_gallery

    reports = [strip_report(oval, 3.0), {**strip_report(oval, 3.0), "kind": "lane"}]
    written = write_gallery(tmp_path, reports, oval, {"a": "agent:a"}, limit=1)
    assert [path.name for _, path in written] == ["000_agent_a_seed3_collision.png"]
    assert written[0][1].read_bytes().startswith(PNG_MAGIC)
