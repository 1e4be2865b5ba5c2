"""The drive-by-wire reference stack (:mod:`sdc_gym.stack.track.dbw_stack`) as an agent for
``sdc_gym/TrackLoop-v0``, with its traffic light source chosen by name."""

from __future__ import annotations

import gymnasium as gym

from sdc_gym.stack.track.behavior import TrackBehaviorPolicy
from sdc_gym.stack.track.controllers import TwistControllerParameters
from sdc_gym.stack.track.dbw_stack import DBWStackAgent, dbw_stack_for_env
from sdc_gym.stack.track.detector import GroundTruthLightSource, LightStateSource
from sdc_gym.stack.track.follower import FollowerParameters
from sdc_gym.stack.track.mpc import MPCParameters
from sdc_gym.stack.track.rates import NodeRates

STEERING_LOWPASS = TwistControllerParameters(steering_tau_s=0.1)
"""The seed's "low pass filter for the steering command": 0.1 s, the throttle's constant."""
NO_THROTTLE_LOWPASS = TwistControllerParameters(throttle_tau_s=0.0)
"""The seed's "improve or remove the low pass filter": removed."""
LIGHT_SOURCES = ("ground_truth", "cnn", "crop")
"""Light source names :func:`dbw_agent` builds itself (or pass any LightStateSource)."""


def light_source_for(env: gym.Env, name: str) -> LightStateSource:
    """The light state source called ``name`` (:data:`LIGHT_SOURCES`) for ``env``.

    ``"ground_truth"`` needs the env config ``observe_light_states: True``; ``"cnn"`` and
    ``"crop"`` (the committed classifiers of :mod:`sdc_agents.track.light_classifier`, torch)
    need the camera (``camera: {enabled: True, preset: "training"}``).
    """
    unwrapped = env.unwrapped
    spaces = getattr(unwrapped.observation_space, "spaces", {})
    if name == "ground_truth":
        if unwrapped.track.light_count and "light_states" not in spaces:
            raise ValueError("light_source 'ground_truth' needs the env config "
                             "{'observe_light_states': True}")
        return GroundTruthLightSource()
    if name in ("cnn", "crop"):
        camera = getattr(unwrapped, "camera", None)
        if camera is None or "camera" not in spaces:
            raise ValueError(f"light_source {name!r} needs the env config "
                             "{'camera': {'enabled': True, 'preset': 'training'}}")
        # torch is imported only for the classifier sources.
        from sdc_agents.track.light_classifier import CNNLightSource, CropLightSource

        if name == "cnn":
            return CNNLightSource()
        return CropLightSource(unwrapped.track, camera.config)
    raise ValueError(f"unknown light source {name!r}; choose one of {list(LIGHT_SOURCES)} "
                     "or pass a LightStateSource")


def dbw_agent(
    env: gym.Env,
    light_source: str | LightStateSource = "ground_truth",
    *,
    rates: str | NodeRates = "original",
    behavior: TrackBehaviorPolicy | None = None,
    follower: FollowerParameters | None = None,
    name: str | None = None,
    follower_kind: str = "pure_pursuit",
    mpc_params: MPCParameters | None = None,
    controller: TwistControllerParameters | None = None,
) -> DBWStackAgent:
    """The reference stack for a ``TrackLoop-v0`` env: its track, car, speed limit, loop
    period and front bumper offset.

    Args:
        light_source: a name of :data:`LIGHT_SOURCES` (see :func:`light_source_for`) or
            any :class:`LightStateSource`.
        rates: ``"original"``, ``"seed"`` or :class:`NodeRates`.
        behavior: the go/stop policy (default: :class:`StopAtRedLights`).
        follower: pure pursuit settings (default:
            :data:`~sdc_gym.stack.track.follower.CONTINUOUS_FOLLOWER`, recomputing every cycle,
            the fix capstone teams made to the original node; ``FollowerParameters()`` is
            the original's hold-until-0.2 m-off rule, which weaves about +-0.25 m).
        name: label (default ``dbw_<source>_<rates>``).
        follower_kind: ``"pure_pursuit"`` or ``"mpc"``
            (:data:`~sdc_gym.stack.track.dbw_stack.FOLLOWERS`); ``mpc_params`` its settings.
        controller: the twist controller's settings (PID gains, low-pass filters).
    """
    if isinstance(light_source, str):
        source = light_source_for(env, light_source)
        label = light_source
    else:
        source = light_source
        label = type(light_source).__name__
    rates_label = rates if isinstance(rates, str) else "custom"
    return dbw_stack_for_env(env, source, name=name or f"dbw_{label}_{rates_label}",
                             rates=rates, behavior=behavior, follower=follower,
                             follower_kind=follower_kind, mpc_params=mpc_params,
                             controller=controller)

