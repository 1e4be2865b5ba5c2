"""Property-based fuzzing (hypothesis) of configs, map files and actions, for every env.

Each generated case ends in one of two ways, within a time bound (hypothesis' deadline):
a clear ``ConfigError`` / ``ValueError``, or a valid episode (reset and a few steps);
never another exception, never a hang. A rejected action leaves the env bit-identical
(its pickled state before and after are the same bytes).

The default budget keeps this file near a minute on the 2-core machine; a longer soak:
``SDC_GYM_FUZZ_EXAMPLES=2000 .venv/bin/python -m pytest tests/test_fuzz.py``.
"""

from __future__ import annotations

import math
import os
import pickle
from datetime import timedelta
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import sdc_gym  # noqa: F401
from sdc_gym.config import ConfigError
from sdc_gym.envs import HighwayLoopBehaviorEnv, HighwayLoopEnv, TrackLoopBehaviorEnv, TrackLoopEnv
from sdc_gym.kernel_threads import max_kernel_threads

EXAMPLES = int(os.environ.get("SDC_GYM_FUZZ_EXAMPLES", "0")) or None
FUZZ = settings(max_examples=EXAMPLES or 60, deadline=timedelta(seconds=30), database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
                derandomize=EXAMPLES is None)  # CI: the same cases every run
ENVS = {"sdc_gym/HighwayLoop-v0": HighwayLoopEnv, "sdc_gym/TrackLoop-v0": TrackLoopEnv,
        "sdc_gym/HighwayLoopBehavior-v0": HighwayLoopBehaviorEnv,
        "sdc_gym/TrackLoopBehavior-v0": TrackLoopBehaviorEnv}
# Short episodes so that a valid case runs in well under a second.
BASE = {"sdc_gym/HighwayLoop-v0": {"map": "oval", "max_duration": 5.0},
        "sdc_gym/TrackLoop-v0": {"track": "site", "max_duration": 5.0},
        "sdc_gym/HighwayLoopBehavior-v0": {"highway": {"map": "oval", "max_duration": 5.0}},
        "sdc_gym/TrackLoopBehavior-v0": {"track": {"track": "site", "max_duration": 5.0}}}
STEPS = 3

HOSTILE_NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-10**12, 10**12),
    st.sampled_from([0, -1, 1, 2, 10**6, 10**9, 1e300, -1e300, math.nan, math.inf, 1e-300]))
HOSTILE = st.one_of(
    HOSTILE_NUMBERS, st.none(), st.booleans(), st.text(max_size=4),
    st.lists(HOSTILE_NUMBERS, max_size=3), st.dictionaries(st.text(max_size=3),
                                                           HOSTILE_NUMBERS, max_size=2))


def value_for(default: Any) -> st.SearchStrategy[Any]:
    """A value to replace ``default``: hostile, or the default scaled (near the valid)."""
    if isinstance(default, dict) and default:
        return overrides(default)
    near: list[st.SearchStrategy[Any]] = []
    if isinstance(default, int | float) and not isinstance(default, bool):
        near.append(st.sampled_from([-1.0, 0.0, 0.5, 2.0, 100.0]).map(
            lambda factor: type(default)(default * factor)))
    if isinstance(default, list | tuple) and default and all(
            isinstance(item, int | float) for item in default):
        near.append(st.lists(HOSTILE_NUMBERS, min_size=len(default), max_size=len(default)))
    return st.one_of(HOSTILE, *near) if near else HOSTILE


def overrides(defaults: dict[str, Any]) -> st.SearchStrategy[dict[str, Any]]:
    """A nested override dict for a few keys of ``defaults`` (sometimes an unknown one)."""
    keys = st.sampled_from(sorted(defaults))
    entry = keys.flatmap(lambda key: st.tuples(st.just(key), value_for(defaults[key])))
    unknown = st.tuples(st.sampled_from(["not_a_key", "Path_points"]), HOSTILE)
    return st.lists(st.one_of(entry, entry, entry, unknown), min_size=1, max_size=3).map(dict)


def merged(base: dict[str, Any], extra: dict[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in extra.items():
        out[key] = (merged(out[key], value) if isinstance(out.get(key), dict)
                    and isinstance(value, dict) else value)
    return out


@pytest.fixture(scope="module", autouse=True)
def compiled_kernels() -> None:
    """Every env and native batch stepped once before the fuzzing: the deadline is for a
    case, not for numba compiling the kernels (a fresh clone's first run)."""
    for env_id, config in BASE.items():
        run_episode(gym.make(env_id, config=config, disable_env_checker=True))
        envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point",
                            config=config)
        envs.reset(seed=0)
        envs.close()
    if max_kernel_threads() >= 2:  # a generated kernel_threads = 2: the parallel twins too
        threaded = {"highway": {**BASE["sdc_gym/HighwayLoopBehavior-v0"]["highway"],
                                "kernel_threads": 2}}
        envs = gym.make_vec("sdc_gym/HighwayLoopBehavior-v0", num_envs=2,
                            vectorization_mode="vector_entry_point", config=threaded)
        envs.reset(seed=0)
        envs.step(np.zeros(2, dtype=np.int64))
        envs.close()


def run_episode(env: gym.Env, seed: int = 0) -> None:
    env.action_space.seed(seed)
    env.reset(seed=seed)
    for _ in range(STEPS):
        action = env.action_space.sample()
        if isinstance(env.unwrapped, HighwayLoopEnv):
            action = action[:0]  # the empty path: always valid (a sampled one is scattered)
        _, reward, terminated, truncated, _ = env.step(action)
        assert math.isfinite(reward)
        if terminated or truncated:
            break


def make_or_clear_error(env_id: str, config: Any) -> gym.Env | None:
    """The env, or None after a clear error (a ConfigError, or a ValueError naming what)."""
    try:
        return gym.make(env_id, config=config, disable_env_checker=True)
    except ConfigError:
        return None
    except ValueError as error:
        assert str(error), "a ValueError without a message"
        return None


@pytest.mark.parametrize("env_id", list(ENVS))
def test_generated_configs_are_a_clear_error_or_a_valid_episode(env_id):
    @FUZZ
    @given(extra=overrides(ENVS[env_id].DEFAULT_CONFIG))
    def check(extra: dict[str, Any]) -> None:
        env = make_or_clear_error(env_id, merged(BASE[env_id], extra))
        if env is None:
            return
        try:
            run_episode(env)
        except ValueError as error:  # e.g. traffic that cannot be placed: named at reset
            assert "car_count" in str(error) or "spawn" in str(error), error
        finally:
            env.close()

    check()


@given(config=st.one_of(HOSTILE, st.lists(HOSTILE, max_size=2)).filter(
    lambda config: config is not None and not isinstance(config, dict)))  # None: defaults
@FUZZ
def test_a_config_that_is_not_a_mapping_is_a_config_error(config):
    for env_id in ENVS:
        with pytest.raises(ConfigError, match="config must be a mapping"):
            gym.make(env_id, config=config)


# ------------------------------------------------------------------------ map files
def loop_text(points: np.ndarray, kind: str) -> str:
    if kind == "highway":
        step = np.diff(np.vstack([points, points[:1]]), axis=0)
        length = np.hypot(*step.T)
        length[length == 0] = 1.0
        s = np.concatenate([[0.0], np.cumsum(length)[:-1]])
        normal = np.column_stack([step[:, 1], -step[:, 0]]) / length[:, None]
        rows = np.column_stack([points, s, normal])
        return "".join(" ".join(f"{v:.6f}" for v in row) + "\n" for row in rows)
    return "".join(f"{x:.6f},{y:.6f},0,0\n" for x, y in points)


SHAPES = st.sampled_from(["random", "circle", "eight", "collinear", "tiny", "huge"])


@st.composite
def loop_points(draw: Any) -> np.ndarray:
    shape = draw(SHAPES)
    count = draw(st.integers(4, 60))
    if shape == "random":
        coordinate = st.floats(-2000.0, 2000.0, allow_nan=False)
        return np.array(draw(st.lists(st.tuples(coordinate, coordinate), min_size=4,
                                      max_size=count)))
    t = np.linspace(0.0, 2 * math.pi, count, endpoint=False)
    radius = {"circle": draw(st.floats(5.0, 3000.0)), "eight": 500.0, "collinear": 500.0,
              "tiny": draw(st.floats(0.1, 3.0)), "huge": draw(st.floats(1e5, 1e12))}[shape]
    if shape == "eight":
        return np.column_stack([radius * np.sin(t), 0.5 * radius * np.sin(2 * t)]) + 5000.0
    if shape == "collinear":
        return np.column_stack([radius * np.cos(t), np.zeros(count)]) + 5000.0
    return radius * np.column_stack([np.cos(t), np.sin(t)]) + radius + 100.0


@given(content=st.one_of(
    st.binary(max_size=300),
    st.text(max_size=200).map(lambda text: text.encode("latin-1", "replace")),
    st.tuples(loop_points(), st.just("highway")).map(lambda p: loop_text(*p).encode()),
    st.tuples(loop_points(), st.just("track")).map(lambda p: loop_text(*p).encode())))
@FUZZ
def test_generated_map_and_track_files_are_a_clear_error_or_a_valid_episode(content,
                                                                          tmp_path_factory):
    path = tmp_path_factory.mktemp("maps") / "loop.csv"
    path.write_bytes(content)
    for env_id, key in (("sdc_gym/HighwayLoop-v0", "map"), ("sdc_gym/TrackLoop-v0", "track")):
        env = make_or_clear_error(env_id, {**BASE[env_id], key: str(path)})
        if env is None:
            continue
        try:
            run_episode(env)
        except ValueError as error:
            assert "car_count" in str(error) or "stop line" in str(error), error
        finally:
            env.close()


# ------------------------------------------------------------------------ actions
DTYPES = [np.bool_, np.int8, np.int64, np.uint8, np.float16, np.float32, np.float64,
          np.complex128, object, np.str_]
SHAPES_OF_ACTIONS = [(), (1,), (2,), (3,), (4,), (1, 2), (2, 1), (1, 1, 2), (1, 3), (3, 2),
                     (60, 2), (0, 2)]


@st.composite
def actions(draw: Any) -> Any:
    kind = draw(st.sampled_from(["array", "array", "list", "scalar", "other"]))
    if kind == "scalar":
        return draw(st.one_of(HOSTILE_NUMBERS, st.booleans(), st.integers(-3, 12)))
    if kind == "other":
        return draw(st.one_of(st.none(), st.text(max_size=4), st.dictionaries(
            st.text(max_size=2), st.integers(), max_size=2)))
    shape = draw(st.sampled_from(SHAPES_OF_ACTIONS))
    values = np.array(draw(st.lists(st.one_of(st.floats(-2.0, 2.0), HOSTILE_NUMBERS),
                                    min_size=int(np.prod(shape)),
                                    max_size=int(np.prod(shape)))), dtype=np.float64)
    values = values.reshape(shape)
    if kind == "list":
        return values.tolist()
    dtype = draw(st.sampled_from(DTYPES))
    with np.errstate(all="ignore"):
        return values.astype(dtype) if dtype is not object else values.astype(object)


@pytest.mark.parametrize("env_id, config", [
    ("sdc_gym/HighwayLoop-v0", BASE["sdc_gym/HighwayLoop-v0"]),
    ("sdc_gym/TrackLoop-v0", BASE["sdc_gym/TrackLoop-v0"]),
    ("sdc_gym/HighwayLoopBehavior-v0", BASE["sdc_gym/HighwayLoopBehavior-v0"]),
    ("sdc_gym/HighwayLoopBehavior-v0", {**BASE["sdc_gym/HighwayLoopBehavior-v0"],
                                        "action": "continuous"}),
    ("sdc_gym/TrackLoopBehavior-v0", BASE["sdc_gym/TrackLoopBehavior-v0"]),
    ("sdc_gym/TrackLoopBehavior-v0", {**BASE["sdc_gym/TrackLoopBehavior-v0"],
                                      "action": "continuous"}),
])
def test_generated_actions_step_or_leave_the_env_bit_identical(env_id, config):
    env = gym.make(env_id, config=config, disable_env_checker=True).unwrapped
    env.reset(seed=0)

    @FUZZ
    @given(action=actions())
    def check(action: Any) -> None:
        before = pickle.dumps(env)
        try:
            _, reward, terminated, truncated, _ = env.step(action)
        except ValueError as error:
            assert str(error)
            assert pickle.dumps(env) == before, f"{action!r} was refused but changed the env"
            return
        accepted = np.asarray(action)
        assert accepted.dtype.kind in "iuf", f"{action!r} ({accepted.dtype}) was accepted"
        assert math.isfinite(reward)
        if terminated or truncated:
            env.reset(seed=0)

    check()
    env.close()


@pytest.mark.parametrize("env_id", ["sdc_gym/HighwayLoopBehavior-v0",
                                    "sdc_gym/TrackLoopBehavior-v0"])
@pytest.mark.parametrize("shape", [(1, 2), (2, 1), (1, 1, 2)])
def test_continuous_behavior_envs_refuse_reshapes_naming_shape_and_dtype(env_id, shape):
    env = gym.make(env_id, config={**BASE[env_id], "action": "continuous"}).unwrapped
    env.reset(seed=0)
    before = pickle.dumps(env)
    with pytest.raises(ValueError, match=r"must be an array of shape \(2,\) with a real dtype "
                                         r"\(int or float; not bool, complex, str or object\)"):
        env.step(np.zeros(shape, dtype=np.float32))
    assert pickle.dumps(env) == before


@pytest.mark.parametrize("action, fragment", [
    (np.ones(3, dtype=bool), "got dtype bool"),  # was full throttle
    (np.array([0.5, 0, 0], dtype=complex), "got dtype complex128"),
    (np.array([0.5, 0, 0], dtype=object), "got dtype object"),
    (["0.5", "0", "0"], "got dtype <U3"),
    ("0.5 0 0", "got the string"),
])
def test_the_track_refuses_bool_complex_object_and_string_actions(action, fragment):
    env = gym.make("sdc_gym/TrackLoop-v0", config=BASE["sdc_gym/TrackLoop-v0"]).unwrapped
    env.reset(seed=0)
    before = pickle.dumps(env)
    with pytest.raises(ValueError, match=r"shape \(3,\) with a real dtype") as raised:
        env.step(action)
    assert fragment in str(raised.value) and pickle.dumps(env) == before
    env.step(np.array([1, 0, 0], dtype=np.int64))  # ints are numbers: accepted


# ------------------------------------------------------------------------ native batches
VECTOR_IDS = ["sdc_gym/HighwayLoop-v0", "sdc_gym/HighwayLoopBehavior-v0", "sdc_gym/TrackLoop-v0",
              "sdc_gym/TrackLoopBehavior-v0"]


@pytest.mark.parametrize("env_id", VECTOR_IDS)
def test_generated_configs_to_the_native_batch_are_a_clear_error_or_a_valid_batch(env_id):
    """``gym.make_vec`` goes through the same validation as ``gym.make``."""
    @FUZZ
    @given(extra=overrides(ENVS[env_id].DEFAULT_CONFIG))
    def check(extra: dict[str, Any]) -> None:
        try:
            envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point",
                                config=merged(BASE[env_id], extra))
        except ConfigError:
            return
        except ValueError as error:
            assert str(error)
            return
        try:
            envs.reset(seed=0)
            for _ in range(STEPS):
                action = envs.action_space.sample()
                if env_id == "sdc_gym/HighwayLoop-v0":  # every env parks on its spot
                    action[:] = envs.unwrapped.world.ego.xy[:, None, :]
                _, reward, _, _, _ = envs.step(action)
                assert np.isfinite(reward).all()
        except ValueError as error:
            assert any(word in str(error) for word in ("car_count", "spawn", "stop line")), \
                error
        finally:
            envs.close()

    check()


@pytest.mark.parametrize("env_id", ["sdc_gym/HighwayLoopBehavior-v0",
                                    "sdc_gym/TrackLoopBehavior-v0"])
@pytest.mark.parametrize("action_type", ["discrete", "continuous"])
def test_generated_batch_actions_step_or_leave_the_batch_bit_identical(env_id, action_type):
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point",
                        config={**BASE[env_id], "action": action_type})
    envs.reset(seed=0)
    expected_shape = (2,) if action_type == "discrete" else (2, 2)

    @FUZZ
    @given(action=actions())
    def check(action: Any) -> None:
        before = pickle.dumps(envs.unwrapped.batch)
        try:
            envs.step(action)
        except ValueError as error:
            assert str(error)
            assert pickle.dumps(envs.unwrapped.batch) == before, \
                f"{action!r} was refused but changed the batch"
            return
        accepted = np.asarray(action)
        assert accepted.shape == expected_shape and accepted.dtype.kind in (
            "iu" if action_type == "discrete" else "iuf"), f"{action!r} was accepted"

    check()
    envs.close()


def test_the_path_batch_refuses_bool_and_complex_paths_naming_shape_and_dtype():
    envs = gym.make_vec("sdc_gym/HighwayLoop-v0", num_envs=2,
                        vectorization_mode="vector_entry_point",
                        config=BASE["sdc_gym/HighwayLoop-v0"])
    envs.reset(seed=0)
    parked = np.repeat(envs.unwrapped.world.ego.xy[:, None, :], 50, axis=1)
    before = pickle.dumps(envs.unwrapped.world)
    for bad in (parked.astype(bool), parked.astype(complex), parked[:, :10]):
        with pytest.raises(ValueError, match=r"actions must be an array of shape \(2, 50, 2\)"):
            envs.step(bad)
    assert pickle.dumps(envs.unwrapped.world) == before
    envs.step(parked)  # real numbers of the right shape: accepted
    envs.close()


def test_the_track_batch_refuses_bad_commands_before_setting_any():
    envs = gym.make_vec("sdc_gym/TrackLoop-v0", num_envs=2,
                        vectorization_mode="vector_entry_point",
                        config=BASE["sdc_gym/TrackLoop-v0"])
    envs.reset(seed=0)
    good = np.array([[0.5, 0.0, 0.0], [0.2, 0.0, 0.1]])
    before = pickle.dumps(envs.unwrapped.world)
    for bad, message in ((good.astype(bool), r"actions must be an array of shape \(2, 3\)"),
                         (good.astype(complex), "got dtype complex128"),
                         (good[:1], r"got shape \(1, 3\)"),
                         (np.array([[0.5, 0.0, 0.0], [2.0, 0.0, 0.0]]),
                          r"action\[0\] throttle = 2.0 is outside")):
        with pytest.raises(ValueError, match=message):
            envs.step(bad)
    assert pickle.dumps(envs.unwrapped.world) == before  # env 0's good command not set
    envs.step(good.astype(np.int64) * 0)  # real numbers of the right shape: accepted
    envs.close()


# ------------------------------------------------------------------------ YAML texts
YAML_TOKENS = st.sampled_from(["a: ", "b: ", "a: 1\n", "&x ", "*x", "&y [", "*y", "[", "]",
                               "{", "}", ", ", "- ", "\n", "  ", "1e-4", "<<: *x\n", "'s'",
                               ": ", "!!python/object:os.system ", "&x [*x]", "? "])


@given(tokens=st.lists(YAML_TOKENS, max_size=40))
@FUZZ
def test_generated_yaml_texts_are_data_or_a_yaml_error(tokens):
    """Every YAML text through the one loader: data, or a yaml.YAMLError (never a
    RecursionError, a Python object or an unbounded expansion)."""
    import yaml

    from sdc_gym.validation.yaml_files import parse_yaml_lines

    text = "".join(tokens)
    try:
        data, lines = parse_yaml_lines(text)
    except yaml.YAMLError as error:
        assert str(error)
        return
    assert isinstance(lines, dict)
    assert data is None or isinstance(data, dict | list | str | int | float | bool)


# ------------------------------------------------------------------------ reset options
RESET_OPTIONS = st.one_of(HOSTILE, st.dictionaries(
    st.sampled_from(["scenario", "reset_mask", "seed", "Scenario"]),
    st.one_of(st.none(), HOSTILE, st.lists(st.booleans(), max_size=3)), max_size=2))


@pytest.mark.parametrize("env_id", list(ENVS))
def test_generated_reset_options_reset_or_are_a_clear_error(env_id):
    env = gym.make(env_id, config=BASE[env_id], disable_env_checker=True)

    @FUZZ
    @given(options=RESET_OPTIONS)
    def check(options: Any) -> None:
        try:
            env.reset(seed=0, options=options)
        except ValueError as error:  # ConfigError included
            assert str(error)

    check()
    env.close()


@pytest.mark.parametrize("env_id", VECTOR_IDS)
def test_generated_batch_reset_options_reset_or_are_a_clear_error(env_id):
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point",
                        config=BASE[env_id], autoreset_mode="Disabled")
    envs.reset(seed=0)

    @FUZZ
    @given(options=RESET_OPTIONS)
    def check(options: Any) -> None:
        try:
            envs.reset(seed=0, options=options)
        except ValueError as error:
            assert str(error)
            return
        mask = options.get("reset_mask") if isinstance(options, dict) else None
        assert mask is None or np.asarray(mask).dtype == bool, f"{options!r} was accepted"

    check()
    envs.close()


# ------------------------------------------------------------------------ after an episode
@pytest.mark.parametrize("env_id", VECTOR_IDS)
def test_a_batch_after_an_episode_ended_refuses_what_it_refuses_before(env_id):
    """The step after an env ended (its action is ignored, NEXT_STEP) checks every env's
    action all the same: a refused batch leaves the batch bit-identical."""
    short = ({"highway": {"map": "oval", "max_duration": 0.4}}
             if env_id == "sdc_gym/HighwayLoopBehavior-v0" else
             {"track": {"track": "site", "max_duration": 0.4}, "decision_period_s": 0.2}
             if env_id == "sdc_gym/TrackLoopBehavior-v0" else
             {**BASE[env_id], "max_duration": 0.4})
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point",
                        config=short)
    envs.reset(seed=0)
    world = envs.unwrapped

    def valid() -> Any:
        action = envs.action_space.sample()
        if env_id == "sdc_gym/HighwayLoop-v0":
            action[:] = world.world.ego.xy[:, None, :]
        return action

    for _ in range(50):
        _, _, terminated, truncated, _ = envs.step(valid())
        if (terminated | truncated).any():
            break
    assert world._needs_reset.any()
    state = world.world if hasattr(world, "world") else world.batch

    @FUZZ
    @given(bad=st.sampled_from([math.nan, math.inf, "x", None, True]))
    def check(bad: Any) -> None:
        action = np.asarray(valid(), dtype=object)
        action[int(np.flatnonzero(world._needs_reset)[0])] = bad
        before = pickle.dumps(state)
        with pytest.raises(ValueError):
            envs.step(action)
        assert pickle.dumps(state) == before

    check()
    envs.close()


# ------------------------------------------------------------------------ scenario files
CAR = st.fixed_dictionaries({"lane": st.one_of(st.integers(-1, 4), HOSTILE)}, optional={
    "gap": st.one_of(st.sampled_from([-40.0, 0.0, 2.0, 6.0, 30.0, 1e9]), HOSTILE),
    "speed": st.one_of(st.floats(0.0, 30.0), HOSTILE), "kind": st.sampled_from(
        ["car", "truck", "semi", "plane"])})
SCENARIO = st.fixed_dictionaries({}, optional={
    "ego": st.fixed_dictionaries({}, optional={
        "lane": st.one_of(st.integers(-1, 4), HOSTILE),
        "d": st.one_of(st.floats(-5.0, 100.0), HOSTILE), "speed": st.floats(0.0, 30.0)}),
    "cars": st.lists(CAR, max_size=4),
    "duration": st.one_of(st.floats(0.1, 2.0), HOSTILE),
    "success": st.fixed_dictionaries({}, optional={"reach_lane": st.fixed_dictionaries(
        {"lane": st.integers(-1, 6), "within": st.floats(1.0, 50.0)})})})


@given(scenario=SCENARIO)
@FUZZ
def test_generated_scenario_files_are_a_clear_error_or_an_episode(scenario, tmp_path_factory):
    import yaml

    path = tmp_path_factory.mktemp("scenarios") / "case.yaml"
    path.write_text(yaml.safe_dump(scenario))
    env = gym.make("sdc_gym/HighwayLoop-v0", config={"max_duration": 2.0},
                   disable_env_checker=True)
    try:
        env.reset(seed=0, options={"scenario": str(path)})
        env.step(np.zeros((0, 2)))
    except ConfigError as error:
        assert str(error).startswith(str(path)), error  # file (and line) named
    finally:
        env.close()


# ------------------------------------------------------------------------ incident reports
@given(report=st.one_of(HOSTILE, st.dictionaries(
    st.sampled_from(["kind", "time", "replay", "agent", "seed"]),
    st.one_of(HOSTILE, st.sampled_from(["collision", "jerk"]), st.fixed_dictionaries(
        {}, optional={key: HOSTILE for key in ("map", "duration", "ego", "cars", "replay")})),
    max_size=5)))
@FUZZ
def test_generated_incident_reports_are_a_scenario_or_a_clear_error(report):
    from sdc_gym.scenarios import load_scenario
    from sdc_gym.scenarios.replay import incident_scenario

    try:
        scenario = incident_scenario(report)
    except ValueError as error:
        assert "incident report" in str(error), error
        return
    try:
        load_scenario(scenario)
    except ConfigError as error:
        assert str(error)


# ------------------------------------------------------------------------ run configs
RUN_VALUES = st.fixed_dictionaries({}, optional={
    "algo": st.one_of(st.sampled_from(["ppo", "dqn", "sac", "a2c", "ddpg"]), HOSTILE),
    "timesteps": HOSTILE_NUMBERS, "n_envs": HOSTILE_NUMBERS, "seed": HOSTILE_NUMBERS,
    "eval": st.one_of(HOSTILE, st.fixed_dictionaries({}, optional={
        "every": HOSTILE_NUMBERS, "episodes": HOSTILE_NUMBERS})),
    "config": st.one_of(HOSTILE, st.just({"action": "continuous"}))})
HP_OVERRIDES = st.lists(st.sampled_from([
    "learning_rate=1e-4", "learning_rate=abc", "gamma=2", "policy_kwargs.net_arch=[0]",
    "policy_kwargs.net_arch=[64, 64]", "policy_kwargs.activation_fn=torch.nn.ReLU",
    "policy_kwargs.activation_fn=os.system", "policy_kwargs=5", "n_steps=[1]",
    "batch_size=-1", "a: &a [*a]"]), max_size=3)


@given(values=RUN_VALUES, hp=HP_OVERRIDES)
@FUZZ
def test_generated_run_configs_and_hyperparameters_resolve_or_exit_clearly(values, hp,
                                                                         tmp_path_factory):
    import yaml

    import train

    folder = tmp_path_factory.mktemp("run")
    path = folder / "run.yaml"
    path.write_text(yaml.safe_dump({"env": "sdc_gym/HighwayLoopBehavior-v0", **values}))
    cli = [item for override in hp for item in ("--hp", override)]
    try:
        config = train.run_config(train.parse_args(
            ["--config", str(path), "--output", str(folder / "out"), *cli]))
    except SystemExit as error:
        assert isinstance(error.code, str) and error.code, error
        assert not (folder / "out").exists()
        return
    assert config["algo"] in ("ppo", "dqn", "qrdqn", "sac", "a2c")
