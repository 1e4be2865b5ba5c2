"""The layered highway agent: perception -> behavior -> motion (the env is the controller).

``world_model`` and ``behavior`` define the interfaces between the layers; ``perception``
turns an observation into a :class:`~agents.highway.world_model.WorldModel`, a behavior
policy (the FSM of the seed, or an RL policy) turns that into a
:class:`~agents.highway.behavior.BehaviorDecision`, and ``motion`` turns decisions into the
path the env's perfect controller follows.
"""
