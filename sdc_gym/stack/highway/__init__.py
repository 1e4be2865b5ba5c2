"""The highway stack: perception -> behavior -> motion (the env is the controller).

``world_model`` and ``behavior`` define the interfaces between the layers; ``perception``
turns an observation into a :class:`~sdc_gym.stack.highway.world_model.WorldModel`, a
behavior policy (the seed's FSM in ``sdc_agents.highway.fsm``, or an RL policy) turns that into a
:class:`~sdc_gym.stack.highway.behavior.BehaviorDecision`, and ``motion`` turns decisions
into the path the env's perfect controller follows. ``layered`` wires the three together.
"""
