"""Trained policies (stable-baselines3 or RLlib) as agents on the path-level envs.

``evaluate.py --agents dqn:agents/highway/policies/dqn_highway.zip fsm_bold`` compares a
policy trained on ``sdc_gym/HighwayLoopBehavior-v0`` with the rule-based planner on the
same ``sdc_gym/HighwayLoop-v0`` seeds: the policy takes the place of the FSM in the same
layered agent (shared perception and motion of :mod:`sdc_gym.stack.highway`), through the
same :class:`~sdc_gym.stack.highway.decisions.DecisionExecutor` and features it was trained
with. Track policies (``sdc_gym/TrackLoopBehavior-v0``) drive ``sdc_gym/TrackLoop-v0``
inside the drive-by-wire stack the same way.

The behavior env's settings the policy was trained with (decision period, shield, action
type) are read from the YAML next to the model: ``<model>.yaml`` or the run folder's
``config.yaml`` (train.py writes it), beside the model or one folder up (a checkpoint in
the run's ``checkpoints/``); without one the env's defaults apply.

``rllib:PATH`` is an RLlib checkpoint folder (``train.py --framework rllib``), loaded by
:mod:`sdc_agents.rllib_policy` behind the same ``predict`` as an SB3 model.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any, Final

import gymnasium as gym
import numpy as np

from sdc_gym.config import excerpt, resolve_config
from sdc_gym.envs.highway_behavior import HighwayLoopBehaviorEnv
from sdc_gym.envs.track_behavior import TrackLoopBehaviorEnv
from sdc_gym.stack.highway.behavior import BehaviorDecision
from sdc_gym.stack.highway.decisions import ACTION_NAMES, DecisionExecutor, HighwayDecision
from sdc_gym.stack.highway.features import BehaviorFeatures
from sdc_gym.stack.highway.layered import LayeredHighwayAgent
from sdc_gym.stack.highway.motion import MotionParameters, SeedMotionPlanner
from sdc_gym.stack.highway.perception import Perception, PerceptionParameters
from sdc_gym.stack.highway.shield import SafetyShield, ShieldParameters
from sdc_gym.stack.highway.world_model import WorldModel
from sdc_gym.stack.track.dbw_stack import DBWStackAgent, dbw_stack_for_env
from sdc_gym.stack.track.decisions import (
    TRACK_ACTION_NAMES,
    TrackDecisionBehavior,
    TrackFeatures,
)
from sdc_gym.stack.track.detector import GroundTruthLightSource
from sdc_gym.validation.yaml_files import read_yaml

SB3_KINDS = ("ppo", "dqn", "qrdqn", "sac", "a2c")
"""Agent spec prefixes of SB3 models: ``<kind>:<path to model.zip>`` (``qrdqn``: sb3-contrib's
QR-DQN, the same interface)."""
RLLIB_KIND = "rllib"
"""The agent spec prefix of RLlib checkpoints: ``rllib:<checkpoint folder>``."""
POLICY_KINDS = (*SB3_KINDS, RLLIB_KIND)
DRIVEN_ENV: Final = {"sdc_gym/HighwayLoopBehavior-v0": "sdc_gym/HighwayLoop-v0",
                     "sdc_gym/TrackLoopBehavior-v0": "sdc_gym/TrackLoop-v0"}
"""The env a policy drives, by the behavior env it was trained on."""
PACKAGE_DIR = Path(__file__).resolve().parent
"""This package's folder: ``agents/`` in a checkout, ``site-packages/sdc_agents/`` installed."""
PACKAGE_FOLDER = "agents"
"""The package's folder name in the repo, as the committed policies' paths begin
(``agents/highway/policies/dqn_highway.zip``)."""


def resolve_model_path(path: str | Path) -> Path:
    """``path`` as given when it exists, else a committed model's path
    (``agents/highway/...``) inside this package wherever it is installed (from any folder,
    also next to a user's own ``agents/``), as an absolute path: RLlib reads a relative
    checkpoint path as a URI and fails (``ArrowInvalid: URI has empty scheme``)."""
    given = Path(path).expanduser()
    if not given.exists() and not given.is_absolute() and given.parts[:1] == (PACKAGE_FOLDER,):
        packaged = PACKAGE_DIR.joinpath(*given.parts[1:])
        if packaged.exists():
            return packaged
    return given.absolute()


def load_model(kind: str, path: str | Path) -> Any:
    """The model of ``kind`` saved at ``path`` (on the CPU): an SB3 algorithm's, or an
    RLlib policy (:class:`sdc_agents.rllib_policy.RLlibPolicy`) for ``"rllib"``."""
    if kind not in POLICY_KINDS:
        raise ValueError(f"unknown policy kind {kind!r}; valid: {list(POLICY_KINDS)}")
    model_path = resolve_model_path(path)
    if kind == RLLIB_KIND:
        from sdc_agents.rllib_policy import load_rllib_policy  # Ray only when used

        return load_rllib_policy(model_path)
    if not model_path.is_file():
        raise ValueError(f"{kind}: no model file at {model_path}")
    with warnings.catch_warnings():
        # A model trained with n-step returns reloads its NStepReplayBuffer class, which
        # SB3 then warns would ignore n_steps; a loaded policy only predicts.
        warnings.filterwarnings("ignore", message=".*n_steps=.* is ignored", category=UserWarning)
        return algorithm_class(kind).load(model_path, device="cpu")


def algorithm_class(kind: str) -> type:
    """The SB3 class of ``kind``: stable-baselines3's, or sb3-contrib's for ``qrdqn``."""
    if kind not in SB3_KINDS:
        raise ValueError(f"unknown SB3 algorithm {kind!r}; valid: {list(SB3_KINDS)}")
    if kind == "qrdqn":
        from sb3_contrib import QRDQN

        return QRDQN
    import stable_baselines3

    return getattr(stable_baselines3, kind.upper())


MAX_MODEL_DATA_BYTES = 16 * 2**20
"""The ``data`` member of an SB3 zip read to name its algorithm (the committed DQN's: 9 kB)."""


def check_policy_file(kind: str, path: str | Path, env_id: str) -> None:
    """``ValueError`` when the policy ``kind:path`` cannot drive ``env_id``, found without
    loading it (no torch): the env is a path-level env a policy drives; the model is there
    (an SB3 zip, an RLlib folder); an SB3 zip holds the algorithm ``kind`` names (its
    policy class's module: ``ppo:`` of a DQN zip was a TypeError in every episode); the
    env its training config names drives ``env_id``. The spaces are checked when the agent
    is built (:func:`check_policy_spaces`)."""
    label = f"{kind}:{path}"
    if env_id not in DRIVEN_ENV.values():
        raise ValueError(f"policy {label!r}: a trained policy drives "
                         f"{' or '.join(DRIVEN_ENV.values())} (its behavior layer), not "
                         f"{env_id}")
    model_path = resolve_model_path(path)
    if kind == RLLIB_KIND:
        if not model_path.is_dir():
            raise ValueError(f"policy {label!r}: no RLlib checkpoint folder at {model_path}")
    else:
        if not model_path.is_file():
            raise ValueError(f"policy {label!r}: no model file at {model_path}")
        module, found = _sb3_algorithm(model_path, label)
        if found != kind:
            raise ValueError(f"policy {label!r}: {model_path.name} holds a policy of "
                             f"{module!r} (an SB3 {found.upper()} model), not of "
                             f"{kind.upper()}: give it as {found}:{path}")
    trained_on, _ = training_config(path)
    if trained_on is not None:
        if trained_on not in DRIVEN_ENV:
            raise ValueError(f"policy {label!r}: its training config names env "
                             f"{excerpt(trained_on)}; a policy is trained on one of "
                             f"{sorted(DRIVEN_ENV)}")
        if DRIVEN_ENV[trained_on] != env_id:
            raise ValueError(f"policy {label!r} was trained on {trained_on}: it drives "
                             f"{DRIVEN_ENV[trained_on]}, not {env_id}")


def _sb3_algorithm(model_path: Path, label: str) -> tuple[str, str]:
    """The module of the policy class an SB3 zip names and the algorithm it belongs to,
    read from its ``data`` JSON without unpickling anything. DQN and SAC have policy
    modules of their own (``stable_baselines3.dqn.policies``, sb3-contrib's QR-DQN
    ``sb3_contrib.qrdqn.policies``); PPO and A2C share
    ``stable_baselines3.common.policies`` and are told apart by PPO's ``clip_range``."""
    import json
    import zipfile

    try:
        with zipfile.ZipFile(model_path) as archive:
            if archive.getinfo("data").file_size > MAX_MODEL_DATA_BYTES:
                raise ValueError(f"its data member is over {MAX_MODEL_DATA_BYTES:,} bytes")
            data = json.loads(archive.read("data"))
        module = data["policy_class"]["__module__"]
        if not isinstance(module, str):
            raise TypeError(f"policy_class.__module__ is {excerpt(module)}")
    except (OSError, KeyError, TypeError, ValueError, zipfile.BadZipFile) as error:
        raise ValueError(f"policy {label!r}: {model_path} is not a stable-baselines3 model "
                         f"file ({type(error).__name__}: {excerpt(str(error))})") from None
    parts = module.split(".")
    if parts[0] not in ("stable_baselines3", "sb3_contrib") or len(parts) < 2:
        return module, module
    if parts[1] == "common":
        return module, "ppo" if "clip_range" in data else "a2c"
    return module, parts[1]


def check_policy_spaces(model: Any, observation_space: gym.Space, action_space: gym.Space,
                        what: str) -> None:
    """``ValueError`` unless ``model`` (SB3 or :class:`~sdc_agents.rllib_policy.RLlibPolicy`)
    takes the observations and gives the actions of ``what`` (the behavior env the agent
    runs under it): the same kind of space, shape and (Discrete) size."""
    for name, expected in (("observation", observation_space), ("action", action_space)):
        got = getattr(model, f"{name}_space")
        same = type(got) is type(expected) and got.shape == expected.shape and (
            not isinstance(expected, gym.spaces.Discrete) or int(got.n) == int(expected.n))
        if not same:
            raise ValueError(f"the policy's {name} space is {got}; {what} has {expected} "
                             f"(was it trained on another env or config?)")


def training_config(path: str | Path) -> tuple[str | None, dict[str, Any]]:
    """The env id and behavior-env config a model was trained with (None, {}: unknown)."""
    model_path = resolve_model_path(path)
    for candidate in (model_path.with_suffix(".yaml"), model_path.parent / "config.yaml",
                      model_path.parent.parent / "config.yaml"):
        if candidate.is_file():
            data = read_yaml(candidate, "policy's training config") or {}
            if not isinstance(data, dict) or not isinstance(data.get("config") or {}, dict):
                raise ValueError(f"{candidate}: the policy's training config must be a "
                                 "mapping with 'env' and a mapping 'config', got "
                                 f"{excerpt(data)}")
            return data.get("env"), dict(data.get("config") or {})
    return None, {}


class PolicyBehavior:
    """A trained highway policy as a :class:`~sdc_gym.stack.highway.behavior.BehaviorPolicy`.

    Decides every ``cycles_per_decision`` planning cycles (the trained decision period
    over the env's cycle) and holds the motion instruction in between, as the behavior
    env does; ``predict`` is deterministic.
    """

    def __init__(self, model: Any, features: BehaviorFeatures, executor: DecisionExecutor,
                 cycles_per_decision: int, action: str = "discrete") -> None:
        action_space = (gym.spaces.Discrete(len(ACTION_NAMES)) if action == "discrete"
                        else gym.spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32))
        check_policy_spaces(model, features.space, action_space,
                            f"HighwayLoopBehavior-v0 on this road with action {action!r}")
        self.model = model
        self.features = features
        self.executor = executor
        self.cycles_per_decision = cycles_per_decision
        self.action = action
        self.reset()

    def reset(self) -> None:
        self.executor.reset()
        self._cycle = 0
        self._plan: BehaviorDecision | None = None

    def decide(self, world: WorldModel) -> BehaviorDecision:
        if self._plan is None or self._cycle % self.cycles_per_decision == 0:
            observation = self.features.encode(world, self.executor)
            action, _ = self.model.predict(observation, deterministic=True)
            decision = (HighwayDecision.from_index(int(np.asarray(action).reshape(())))
                        if self.action == "discrete"
                        else HighwayDecision.from_vector(action, self.executor.cruise_speed_mps))
            self._plan = self.executor.execute(world, decision)
        elif self._plan.replan:  # a replan is an instruction for one cycle only
            self._plan = BehaviorDecision(self._plan.target_lane, self._plan.target_speed,
                                          self._plan.acceleration, False, True,
                                          self._plan.mode)
        self._cycle += 1
        return self._plan


def _cycles_per_decision(decision_frames: int, env_frames: int) -> int:
    if decision_frames % env_frames:
        valid = [f for f in range(1, decision_frames + 1) if decision_frames % f == 0]
        raise ValueError(f"the policy decides every {decision_frames} frames, which is not a "
                         f"multiple of the env's steps_per_action {env_frames}; use one of "
                         f"{valid}")
    return decision_frames // env_frames


def highway_policy_agent(env: gym.Env, kind: str, path: str | Path,
                         name: str | None = None) -> LayeredHighwayAgent:
    """The trained highway policy at ``path`` driving ``HighwayLoop-v0`` (see module doc)."""
    unwrapped = env.unwrapped
    _, trained = training_config(path)
    cfg = resolve_config(HighwayLoopBehaviorEnv.DEFAULT_CONFIG, trained,
                         owner="HighwayLoopBehavior-v0 (policy's training config)")
    road = unwrapped.road
    perception = Perception(road, PerceptionParameters(tracking=bool(cfg["kalman_tracking"])))
    shield = SafetyShield(ShieldParameters(**cfg["shield"])) if cfg["safety_shield"] else None
    executor = DecisionExecutor(shield, slow_step_mps=float(cfg["slow_step_mps"]))
    behavior = PolicyBehavior(
        load_model(kind, path), BehaviorFeatures(road.lane_count,
                                                 perception.params.sensing_range,
                                                 extended=cfg["observation"] == "extended"),
        executor, _cycles_per_decision(int(cfg["decision_frames"]),
                                       int(unwrapped.steps_per_action)), cfg["action"])
    return LayeredHighwayAgent(name or f"{kind}:{Path(path).stem}", road, behavior, perception,
                               SeedMotionPlanner(road, MotionParameters.for_env(unwrapped)))


def track_policy_agent(env: gym.Env, kind: str, path: str | Path,
                       name: str | None = None) -> DBWStackAgent:
    """The trained track policy at ``path`` inside the DBW stack on ``TrackLoop-v0``
    (ground-truth light states: the env config needs ``observe_light_states: True``)."""
    unwrapped = env.unwrapped
    _, trained = training_config(path)
    cfg = resolve_config(TrackLoopBehaviorEnv.DEFAULT_CONFIG, trained,
                         owner="TrackLoopBehavior-v0 (policy's training config)")
    if unwrapped.track.light_count and "light_states" not in unwrapped.observation_space.spaces:
        raise ValueError("a track policy needs the env config {'observe_light_states': True}")
    model = load_model(kind, path)
    continuous = cfg["action"] == "continuous"
    features = TrackFeatures(abs(unwrapped.params.decel_limit))
    check_policy_spaces(model, features.space,
                        gym.spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32) if continuous
                        else gym.spaces.Discrete(len(TRACK_ACTION_NAMES)),
                        f"TrackLoopBehavior-v0 with action {cfg['action']!r}")

    def choose(observation: np.ndarray) -> Any:
        action, _ = model.predict(observation, deterministic=True)
        return action

    behavior = TrackDecisionBehavior(features, continuous=continuous, chooser=choose,
                                     decision_period_s=float(cfg["decision_period_s"]),
                                     red_light_shield=bool(cfg["red_light_shield"]))
    return dbw_stack_for_env(env, GroundTruthLightSource(), behavior=behavior,
                             name=name or f"{kind}:{Path(path).stem}")


def policy_agent(env: gym.Env, kind: str, path: str | Path, name: str | None = None) -> Any:
    """A policy agent for ``env``: the highway or the track kind, by the env."""
    if hasattr(env.unwrapped, "track"):
        return track_policy_agent(env, kind, path, name)
    return highway_policy_agent(env, kind, path, name)
