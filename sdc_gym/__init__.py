"""sdc-gym: the Udacity self-driving-car simulators as fast, faithful Gymnasium environments.

Importing the package registers the environments under the ``sdc_gym/`` namespace::

    import gymnasium as gym
    import sdc_gym  # noqa: F401  (registers the ids)

    env = gym.make("sdc_gym/HighwayLoop-v0", config={"traffic": {"car_count": 20}})
    env = gym.make("sdc_gym/TrackLoop-v0", config={"track": "site"})
"""

from gymnasium.envs.registration import register, registry

__version__ = "0.1.0"

_ENVIRONMENTS = {
    "sdc_gym/HighwayLoop-v0": "sdc_gym.envs.highway_loop:HighwayLoopEnv",
    "sdc_gym/TrackLoop-v0": "sdc_gym.envs.track_loop:TrackLoopEnv",
    "sdc_gym/HighwayLoopBehavior-v0": "sdc_gym.envs.highway_behavior:HighwayLoopBehaviorEnv",
    "sdc_gym/TrackLoopBehavior-v0": "sdc_gym.envs.track_behavior:TrackLoopBehaviorEnv",
}
# Natively batched vector envs: gym.make_vec(id, num_envs=E,
# vectorization_mode="vector_entry_point") steps E envs as one batch of arrays.
_VECTOR_ENTRY_POINTS = {
    "sdc_gym/HighwayLoop-v0": "sdc_gym.envs.highway_vector:make_highway_vector_env",
    "sdc_gym/HighwayLoopBehavior-v0": "sdc_gym.envs.highway_vector:make_behavior_vector_env",
    "sdc_gym/TrackLoop-v0": "sdc_gym.envs.track_vector:make_track_vector_env",
    "sdc_gym/TrackLoopBehavior-v0": "sdc_gym.envs.track_vector:make_track_behavior_vector_env",
}

ENV_IDS: tuple[str, ...] = tuple(_ENVIRONMENTS)
"""Every env id the package registers (``sdc_gym.ray.register_envs`` registers them with
Ray too)."""

for _env_id, _entry_point in _ENVIRONMENTS.items():
    if _env_id not in registry:
        register(id=_env_id, entry_point=_entry_point,
                 vector_entry_point=_VECTOR_ENTRY_POINTS.get(_env_id))

__all__ = ["ENV_IDS", "__version__"]
