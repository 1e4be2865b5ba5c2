"""The track loop's drive-by-wire reference stack (the capstone's nodes) as components.

Data flow, one env step = one tick of :class:`~sdc_gym.stack.track.rates.RateScheduler`, each node
at its own rate::

    observation ──► detector ──► behavior ──► updater ──► follower ──► twist controller ──► action
                   (light state  (go/stop,    (final       (pure        (PID + filter,
                    source, 70 m  target       waypoints    pursuit:     brake torque,
                    gate, 3-frame speed)       + speeds)    twist)       yaw controller)
                    debounce)

* :mod:`~sdc_gym.stack.track.waypoints`: waypoint loader (once) and waypoint updater.
* :mod:`~sdc_gym.stack.track.detector`: traffic light detector and the
  :class:`~sdc_gym.stack.track.detector.LightStateSource` protocol (ground truth here; the CNN
  and crop classifiers in ``sdc_agents.track.light_classifier*``).
* :mod:`~sdc_gym.stack.track.behavior`: the replaceable go/stop layer
  (:class:`~sdc_gym.stack.track.behavior.TrackBehaviorPolicy`); rule-based
  :class:`~sdc_gym.stack.track.behavior.StopAtRedLights`.
* :mod:`~sdc_gym.stack.track.follower`: pure pursuit.
* :mod:`~sdc_gym.stack.track.controllers`: PID, low-pass filter, yaw controller, twist controller.
* :mod:`~sdc_gym.stack.track.rates`: node rates (the original's and the seed team's presets).
* :mod:`~sdc_gym.stack.track.dbw_stack`: the wired stack for ``sdc_gym/TrackLoop-v0``
  (``sdc_agents.track.dbw_agent`` builds it with a light source chosen by name).

Every component takes plain Python inputs (pose, speed, waypoints, light state), not the
observation dict, so they can be tested and recombined alone.
"""
