"""Traffic light detector: distance gate, pluggable light state source, 3-in-a-row debouncing.

The reference stack's detector node (spec "The nodes"), per camera frame:

1. **Gate**: only when the next stop line is within ``gate_m`` (70 m) is the light looked
   at; otherwise the frame's state is UNKNOWN (no light in range).
2. **Classify**: a :class:`LightStateSource` returns the state of the next light for the
   observation (RED 0, YELLOW 1, GREEN 2, UNKNOWN 4: the codes of
   :mod:`sdc_gym.lights.traffic_lights`). It is called only inside the gate, so a costly
   classifier runs only when it matters.
3. **Debounce**: a new state is published only after it was seen on ``debounce_frames``
   (3) consecutive frames; until then the previous published state stands. A change of
   the next stop line (one was passed) clears it: the old line's state never applies to
   the new one.
4. **Output**: a :class:`LightReport`; its :attr:`~LightReport.red_light_waypoint` is the
   original node's message: the stop-line waypoint index of the next light if it is red,
   else -1.

Light state sources (the :class:`LightStateSource` protocol)
    Any object with ``classify(observation) -> int``. ``observation`` is the env's
    observation dict (``TrackLoop-v0``: ``pose``, ``velocity``, ``next_stop_line`` = [index
    of the next stop line, its distance m], optional ``light_states``, optional
    ``camera`` (H, W, 3) uint8). The light of interest is the one of the next stop line
    (light ``i`` belongs to stop line ``i``); the method returns its state as an ``int``
    code, UNKNOWN when no light is recognised. The committed classifiers
    (:mod:`sdc_agents.track.light_classifier`) return RED, YELLOW or UNKNOWN: a red / not-red
    classifier alone would leave the behavior layer unable to stop early for a yellow
    light, and it runs reds that turn red inside its braking distance.

    * :class:`GroundTruthLightSource` (here): the env's ``light_states`` observation
      (``observe_light_states: True`` in the env config).
    * the whole-image CNN and the crop classifier (``sdc_agents.track.light_classifier*``):
      the camera image, the crop source projecting the next light's known 3D box.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sdc_gym.kernel_compiler import TypedCall
from sdc_gym.lights.traffic_lights import RED, UNKNOWN, VALID_STATES
from sdc_gym.stack.track.node_kernels import (
    DetectorConstants,
    detect,
    detector_reset,
    detector_state,
    in_gate,
)

DETECTION_GATE_M = 70.0
DEBOUNCE_FRAMES = 3


@runtime_checkable
class LightStateSource(Protocol):
    """Anything that tells the next light's state from an observation (see the module)."""

    def classify(self, observation: Mapping[str, Any]) -> int:
        """The next stop line's light state code (RED 0, YELLOW 1, GREEN 2, UNKNOWN 4)."""


def next_stop_line(observation: Mapping[str, Any]) -> tuple[int, float]:
    """(index, distance m) of the next stop line from ``observation["next_stop_line"]``
    (index -1 when the track has none)."""
    try:
        value = observation["next_stop_line"]
    except KeyError:
        raise KeyError("observation has no 'next_stop_line' ([index, distance m]); "
                       f"keys: {sorted(observation)}") from None
    index, distance = float(value[0]), float(value[1])
    return (round(index), distance) if index >= 0 else (-1, math.inf)


class GroundTruthLightSource:
    """The env's ground truth: ``observation["light_states"][next stop line]``."""

    def classify(self, observation: Mapping[str, Any]) -> int:
        line, _ = next_stop_line(observation)
        if line < 0:
            return UNKNOWN
        try:
            states = observation["light_states"]
        except KeyError:
            raise KeyError("GroundTruthLightSource needs the observation's 'light_states': "
                           "create the env with config {'observe_light_states': True}") from None
        return int(states[line])


@dataclass(frozen=True)
class LightReport:
    """The detector's published output.

    Attributes:
        stop_line: index of the next stop line (-1: none).
        stop_waypoint: its base waypoint index (-1: none).
        state: the debounced light state of that line (UNKNOWN: none in range / unseen).
        distance_m: m to that line when detected (inf: none).
        time_s: when it was published (agent clock).
    """

    stop_line: int
    stop_waypoint: int
    state: int
    distance_m: float
    time_s: float

    @property
    def red_light_waypoint(self) -> int:
        """The original message: the stop-line waypoint index if the light is red, else -1."""
        return self.stop_waypoint if self.state == RED else -1


@dataclass(frozen=True)
class DetectorParameters:
    """Attributes: gate_m (look at lights within this distance, m); debounce_frames (the
    same state on this many consecutive frames before it is published)."""

    gate_m: float = DETECTION_GATE_M
    debounce_frames: int = DEBOUNCE_FRAMES

    def __post_init__(self) -> None:
        if not self.gate_m > 0 or not self.debounce_frames >= 1:
            raise ValueError(f"DetectorParameters: need gate_m > 0 m and debounce_frames >= "
                             f"1, got {self.gate_m!r}, {self.debounce_frames!r}")


class TrafficLightDetector:
    """The traffic light detector node; see the module docstring. Its debouncing is
    :func:`~sdc_gym.stack.track.node_kernels.detect` (the kernel the batched stack runs for
    every env); this class is its batch of one, with a Python light state source.

    Args:
        stop_waypoints: (k,) base waypoint index of each stop line (see
            :func:`~sdc_gym.stack.track.waypoints.stop_line_waypoints`).
        source: the light state source (:meth:`detect`); :meth:`process` takes a
            callable instead.
    """

    def __init__(self, stop_waypoints: ArrayLike, source: LightStateSource | None = None,
                 params: DetectorParameters | None = None) -> None:
        self.stop_waypoints: NDArray[np.int64] = np.asarray(stop_waypoints, dtype=np.int64)
        self.source = source
        self.params = params or DetectorParameters()
        self.constants = DetectorConstants(np.ascontiguousarray(self.stop_waypoints),
                                           float(self.params.gate_m),
                                           int(self.params.debounce_frames))
        self.classifications = 0
        self._state = detector_state(1)
        self._in_gate, self._detect = TypedCall(in_gate), TypedCall(detect)
        self.reset()

    def reset(self) -> None:
        detector_reset(self._state, 0)
        self.report = LightReport(-1, -1, UNKNOWN, math.inf, -math.inf)

    @property
    def state(self) -> int:
        """The published (debounced) state of the current line's light."""
        return int(self._state.state[0])

    def process(self, time_s: float, stop_line: int, distance_m: float,
                classify: Callable[[], int]) -> LightReport:
        """One frame from plain inputs: the next stop line and its distance; ``classify``
        is called (inside the gate only) for the light's state code."""
        stop_line, distance_m = int(stop_line), float(distance_m)
        if self._in_gate(self.constants, stop_line, distance_m):
            frame_state = int(classify())
            self.classifications += 1
            if frame_state not in VALID_STATES:
                raise ValueError(f"light state source returned {frame_state!r}; valid codes: "
                                 f"{sorted(VALID_STATES)} (RED 0, YELLOW 1, GREEN 2, "
                                 "UNKNOWN 4)")
        else:
            frame_state = UNKNOWN
        if stop_line >= len(self.stop_waypoints):
            raise ValueError(f"stop line index {stop_line} out of range: the detector "
                             f"knows {len(self.stop_waypoints)} stop line(s)")
        self._detect(self.constants, self._state, 0, float(time_s), stop_line, distance_m,
               frame_state)
        s = self._state
        self.report = LightReport(stop_line, int(s.report_waypoint[0]), int(s.state[0]),
                                  distance_m, time_s)
        return self.report

    def detect(self, observation: Mapping[str, Any], time_s: float) -> LightReport:
        """One frame from an env observation, classified by :attr:`source`."""
        if self.source is None:
            raise ValueError("TrafficLightDetector.detect needs a LightStateSource "
                             "(source=...)")
        line, distance = next_stop_line(observation)
        source = self.source
        return self.process(time_s, line, distance, lambda: source.classify(observation))
