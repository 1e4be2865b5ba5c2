"""The track loop's drive-by-wire reference stack (the capstone's nodes) as components.

Data flow, one env step = one tick of :class:`~agents.track.rates.RateScheduler`, each node
at its own rate::

    observation ──► detector ──► behavior ──► updater ──► follower ──► twist controller ──► action
                   (light state  (go/stop,    (final       (pure        (PID + filter,
                    source, 70 m  target       waypoints    pursuit:     brake torque,
                    gate, 3-frame speed)       + speeds)    twist)       yaw controller)
                    debounce)

* :mod:`~agents.track.waypoints`: waypoint loader (once) and waypoint updater.
* :mod:`~agents.track.detector`: traffic light detector and the
  :class:`~agents.track.detector.LightStateSource` protocol (ground truth here; the CNN
  and crop classifiers in ``agents.track.light_classifier*``).
* :mod:`~agents.track.behavior`: the replaceable go/stop layer
  (:class:`~agents.track.behavior.TrackBehaviorPolicy`); rule-based
  :class:`~agents.track.behavior.StopAtRedLights`.
* :mod:`~agents.track.follower`: pure pursuit.
* :mod:`~agents.track.controllers`: PID, low-pass filter, yaw controller, twist controller.
* :mod:`~agents.track.rates`: node rates (the original's and the seed team's presets).
* :mod:`~agents.track.dbw_agent`: the wired agent for ``sdc_gym/TrackLoop-v0``.

Every component takes plain Python inputs (pose, speed, waypoints, light state), not the
observation dict, so they can be tested and recombined alone.
"""
