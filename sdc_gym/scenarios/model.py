"""A scenario as data: who starts where, what they do when, what happens on the road, and
what counts as passing.

Built from a scenario file (or mapping) by :func:`sdc_gym.validation.scenarios.check_scenario`,
which checks every key and value; run by the highway worlds
(:mod:`sdc_gym.scenarios.runtime`). Distances in m, speeds in m/s, times in s; lanes are
0, 1, 2 from the yellow centre line outward; ``gap`` is centre to centre along s from the
ego's start (> 0 ahead). The file format, key by key, is in ``docs/scenarios.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

TRIGGERS = ("time", "gap_below", "gap_above", "ego_distance")
"""What starts a scripted action: the episode's time reaching ``time`` s; the car's gap
to the ego (its s minus the ego's, centre to centre, > 0 ahead) falling to ``gap_below`` m
or rising to ``gap_above`` m; the ego having driven ``ego_distance`` m."""
ACTIONS = ("cut_in", "lane_change", "brake", "stop", "go", "set_speed")
"""What a scripted car does: a sudden lane change (``cut_in``, 1 s by default, into the
ego's lane unless ``lane`` says otherwise, whoever is there), an ordinary
``lane_change`` (3 s, also without looking), ``brake`` at ``decel`` for ``duration`` s or
down to ``to_speed``, ``stop`` (brake at ``decel`` to a standstill and stay), ``go``
(drive on after a stop or a braking, optionally at a new desired ``speed``), and
``set_speed`` (a new desired speed)."""
EVENT_KINDS = ("closed_lane", "cargo", "animal")
"""Road events: a lane closed by cones and barriers over a stretch (traffic merges out
before it), fallen cargo (a static obstacle in a lane), an animal walking across."""


@dataclass(frozen=True)
class Trigger:
    """When an action (or an animal's walk) starts: ``kind`` of :data:`TRIGGERS`, ``value``."""

    kind: str
    value: float


@dataclass(frozen=True)
class EgoStart:
    """The ego at the start: ``s`` (None: the map's start), ``lane`` (its centre) or ``d``
    (m right of the centre line; neither: the map's start), ``speed``; a replay's exact
    pose and path (``x``, ``y``, ``yaw``, ``path``: the points not yet driven,
    ``in_flight``: paths sent but not yet arrived, as ``(frames until due, points)``)."""

    s: float | None
    d: float | None
    speed: float = 0.0
    lane: int | None = None
    x: float | None = None
    y: float | None = None
    yaw: float | None = None
    path: tuple[tuple[float, float], ...] | None = None
    in_flight: tuple[tuple[int, tuple[tuple[float, float], ...]], ...] = ()


@dataclass(frozen=True)
class CarStart:
    """A traffic car at the start: ``kind`` (a vehicle kind), ``lane``, position by
    ``gap`` to the ego or absolute ``s``, ``speed``, ``desired_speed``, whether it changes
    lanes of its own, whether it is ``stalled`` (stands still for good: an obstacle) and
    whether it is recycled once more than the traffic's ``spawn_range`` from the ego.
    ``state``: a recorded car's exact state (replays; the keys of
    :class:`~sdc_gym.traffic.slots.SlotSpec`)."""

    name: str
    kind: str
    lane: int
    gap: float | None
    s: float | None
    speed: float
    desired_speed: float
    lane_changes: bool
    stalled: bool = False
    recycle: bool = False
    state: dict[str, Any] | None = None


@dataclass(frozen=True)
class Action:
    """Car ``car`` (its index in :attr:`Scenario.cars`) does ``do`` (of :data:`ACTIONS`)
    once ``when`` holds, with its parameters (``lane``, ``duration``, ``decel``,
    ``to_speed``, ``speed``; None: the defaults)."""

    car: int
    when: Trigger
    do: str
    lane: int | None = None
    duration: float | None = None
    decel: float | None = None
    to_speed: float | None = None
    speed: float | None = None


@dataclass(frozen=True)
class RoadEvent:
    """A road event (``kind`` of :data:`EVENT_KINDS`) at ``gap`` from the ego's start or
    absolute ``s`` (the start of a closed lane; the object's centre otherwise).

    ``closed_lane``: ``lane``, ``length`` m. ``cargo``: ``lane``, ``offset`` m from the
    lane's centre, ``size`` (length, width) m. ``animal``: walks at ``speed`` m/s from
    ``from_d`` to ``to_d`` (m right of the centre line) once ``when`` holds.
    """

    kind: str
    gap: float | None = None
    s: float | None = None
    lane: int = 0
    length: float = 150.0
    offset: float = 0.0
    size: tuple[float, float] | None = None
    from_d: float = -1.5
    to_d: float | None = None
    speed: float = 1.5
    when: Trigger = Trigger("time", 0.0)


@dataclass(frozen=True)
class Success:
    """What passing means (every condition set must hold; see ``docs/scenarios.md``):
    no collision; none of the ``no_incidents`` kinds; ``reach_lane`` (lane, within s);
    ``keep_lane`` (lane, for s from the start); ``min_distance`` m driven; ``end_lane``."""

    no_collision: bool = True
    no_incidents: tuple[str, ...] = ()
    reach_lane: tuple[int, float] | None = None
    keep_lane: tuple[int, float] | None = None
    min_distance: float | None = None
    end_lane: int | None = None


@dataclass(frozen=True)
class ReplayState:
    """A replay's recorded internals: the traffic clock (``traffic_step``: the decision
    instants and the lateral wander fall as they did), the env generator's state (the
    respawns and rogue moments to come are the recorded ones), the respawn pause left,
    and where it came from (``source``: run, agent, seed, incident)."""

    traffic_step: int = 0
    generator_state: dict[str, Any] | None = None
    respawn_blocked_steps: int = 0
    source: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Scenario:
    """A whole scenario (see the module docstring); ``source`` names its file (or
    ``<mapping>``), for messages."""

    name: str
    description: str
    source: str
    duration: float
    ego: EgoStart
    cars: tuple[CarStart, ...] = ()
    actions: tuple[Action, ...] = ()
    road_events: tuple[RoadEvent, ...] = ()
    success: Success = Success()
    map: str | None = None
    replay: ReplayState | None = None
    where: dict[str, str] = field(default_factory=dict, compare=False, repr=False)

    def at(self, path: str) -> str:
        """``file:line`` of a key path (for errors found when an env applies it)."""
        while path not in self.where and path:
            path = path.rsplit(".", 1)[0] if "." in path else path.rsplit("[", 1)[0] \
                if "[" in path else ""
        return self.where.get(path, self.source)

    @property
    def objects_needed(self) -> int:
        """Road-object slots this scenario fills (a closed lane needs one per piece)."""
        from sdc_gym.traffic.road_events import slots_needed  # (imports the kinds)

        return sum(slots_needed(event) for event in self.road_events)
