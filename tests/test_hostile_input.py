"""Each case of the second hostile-input pass (issue 26 and the audit of 2026-12-02), by
name, with its exact message: the YAML loader's bounds (alias bombs, duplicate keys,
nesting, size), the sizes bounded before any allocation, reset options, light files and
bounded excerpts of bad values."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import sdc_gym  # noqa: F401
from sdc_gym.config import ConfigError, excerpt
from sdc_gym.road.track_map import TrackFormatError, load_light_config, load_track
from sdc_gym.scenarios import load_scenario
from sdc_gym.validation.yaml_files import (
    MAX_YAML_BYTES,
    MAX_YAML_NODES,
    YamlLimitError,
    parse_yaml,
    parse_yaml_lines,
    read_yaml,
)
from tests.conftest import UDACITY

ROOT = Path(__file__).resolve().parents[1]
CAPSTONE = UDACITY / "capstone"
HIGHWAY = "sdc_gym/HighwayLoop-v0"
TRACK = "sdc_gym/TrackLoop-v0"
SITE = {"track": "site", "max_duration": 5.0}


def alias_bomb(levels: int = 9, width: int = 10) -> str:
    """``a: &a [x, ...]``, ``b: &b [*a, ...]``, ...: ``width ** levels`` leaves."""
    names = "abcdefghijklmnop"
    lines = [f"a: &a [{', '.join(['x'] * width)}]"]
    lines += [f"{names[i]}: &{names[i]} [{', '.join(['*' + names[i - 1]] * width)}]"
              for i in range(1, levels)]
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------ the YAML loader
def test_a_billion_laughs_file_is_refused_before_anything_is_built():
    text = alias_bomb()  # 10^9 leaves in 413 bytes
    assert len(text) < 500
    tracemalloc.start()
    try:
        with pytest.raises(YamlLimitError) as raised:
            parse_yaml_lines(text)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert str(raised.value) == (
        "line 5: the document expands to more than 50,000 nodes (aliases counted as what "
        "they name; the bound of every YAML file)")
    assert peak < 5_000_000  # bytes: the composed graph only (10^6 leaves took 272 MB)


def test_an_alias_bomb_scenario_file_names_the_file_and_line(tmp_path):
    path = tmp_path / "bomb.yaml"
    path.write_text(alias_bomb())
    with pytest.raises(ConfigError) as raised:
        load_scenario(str(path))
    assert str(raised.value) == (
        f"{path}:5: the scenario file is refused: the document expands to more than 50,000 "
        "nodes (aliases counted as what they name; the bound of every YAML file)")


def test_aliases_within_the_bound_still_load():
    data = parse_yaml("base: &car {lane: 1, speed: 20}\ncars: [*car, *car]\n")
    assert data == {"base": {"lane": 1, "speed": 20},
                    "cars": [{"lane": 1, "speed": 20}, {"lane": 1, "speed": 20}]}
    assert MAX_YAML_NODES >= 9 * 1_000  # a scenario of 1,000 cars (4 keys a car) fits


def test_a_recursive_alias_is_refused():
    with pytest.raises(YamlLimitError, match=r"^line 1: a recursive alias \(a node that "
                       r"contains itself\)$"):
        parse_yaml("&a [*a]")


def test_a_duplicate_key_is_refused_with_both_lines(tmp_path):
    path = tmp_path / "case.yaml"
    path.write_text("ego:\n  lane: 1\nduration: 6\ncars: []\nduration: 20\n")
    with pytest.raises(ConfigError) as raised:
        load_scenario(str(path))
    assert str(raised.value) == (
        f"{path}:5: the scenario file is refused: duplicate key 'duration' (first at line "
        "3); each key may appear once in a mapping")


def test_a_duplicate_key_in_a_nested_mapping_and_a_merge_key():
    with pytest.raises(YamlLimitError, match=r"^line 3: duplicate key 'b' \(first at line 2\)"):
        parse_yaml("a:\n  b: 1\n  b: 2\n")
    # A merge key's entries are overridden by the mapping's own, as YAML defines: no error.
    assert parse_yaml("x: &x {b: 1, c: 3}\ny:\n  <<: *x\n  b: 2\n")["y"] == {"b": 2, "c": 3}


def test_deep_nesting_is_refused_not_a_recursion_error():
    with pytest.raises(YamlLimitError, match=r"^line 1: nested deeper than 64 levels"):
        parse_yaml("[" * 5000 + "]" * 5000)
    assert parse_yaml("[" * 60 + "]" * 60) is not None


def test_a_yaml_text_past_the_size_bound_is_refused(tmp_path):
    path = tmp_path / "big.yaml"
    path.write_text("a: [" + "1, " * (MAX_YAML_BYTES // 3) + "1]\n")
    with pytest.raises(ValueError) as raised:
        read_yaml(path, "run config")
    size = path.stat().st_size
    assert str(raised.value) == (f"{path}: the run config is {size:,} bytes; at most "
                                 f"{MAX_YAML_BYTES:,} are read (is this the right file?)")


def test_yaml_12_floats_are_kept():
    assert parse_yaml("lr: 1e-4\nbig: 1E5\n") == {"lr": 0.0001, "big": 100000.0}


def test_no_yaml_is_read_outside_the_loader():
    """Every YAML the project reads goes through sdc_gym.validation.yaml_files."""
    offenders = []
    for folder in ("sdc_gym", "agents", "evaluation", "training"):
        for path in (ROOT / folder).rglob("*.py"):
            text = path.read_text(encoding="utf-8")
            if path.name != "yaml_files.py" and any(call in text for call in (
                    "yaml.safe_load(", "yaml.load(", "yaml.full_load(", "yaml.unsafe_load(")):
                offenders.append(str(path.relative_to(ROOT)))
    for script in ("train.py", "evaluate.py"):
        if "yaml.safe_load(" in (ROOT / script).read_text(encoding="utf-8"):
            offenders.append(script)
    assert offenders == []


# ------------------------------------------------------------------------ excerpts
def test_a_bad_value_is_quoted_as_a_bounded_excerpt():
    cars = [{"lane": 1, "s": 10.0, "speed": 20.0}] * 10_000
    with pytest.raises(ConfigError) as raised:
        gym.make(HIGHWAY, config={"traffic": {"car_count": cars}})
    assert len(str(raised.value)) < 500  # was 370,105 characters
    assert excerpt(list(range(10_000))) == "[0, 1, 2, 3, 4, 5, ...] (10,000 items)"
    assert len(excerpt("x" * 100_000)) <= 200


# ------------------------------------------------------------------------ sizes
@pytest.mark.parametrize("env_id, config, message", [
    ("sdc_gym/TrackLoopBehavior-v0", {"decision_period_s": 1e6},
     "TrackLoopBehavior-v0: config key 'decision_period_s' must be a finite number in "
     "(0, 1000] (s): a decision lasts at most the episode's max_duration (1200.0 s) and at "
     "most 1000 s (its per-frame buffers), got 1000000.0"),
    (TRACK, {"camera": {"enabled": True, "width": 1_000_000}},
     "TrackLoop-v0.camera: CameraConfig.width must be an int in [1, 4096] px, got 1000000"),
    (TRACK, {"camera": {"enabled": True, "width": 4096, "height": 4096}},
     "TrackLoop-v0.camera: CameraConfig: width x height must be at most 8,294,400 pixels "
     "(4K UHD: each image is a float64 buffer of 24 bytes per pixel), got 4096 x 4096"),
    (HIGHWAY, {"map": "x" * 100_000},
     "HighwayLoop-v0: config key 'map': the map path is 100,000 characters "
     "('xxxxxxxxxxxxxxxxxxxxxxxxxxx...xxxxxxxxxxxxxxxxxxxxxxxxxxxx'); at most 4,096 "
     "(a file path)"),
    (HIGHWAY, {"start_s": 1e300},
     "HighwayLoop-v0: config key 'start_s' must be None or a finite number in "
     "[0, 6906.97) (m along the 6,907.0 m loop), got 1e+300"),
    (TRACK, {**SITE, "start_s": 1e300},
     "TrackLoop-v0: config key 'start_s' must be None or a finite number in [0, 76.5386) "
     "(m along the 76.5 m loop), got 1e+300"),
    (HIGHWAY, {"traffic": {"car_count": 1000}},
     "HighwayLoop-v0: config key 'traffic.car_count' must be at most 56 on this road "
     "(3 lanes, cars placed within +-190 m of the ego: spawn_range, capped at 0.45 x the "
     "6,907 m loop; a random layout fills 75% of it), got 1000; lower car_count or raise "
     "spawn_range, or lower spawn_min_gap"),
])
def test_each_unbounded_size_is_refused_at_make(env_id, config, message):
    with pytest.raises(ConfigError) as raised:
        gym.make(env_id, config=config)
    assert str(raised.value) == message


def test_the_road_capacity_is_a_real_bound():
    """56 cars (the bound on the original road) are placed; a larger road takes more."""
    env = gym.make(HIGHWAY, config={"traffic": {"car_count": 56}, "max_duration": 1.0})
    for seed in range(3):
        env.reset(seed=seed)
    env.close()
    gym.make(HIGHWAY, config={"traffic": {"car_count": 500, "spawn_range": 3000.0}}).close()


@pytest.mark.parametrize("kwargs, message", [
    ({"num_envs": 10**7}, "num_envs must be an int in [1, 4096] (a batch's arrays grow with "
                          "it), got 10000000 (int)"),
    ({"num_envs": True}, "num_envs must be an int in [1, 4096] (a batch's arrays grow with "
                         "it), got True (bool)"),
    ({"num_envs": 2, "full_info": "no"}, "full_info must be True or False, got 'no' (str)"),
])
@pytest.mark.parametrize("env_id", [HIGHWAY, TRACK])
def test_batch_sizes_and_flags_are_checked(env_id, kwargs, message):
    with pytest.raises(ValueError) as raised:
        gym.make_vec(env_id, vectorization_mode="vector_entry_point", **kwargs)
    assert str(raised.value) == message


# ------------------------------------------------------------------------ reset options
def test_reset_options_must_be_a_mapping_of_known_keys():
    highway = gym.make(HIGHWAY, config={"map": "oval", "max_duration": 5.0})
    with pytest.raises(ValueError) as raised:
        highway.reset(options="x")
    assert str(raised.value) == ("HighwayLoopEnv.reset: options must be a mapping or None, "
                                 "got str ('x'); valid keys: 'scenario'")
    with pytest.raises(ValueError) as raised:
        highway.reset(options={"senario": None})
    assert str(raised.value) == ("HighwayLoopEnv.reset: unknown reset option 'senario'; "
                                 "valid keys: 'scenario'")
    highway.reset(options={"scenario": None})  # random traffic: valid
    track = gym.make(TRACK, config=SITE)
    with pytest.raises(ValueError) as raised:
        track.reset(options={"scenario": None})
    assert str(raised.value) == ("TrackLoopEnv.reset: unknown reset option 'scenario'; "
                                 "valid keys: none (it takes no options)")


def test_a_batch_reset_mask_must_be_bools():
    envs = gym.make_vec(TRACK, num_envs=4, vectorization_mode="vector_entry_point",
                        config=SITE, autoreset_mode="Disabled")
    envs.reset(seed=0)
    with pytest.raises(ValueError) as raised:
        envs.reset(options={"reset_mask": ["no"] * 4})
    assert str(raised.value) == ("options['reset_mask'] must be 4 bools (shape (4,), dtype "
                                 "bool), got ['no', 'no', 'no', 'no'] (dtype <U2, shape (4,))")
    with pytest.raises(ValueError, match=r"^TrackLoopVectorEnv.reset: unknown reset option "
                       r"'scenario'; valid keys: 'reset_mask'$"):
        envs.reset(options={"scenario": None})
    envs.reset(options={"reset_mask": np.array([True, False, True, False])})


def test_the_vector_track_env_refuses_a_nan_batch_after_an_episode_ends():
    envs = gym.make_vec(TRACK, num_envs=2, vectorization_mode="vector_entry_point",
                        config={"track": "site", "max_duration": 0.2})
    envs.reset(seed=0)
    action = np.zeros((2, 3))
    for _ in range(100):
        _, _, terminated, truncated, _ = envs.step(action)
        if (terminated | truncated).any():
            break
    assert (terminated | truncated).any()
    ended = int(np.flatnonzero(terminated | truncated)[0])
    bad = action.copy()
    bad[ended] = np.nan
    with pytest.raises(ValueError) as raised:
        envs.step(bad)
    assert str(raised.value) == ("action[0] throttle = nan is outside its valid range [0, 1] "
                                 "(NaN is never valid)")


# ------------------------------------------------------------------------ light files
def write_lights(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "lights.yaml"
    path.write_text("camera_info:\n  image_width: 800\n  image_height: 600\n" + body)
    return path


def test_an_unknown_light_config_key_is_refused(tmp_path):
    path = write_lights(tmp_path, "stop_line_positions:\n  - [1148.56, 1184.65]\ncolour: red\n")
    with pytest.raises(TrackFormatError) as raised:
        load_light_config(path)
    assert str(raised.value) == (f"{path}: unknown light config key 'colour'; valid: "
                                 "camera_info, stop_line_positions, is_site")


def test_too_many_stop_lines_are_refused(tmp_path):
    path = write_lights(tmp_path, "stop_line_positions:\n" + "  - [1.0, 2.0]\n" * 1001)
    with pytest.raises(TrackFormatError) as raised:
        load_light_config(path)
    assert str(raised.value) == (f"{path}: stop_line_positions must hold at most 1,000 stop "
                                 "lines (the original: 8), got 1,001")


def test_a_stop_line_off_the_track_and_the_sites_lights_on_the_sim_track(tmp_path):
    waypoints = CAPSTONE / "sim_waypoints.csv"
    far = write_lights(tmp_path, "stop_line_positions:\n  - [10000000.0, 1184.65]\n")
    with pytest.raises(TrackFormatError) as raised:
        load_track(waypoints, far)
    assert str(raised.value) == (
        f"{waypoints}: stop line 0 at [10000000.0, 1184.65] is 9,997,660.7 m from the "
        "track's path; a stop line lies on the road, within 20 m of it (is the light config "
        "the track's? the site's and the simulator's differ)")
    with pytest.raises(TrackFormatError, match=r"stop line 0 at \[8.0, 16.2\] is 1,314.4 m "
                       "from the track's path"):
        load_track(waypoints, CAPSTONE / "site_traffic_light_config.yaml")
    assert len(load_track(waypoints, CAPSTONE / "sim_traffic_light_config.yaml")
               .stop_line_s) == 8


def test_the_validation_scenarios_module_imports_first():
    import subprocess
    import sys

    result = subprocess.run([sys.executable, "-c", "import sdc_gym.validation.scenarios"],
                            cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr


def test_yaml_errors_are_yaml_errors():
    assert issubclass(YamlLimitError, yaml.YAMLError)


# ------------------------------------------------------------------------ actions
@pytest.mark.parametrize("action, shape", [
    (np.zeros((0, 3)), "(0, 3)"), (np.zeros((5, 0)), "(5, 0)"), ([], "(0,)")])
def test_only_a_0_by_2_array_is_the_empty_path(action, shape):
    env = gym.make(HIGHWAY, config={"map": "oval", "max_duration": 5.0})
    env.reset(seed=0)
    with pytest.raises(ValueError) as raised:
        env.step(action)
    assert str(raised.value) == f"path must have shape (m, 2) with m <= 50, got {shape}"
    env.step(np.zeros((0, 2)))  # the empty path: the car stops dead


@pytest.mark.parametrize("action", [np.array([1], dtype=object), np.array(1, dtype=object)])
def test_the_highway_behavior_env_refuses_an_object_array(action):
    env = gym.make("sdc_gym/HighwayLoopBehavior-v0",
                   config={"highway": {"map": "oval", "max_duration": 5.0}})
    env.reset(seed=0)
    with pytest.raises(ValueError) as raised:
        env.step(action)
    assert str(raised.value).startswith("a Discrete(9) action is an int in 0..8 = "
                                        "['left/cruise', ")
    assert str(raised.value).endswith("(a Python or NumPy int, or an int array of shape () "
                                      f"or (1,)); got {action!r}")
    env.step(np.array([1]))  # an int array of shape (1,), as vector envs hand out: valid


# ------------------------------------------------------------------------ road files
@pytest.mark.parametrize("count, phase", [(50, 0.0), (50, np.pi), (180, np.pi), (401, 0.0)])
def test_a_figure_eight_crossing_at_its_first_waypoint_is_refused(tmp_path, count, phase):
    """Each of these was accepted and driven: the crossing fell exactly on a sample, where
    a side of +-1e-10 had a random sign (the same eight turned by 0.3 rad was refused)."""
    from sdc_gym.road.highway_map import MapFormatError, load_highway_map
    from tests.test_file_validation import highway_rows

    t = np.linspace(0.0, 2 * np.pi, count, endpoint=False) + phase
    eight = np.column_stack([1000 * np.sin(t), 500 * np.sin(2 * t)]) + 2000.0
    path = tmp_path / "eight.csv"
    path.write_text(highway_rows(eight))
    with pytest.raises(MapFormatError, match=r"the road crosses itself \(at s = .* m, near "
                       r"x 2000\.\d, y 2000\.\d\): a loop must be simple, not a figure eight"):
        load_highway_map(path)


# ------------------------------------------------------------------------ scenarios
SCENARIOS = {
    "gap 0 in the ego's lane": (
        "ego: {lane: 1, speed: 20}\ncars:\n  - {lane: 1, gap: 0, speed: 20}\n",
        ":3: scenario car cars[0] ('0', a car in lane 1 at s 124.8 m) overlaps the ego "
        "(s 124.8 m): their centres are 0.0 m apart, less than the sum of their half "
        "lengths, 4.7 m"),
    "gap 2 m in the ego's lane": (
        "ego: {lane: 1, speed: 20}\ncars:\n  - {lane: 1, gap: 2, speed: 20}\n",
        ":3: scenario car cars[0] ('0', a car in lane 1 at s 126.8 m) overlaps the ego "
        "(s 124.8 m): their centres are 2.0 m apart, less than the sum of their half "
        "lengths, 4.7 m"),
    "two cars on the same spot": (
        "ego: {lane: 1, speed: 20}\ncars:\n  - {name: a, lane: 0, gap: 30, speed: 20}\n"
        "  - {name: b, lane: 0, gap: 30, speed: 20}\n",
        ":4: scenario car cars[1] ('b', a car in lane 0 at s 154.8 m) overlaps cars[0] ('a') "
        "(s 154.8 m): their centres are 0.0 m apart, less than the sum of their half "
        "lengths, 4.7 m"),
    "ego d 100 on a 12 m road": (
        "ego: {d: 100, speed: 20}\n",
        ":1: scenario key 'ego.d' must be on the road, in [0, 12] m right of the centre "
        "line, got 100"),
    "lane_change to lane 7": (
        "ego: {lane: 1, speed: 20}\ncars:\n  - {name: a, lane: 0, gap: 30, speed: 20}\n"
        "actions:\n  - {car: a, when: {time: 1}, do: lane_change, lane: 7}\n",
        ":5: scenario key 'actions[0].lane' must be a lane of the map, 0 to 2, got 7"),
    "reach_lane 5 on three lanes": (
        "ego: {lane: 1, speed: 20}\nsuccess:\n  reach_lane: {lane: 5, within: 10}\n",
        ":3: scenario key 'success.reach_lane' must be a lane of the map, 0 to 2, got 5"),
}


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_each_bad_scenario_placement_names_the_file_and_line(name, tmp_path):
    text, message = SCENARIOS[name]
    path = tmp_path / "case.yaml"
    path.write_text(text)
    env = gym.make(HIGHWAY, config={"max_duration": 5.0})
    with pytest.raises(ConfigError) as raised:
        env.reset(seed=0, options={"scenario": str(path)})
    assert str(raised.value) == f"{path}{message}"


def test_cars_side_by_side_and_close_behind_are_valid(tmp_path):
    path = tmp_path / "ok.yaml"
    path.write_text("ego: {lane: 1, speed: 20}\ncars:\n  - {name: a, lane: 1, gap: 30, "
                    "speed: 20}\n  - {name: b, lane: 0, gap: 30, speed: 20}\n"
                    "  - {name: c, lane: 1, gap: 36, speed: 20}\n")
    env = gym.make(HIGHWAY, config={"max_duration": 5.0})
    env.reset(seed=0, options={"scenario": str(path)})
    assert env.unwrapped.world.traffic.state.s[0, :3].tolist() == pytest.approx(
        [154.83, 154.83, 160.83], abs=0.01)


# ------------------------------------------------------------------------ incident reports
@pytest.mark.parametrize("report, message", [
    ({"replay": {}}, "the incident report lacks ['kind', 'time'] (a replay needs ['kind', "
                     "'time', 'replay']; evaluate.py's incidents.json has them)"),
    ({"kind": "collision", "time": 3.0, "replay": 5},
     "the incident report's 'replay' must be a snapshot mapping of ['map', 'duration', "
     "'ego', 'cars', 'replay'], got 5"),
    ({"kind": "collision", "time": 3.0, "replay": {}},
     "the incident report's 'replay' snapshot lacks ['map', 'duration', 'ego', 'cars', "
     "'replay'] (a snapshot has ['map', 'duration', 'ego', 'cars', 'replay'])"),
    ({"kind": "crash", "time": 3.0, "replay": {}},
     "the incident report's 'kind' must be one of ['collision', 'acceleration', 'jerk', "
     "'speed', 'lane', 'off_road'], got 'crash'"),
    ({"kind": "collision", "time": 3.0, "replay": {"map": "original", "duration": 5.0,
                                                   "ego": {}, "cars": [], "replay": {}}},
     "the incident report's 'replay.replay' must be a mapping of ['traffic_step', "
     "'generator_state', 'respawn_blocked_steps', 'source'], got {}"),
    ("x", "an incident report must be a mapping, got str ('x')"),
])
def test_an_incident_report_is_validated_as_a_whole(report, message):
    from sdc_gym.scenarios.replay import incident_scenario

    with pytest.raises(ValueError) as raised:
        incident_scenario(report)
    assert str(raised.value) == message


def test_a_broken_report_in_incidents_json_names_the_file_and_index(tmp_path):
    import json

    from sdc_evaluation.scenario_runs import scenario_cases

    path = tmp_path / "incidents.json"
    path.write_text(json.dumps([{"replay": 5}]))
    with pytest.raises(SystemExit) as raised:
        scenario_cases(path)
    assert str(raised.value) == (f"--scenario {path}: report 0: the incident report lacks "
                                 "['kind', 'time'] (a replay needs ['kind', 'time', 'replay']; "
                                 "evaluate.py's incidents.json has them)")


# ------------------------------------------------------------------------ train.py
def train_config(tmp_path: Path, *cli: str, text: str | None = None, **content) -> dict:
    import train

    path = tmp_path / "run.yaml"
    path.write_text(text if text is not None else yaml.safe_dump(
        {"env": "sdc_gym/HighwayLoopBehavior-v0",
         "config": {"highway": {"max_duration": 20.0}}, **content}))
    args = train.parse_args(["--config", str(path), "--output", str(tmp_path / "run"), *cli])
    return train.run_config(args)


@pytest.mark.parametrize("name", ["torch.nn.ReLU", "nn.ReLU", "ReLU", "relu"])
def test_an_activation_is_named_and_resolved_to_its_torch_class(tmp_path, name):
    from torch import nn

    from sdc_gym.validation.run_config import resolved_policy_kwargs

    config = train_config(tmp_path, "--hp", f"policy_kwargs.activation_fn={name}")
    assert config["hyperparams"]["policy_kwargs"]["activation_fn"] == name  # kept as text
    assert resolved_policy_kwargs(config["hyperparams"])["policy_kwargs"][
        "activation_fn"] is nn.ReLU


@pytest.mark.parametrize("cli, content, message", [
    (["--hp", "policy_kwargs.activation_fn=torch.nn.Relu6"], {},
     " (hyperparameters): hyperparameter 'policy_kwargs.activation_fn' must be one of "
     "['elu', 'gelu', 'leaky_relu', 'relu', 'selu', 'sigmoid', 'silu', 'tanh'] (or the "
     "torch.nn class name, e.g. 'torch.nn.ReLU'), got 'torch.nn.Relu6'"),
    (["--hp", "policy_kwargs.net_arch=[0]"], {},
     " (hyperparameters): hyperparameter 'policy_kwargs.net_arch' must be a list of at most "
     "16 layer widths, each an int in [1, 4096], or a mapping of ['pi', 'vf', 'qf'] to such "
     "lists, got [0]"),
    (["--algo", "sac"], {},
     ": algo 'sac' learns Box actions; sdc_gym/HighwayLoopBehavior-v0 has Discrete actions "
     "(Discrete(9)): use one of ['ppo', 'a2c', 'dqn', 'qrdqn'] (the behavior envs take config "
     "action: discrete or continuous)"),
])
def test_bad_hyperparameters_and_algorithms_are_refused_before_sb3(tmp_path, cli, content,
                                                                   message):
    with pytest.raises(SystemExit) as raised:
        train_config(tmp_path, *cli, **content)
    assert str(raised.value) == f"{tmp_path / 'run.yaml'}{message}"
    assert not (tmp_path / "run").exists()


def test_sac_on_the_continuous_behavior_env_is_valid(tmp_path):
    config = train_config(tmp_path, "--algo", "sac", config={
        "action": "continuous", "highway": {"max_duration": 20.0}})
    assert config["algo"] == "sac"


def test_an_empty_run_config_and_a_duplicated_key_are_refused(tmp_path):
    with pytest.raises(SystemExit) as raised:
        train_config(tmp_path, text="# nothing\n")
    assert str(raised.value).startswith(f"{tmp_path / 'run.yaml'}: the run config is empty; "
                                        "give the keys to set (valid: [")
    assert str(raised.value).endswith("or drop --config to train the defaults "
                                      "(sdc_gym/HighwayLoopBehavior-v0, ppo)")
    with pytest.raises(SystemExit) as raised:
        train_config(tmp_path, text="algo: ppo\ntimesteps: 10\nalgo: dqn\n")
    assert str(raised.value) == (f"{tmp_path / 'run.yaml'}:3: the YAML file is refused: "
                                 "duplicate key 'algo' (first at line 1); each key may appear "
                                 "once in a mapping")


# ------------------------------------------------------------------------ stale temp files
def test_a_killed_runs_temporary_files_are_removed_when_the_folder_is_used_again(tmp_path):
    import os
    import subprocess
    import sys

    from sdc_evaluation.run_folders import remove_stale_temporaries

    ended = subprocess.Popen([sys.executable, "-c", "pass"])
    ended.wait()
    live = os.getppid()  # pytest's parent: alive while the test runs
    (tmp_path / "checkpoints").mkdir()
    stale = [tmp_path / "checkpoints" / ".replay_buffer.pkl.k2j4x9.tmp",
             tmp_path / f".returns.png.{ended.pid}.tmp", tmp_path / f".x.csv.{os.getpid()}.tmp"]
    kept = [tmp_path / f".returns.png.{live}.tmp", tmp_path / "config.yaml",
            tmp_path / "checkpoints" / "model_100_steps.zip"]
    for path in stale + kept:
        path.write_bytes(b"x" * 100)
    (tmp_path / ".best_model.tmp").mkdir()
    (tmp_path / ".best_model.tmp" / "state.pkl").write_bytes(b"x")
    removed = remove_stale_temporaries(tmp_path)
    assert sorted(removed) == sorted([*stale, tmp_path / ".best_model.tmp"])
    assert all(path.exists() for path in kept)
    assert not any(path.exists() for path in stale)


# ------------------------------------------------------------------------ evaluate.py
def test_an_agent_that_cannot_drive_the_env_is_refused_before_any_episode(tmp_path):
    import evaluate

    with pytest.raises(SystemExit) as raised:
        evaluate.main(["--agents", "dbw_ground_truth", "--output", str(tmp_path / "run"),
                       "--episodes", "1", "--workers", "1", "--no-progress"])
    assert str(raised.value) == (
        "--agents: agent 'dbw_ground_truth' drives sdc_gym/TrackLoop-v0, not "
        "sdc_gym/HighwayLoop-v0; the agents for sdc_gym/HighwayLoop-v0: dqn_highway, "
        "dqn_nstep_highway, dqn_swa_highway, "
        "fsm_alert, fsm_bold, fsm_bold_kf, fsm_caution, fsm_conservative, "
        "fsm_conservative_kf, fsm_easing, fsm_hyper, fsm_reroute, fsm_reverse, "
        "fsm_straight_braking, lane_keeping")
    assert not (tmp_path / "run").exists()
