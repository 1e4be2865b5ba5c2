"""The driving stacks below the behavior layer, shared by the reference agents and the
behavior-level envs.

* :mod:`sdc_gym.stack.highway`: perception (world model), the behavior interface, and the
  seed's motion layer for ``HighwayLoop-v0``; the FSM behavior lives in ``agents``.
* :mod:`sdc_gym.stack.track`: the drive-by-wire nodes for ``TrackLoop-v0`` (detector,
  behavior interface + the rule-based go/stop policy, waypoint updater, pure pursuit, twist
  controller, node rates); the camera light classifiers live in ``agents``.

The behavior-level envs (``HighwayLoopBehavior-v0``, ``TrackLoopBehavior-v0``) put an RL
policy where the rule-based behavior sits, on top of exactly these layers, so that a trained
policy and the reference agent differ only in that layer.
"""
