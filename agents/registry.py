"""Agents by name, so that scripts can say ``--agents lane_keeping`` and build one per env.

An agent has ``name``, ``reset()`` (start of an episode) and ``act(observation)`` (the
action for ``env.step``; see :mod:`sdc_agents.protocol`). A factory takes the (unwrapped) env
it will drive, so it can read the map and the env's configuration. This module is the one
door of the package for the evaluation machinery (:mod:`sdc_evaluation`): it builds agents and
re-exports the protocol.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, Final

import gymnasium as gym

from sdc_agents.committed_policies import committed_policy_agents
from sdc_agents.highway.fsm import DrivingStyle
from sdc_agents.highway.fsm_agent import fsm_agent, fsm_rules_agent
from sdc_agents.lane_keeping import LaneKeepingDriver
from sdc_agents.protocol import Agent, EpisodeAborted
from sdc_agents.track.dbw_agent import NO_THROTTLE_LOWPASS, STEERING_LOWPASS, dbw_agent
from sdc_agents.track.tuning import tuned_dbw_agent
from sdc_gym.stack.track.follower import FollowerParameters

__all__ = ["AGENTS", "AGENT_ENVS", "AGENT_KINDS", "KIND_ENVS", "Agent", "EpisodeAborted",
           "agent_label", "check_agent_builds", "check_agent_env", "make_agent",
           "parse_agent_spec"]


AgentFactory = Callable[[gym.Env], Agent]

_TRACK_VARIANTS: dict[str, AgentFactory] = {
    "dbw_mpc": lambda env: dbw_agent(env, "ground_truth", follower_kind="mpc",
                                     name="dbw_mpc"),
    "dbw_steering_lowpass": lambda env: dbw_agent(
        env, "ground_truth", controller=STEERING_LOWPASS, name="dbw_steering_lowpass"),
    "dbw_no_throttle_lowpass": lambda env: dbw_agent(
        env, "ground_truth", controller=NO_THROTTLE_LOWPASS, name="dbw_no_throttle_lowpass"),
    **{f"dbw_{tuner}": (lambda env, _tuner=tuner: tuned_dbw_agent(env, _tuner))
       for tuner in ("twiddle", "optuna")},
}

AGENTS: dict[str, AgentFactory] = {
    "lane_keeping": lambda env: LaneKeepingDriver(env.unwrapped.road),
    "fsm_conservative": lambda env: fsm_agent(env, DrivingStyle.CONSERVATIVE),
    "fsm_bold": lambda env: fsm_agent(env, DrivingStyle.BOLD),
    # With Kalman tracking of every car (for the env's sensor noise).
    "fsm_conservative_kf": lambda env: fsm_agent(env, DrivingStyle.CONSERVATIVE, tracking=True),
    "fsm_bold_kf": lambda env: fsm_agent(env, DrivingStyle.BOLD, tracking=True),
    # The seed's further work (issue 29): Bold with one optional mode or option, from its
    # packaged rule file (agents/highway/rules/<name>.yaml); any rule file: "fsm:PATH".
    **{f"fsm_{rules}": (lambda env, _rules=rules: fsm_rules_agent(env, _rules,
                                                                  name=f"fsm_{_rules}"))
       for rules in ("alert", "caution", "reverse", "hyper", "straight_braking", "reroute",
                     "easing")},
    # The track loop's drive-by-wire stack, by traffic light source: the env's ground truth
    # (config observe_light_states), or the committed classifiers on the camera image
    # (config camera: {enabled: true, preset: training}).
    "dbw_ground_truth": lambda env: dbw_agent(env, "ground_truth", name="dbw_ground_truth"),
    "dbw_cnn": lambda env: dbw_agent(env, "cnn", name="dbw_cnn"),
    "dbw_crop": lambda env: dbw_agent(env, "crop", name="dbw_crop"),
    # Node rates and follower variants, for the rates study (ground-truth lights).
    "dbw_seed_rates": lambda env: dbw_agent(env, "ground_truth", rates="seed",
                                            name="dbw_seed_rates"),
    "dbw_original_follower": lambda env: dbw_agent(env, "ground_truth",
                                                   follower=FollowerParameters(),
                                                   name="dbw_original_follower"),
    # The seed team's further work (issue 29): MPC follower, low-pass options, tuned gains.
    **_TRACK_VARIANTS,
}


POLICY_KINDS: Final = ("ppo", "dqn", "qrdqn", "sac", "a2c", "rllib")
"""The trained-policy kinds (sdc_agents.policy_agent.POLICY_KINDS, without importing it)."""
AgentKindFactory = Callable[..., Agent]
"""``factory(argument, env, **options)``: builds the agent of a ``"kind:argument"`` spec."""


def _external_agent(argument: str, env: gym.Env, **options: Any) -> Agent:
    from sdc_agents.external import external_agent  # the websocket client only when used

    return external_agent(argument, env, **options)


def _capstone_agent(argument: str, env: gym.Env, **options: Any) -> Agent:
    from sdc_agents.capstone import capstone_agent  # the Socket.IO client only when used

    return capstone_agent(argument, env, **options)


def _policy_agent(kind: str, argument: str, env: gym.Env) -> Agent:
    from sdc_agents.policy_agent import policy_agent  # SB3 and torch only when used

    return policy_agent(env, kind, argument)


AGENT_KINDS: dict[str, AgentKindFactory] = {
    # The FSM with the rules of a YAML rule file, a path or a packaged one's name:
    # "fsm:my_rules.yaml", "fsm:bold" (agents/highway/fsm_rules.py).
    "fsm": lambda argument, env, **options: fsm_rules_agent(env, argument, **options),
    # A planner written for the original highway simulator, run per episode and driven
    # through its wire protocol: "external:./path_planning" (agents/external.py).
    "external": _external_agent,
    # A capstone team's whole stack for the original track simulator, run per episode and
    # driven through its styx server: "capstone:roslaunch launch/styx.launch"
    # (agents/capstone.py).
    "capstone": _capstone_agent,
    # Trained policies of the behavior-level envs, in the place of the rule-based behavior
    # layer: stable-baselines3 models ("dqn:agents/highway/policies/dqn_highway.zip") and
    # RLlib checkpoints ("rllib:runs/ppo_rllib/model") (agents/policy_agent.py).
    **{kind: (lambda argument, env, _kind=kind, **options: _policy_agent(_kind, argument, env))
       for kind in POLICY_KINDS},
}
"""Agent specs ``"kind:argument"``, an agent per argument (a command, a model file...)."""

AGENT_KIND_SEPARATOR = ":"


HIGHWAY_PATH_ENVS: Final = ("sdc_gym/HighwayLoop-v0",)
TRACK_ENVS: Final = ("sdc_gym/TrackLoop-v0",)
AGENT_ENVS: Final[dict[str, tuple[str, ...]]] = {
    name: TRACK_ENVS if name.startswith("dbw_") else HIGHWAY_PATH_ENVS for name in AGENTS}
# The committed policies by name (agents/*/policies/<name>.zip with <name>.yaml beside it).
_POLICY_FACTORIES, _POLICY_ENVS = committed_policy_agents()
AGENTS.update(_POLICY_FACTORIES)
AGENT_ENVS.update({name: (env_id,) for name, env_id in _POLICY_ENVS.items()})
"""The envs each named agent drives: the highway agents send paths (HighwayLoop-v0), the
drive-by-wire stacks throttle, brake and steering (TrackLoop-v0). The ``kind:argument``
agents by :data:`KIND_ENVS` and their files (:func:`check_agent_env`)."""


KIND_ENVS: Final[dict[str, tuple[str, ...]]] = {
    "fsm": HIGHWAY_PATH_ENVS,  # the seed's FSM from a rule file
    "external": HIGHWAY_PATH_ENVS,  # the original highway simulator's wire protocol
    "capstone": TRACK_ENVS,  # the original track simulator's styx server
    **{kind: (*HIGHWAY_PATH_ENVS, *TRACK_ENVS) for kind in POLICY_KINDS},
}
"""The envs each agent kind can drive (a policy: the one its behavior env names, checked
from its file by :func:`sdc_agents.policy_agent.check_policy_file`)."""
KIND_DESCRIPTIONS: Final = {"fsm": "the FSM from a rule file",
                            "external": "an external planner (the original highway's path "
                                        "protocol)",
                            "capstone": "a capstone stack (the original track's styx server)",
                            **{kind: "a trained policy (its behavior layer under the "
                                     "rule-based stack)" for kind in POLICY_KINDS}}


NO_KINDS: Final = "none (a behavior env is driven by its policy: train.py evaluates it there)"


def check_agent_env(spec: str, env_id: str) -> None:
    """``ValueError`` naming the agent, the env and the envs it drives when the agent
    ``spec`` cannot drive ``env_id``, before any episode starts and without starting
    anything: a named agent by :data:`AGENT_ENVS` (``--agents dbw_ground_truth`` on the
    highway raised an AttributeError in every episode), a ``kind:argument`` agent by
    :data:`KIND_ENVS` (``external:`` planners on the track failed every episode on a
    highway config key, ``capstone:`` stacks on the highway), a policy by its file too
    (:func:`sdc_agents.policy_agent.check_policy_file`). The spaces of a policy are
    checked by :func:`check_agent_builds` on the env itself."""
    kind, name = parse_agent_spec(spec)
    if kind == "fsm":  # a rule file: read and checked before any episode starts
        from sdc_agents.highway.fsm_rules import load_rules

        load_rules(name)
    if kind is None:
        if env_id not in AGENT_ENVS[name]:
            fits = sorted(other for other, envs in AGENT_ENVS.items() if env_id in envs)
            raise ValueError(f"agent {name!r} drives {', '.join(AGENT_ENVS[name])}, not "
                             f"{env_id}; the agents for {env_id}: "
                             f"{', '.join(fits) or 'none by name'}")
        return
    if env_id not in KIND_ENVS[kind]:
        fits = sorted(other for other, envs in KIND_ENVS.items() if env_id in envs)
        raise ValueError(f"agent {spec!r} is {KIND_DESCRIPTIONS.get(kind, kind)}: it drives "
                         f"{', '.join(KIND_ENVS[kind])}, not {env_id}; the kinds for "
                         f"{env_id}: {', '.join(f'{other}:' for other in fits) or NO_KINDS}")
    if kind in POLICY_KINDS:
        from sdc_agents.policy_agent import check_policy_file

        check_policy_file(kind, name, env_id)


def check_agent_builds(spec: str, env: gym.Env) -> None:
    """``ValueError`` when a trained policy (``dqn:``, ``ppo:``, ``rllib:``...) cannot run on
    ``env`` (an env of the run's id and config): its agent is built once, as every episode
    builds it, which loads the model and checks its observation and action spaces against
    the behavior env under it. Other agents start processes when built: nothing to do."""
    kind, _ = parse_agent_spec(spec)
    if kind in POLICY_KINDS:
        make_agent(spec, env)


def _valid_agents() -> str:
    kinds = ", ".join(f"{kind}:ARGUMENT" for kind in sorted(AGENT_KINDS))
    return f"valid agents: {', '.join(sorted(AGENTS))}; or a spec {kinds}"


def parse_agent_spec(spec: str) -> tuple[str | None, str]:
    """``(kind, argument)`` of a ``"kind:argument"`` spec, ``(None, name)`` of a plain name.

    Raises ``ValueError`` listing the valid names and kinds for anything else.
    """
    if spec in AGENTS:
        return None, spec
    kind, separator, argument = spec.partition(AGENT_KIND_SEPARATOR)
    if not separator:
        raise ValueError(f"unknown agent {spec!r}; {_valid_agents()}")
    if kind not in AGENT_KINDS:
        raise ValueError(f"unknown agent kind {kind!r} in {spec!r}; {_valid_agents()}")
    if not argument.strip():
        raise ValueError(f"agent spec {spec!r} needs an argument after {kind!r}:, "
                         f"e.g. {kind}:./path_planning")
    return kind, argument


def make_agent(name: str, env: gym.Env,
               options: dict[str, dict[str, Any]] | None = None) -> Agent:
    """Build the agent ``name`` for ``env``: a name of :data:`AGENTS` or a
    ``"kind:argument"`` spec of :data:`AGENT_KINDS`, whose factory also gets
    ``options[kind]`` as keyword arguments. Unknown names list the valid ones."""
    kind, argument = parse_agent_spec(name)
    if kind is None:
        return AGENTS[argument](env)
    return AGENT_KINDS[kind](argument, env, **(options or {}).get(kind, {}))


def agent_label(spec: str) -> str:
    """A short name of an agent for tables and plots: the name itself, or for a
    ``"kind:argument"`` spec the kind and the argument's last part without its folders and
    suffix (``"dqn:agents/highway/policies/dqn_highway.zip"`` -> ``"dqn:dqn_highway"``,
    ``"external:./build/path_planning --port {port}"`` -> ``"external:path_planning"``;
    an external planner named by its folder, ``"external:./path_planning@~/a/build"`` ->
    ``"external:path_planning@build"``); a name that is not (or no longer) registered
    stays as it is."""
    kind, separator, argument = spec.partition(AGENT_KIND_SEPARATOR)
    if spec in AGENTS or not separator or kind not in AGENT_KINDS or not argument.split():
        return spec
    folder = ""
    if kind == "external" and "@" in argument:  # sdc_agents.external.FOLDER_SEPARATOR
        argument, _, folder = argument.rpartition("@")
        folder = "@" + (Path(folder).name or folder)
    words = argument.split() or [argument]
    return f"{kind}{AGENT_KIND_SEPARATOR}{Path(words[0]).stem or words[0]}{folder}"
