"""Traffic light phases on the track: a fixed green -> yellow -> red cycle per light.

Model. Every light runs the same kind of cycle, green first::

    phase 0 ........ green_s ........ green_s + yellow_s ........ cycle_s (= 0 again)
          |  GREEN  |       YELLOW        |           RED            |

A light's state at time ``t`` (s since ``reset``) is a pure function of ``t``: the phase is
``(t + offset_s) mod cycle_s``, where ``offset_s`` is how far into its cycle the light is at
``t = 0``. ``reset(rng)`` draws the offsets uniformly over the cycle (seeded), unless fixed
offsets were given; ``step(dt)`` only advances the clock. So the states at any time are
reproducible and can be asked for directly with :meth:`TrafficLights.state_at`.

State codes are the original simulator's (``styx_msgs/TrafficLight``): RED 0, YELLOW 1,
GREEN 2, UNKNOWN 4. Because GREEN = 2 and YELLOW = 1, a cycling light's state is the number
of phase boundaries still ahead in its cycle: ``(phase < green_s) + (phase < green_s +
yellow_s)``, one expression for all lights at once.

Scripted lights (for tests and scenarios) replace the cycle of chosen lights by either a
constant state or a schedule ``[(t0, state0), (t1, state1), ...]`` with ``t0 = 0`` and
strictly increasing times: the state is that of the last entry whose time is <= t, held
forever after the last entry.

Default durations (a 40 km/h track, 11.1 m/s): the yellow must let a driver who sees it
begin stop comfortably, or clear the line. The kinematic (ITE) yellow interval is
``t_reaction + v / (2 a)`` = 1.0 s + 11.1 / (2 x 3.05 m/s^2) = 2.8 s, rounded up to the
customary 3 s minimum. Green and red last 10 s each: long enough that a car stopped at a
red line waits a noticeable time, short enough that a 7 km lap past 8 lights meets all
three states. Cycle 23 s.

Cost. ``step`` adds ``dt`` and compares with the cached time of the next change of any
light; the states are recomputed only when a light changes. The phase arithmetic is the
numba kernel of :mod:`sdc_gym.lights.light_kernel` (the track world steps every env's
lights with it); :class:`TrafficLights` is its batch of one.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import IntEnum
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.config import ConfigError, excerpt, resolve_config
from sdc_gym.lights.light_kernel import LightSchedule, refresh_lights, states_at, times_to_change


class LightState(IntEnum):
    """The original's light state codes (``styx_msgs/TrafficLight``)."""

    RED = 0
    YELLOW = 1
    GREEN = 2
    UNKNOWN = 4


RED = int(LightState.RED)
YELLOW = int(LightState.YELLOW)
GREEN = int(LightState.GREEN)
UNKNOWN = int(LightState.UNKNOWN)
VALID_STATES = frozenset(int(state) for state in LightState)

DEFAULT_GREEN_S = 10.0
DEFAULT_YELLOW_S = 3.0  # ITE: 1 s reaction + 11.1 m/s / (2 x 3.05 m/s^2) = 2.8 s -> 3 s
DEFAULT_RED_S = 10.0


LIGHTS_DEFAULTS: dict[str, Any] = {
    "green_s": DEFAULT_GREEN_S,  # s, duration of green
    "yellow_s": DEFAULT_YELLOW_S,  # s, duration of yellow
    "red_s": DEFAULT_RED_S,  # s, duration of red
    "offsets_s": None,  # None: drawn per reset; else k fixed phase offsets (s into the cycle)
    "script": None,  # None, or k entries: None (cycle), a state, or [[t_s, state], ...]
}

# One light's script: None (cycle), a constant state, or a schedule of (time_s, state).
LightScript = int | Sequence[tuple[float, int]] | None


@dataclass(frozen=True)
class LightTiming:
    """Durations of one light's cycle phases, s (green, then yellow, then red)."""

    green_s: float = DEFAULT_GREEN_S
    yellow_s: float = DEFAULT_YELLOW_S
    red_s: float = DEFAULT_RED_S

    def __post_init__(self) -> None:
        for name in ("green_s", "yellow_s", "red_s"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ValueError(f"LightTiming.{name} must be a finite number > 0 s, "
                                 f"got {excerpt(value)}")

    @property
    def cycle_s(self) -> float:
        """s, one full green + yellow + red cycle."""
        return self.green_s + self.yellow_s + self.red_s


def _check_state(value: Any, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or (
            int(value) not in VALID_STATES):
        raise ValueError(f"{where}: light state must be one of "
                         f"{', '.join(f'{s.name} {int(s)}' for s in LightState)}, "
                         f"got {excerpt(value)}")
    return int(value)


def _parse_script(entry: Any, light: int) -> tuple[NDArray[np.float64], NDArray[np.int8]] | None:
    """One light's script as (times_s, states) arrays, or None for a cycling light."""
    where = f"script of light {light}"
    if entry is None:
        return None
    if isinstance(entry, int | np.integer) and not isinstance(entry, bool):
        return np.zeros(1), np.array([_check_state(entry, where)], dtype=np.int8)
    if isinstance(entry, str) or not isinstance(entry, Sequence) or len(entry) == 0:
        raise ValueError(f"{where}: expected None, a state, or a non-empty list of "
                         f"(time_s, state) pairs, got {excerpt(entry)}")
    times, states = [], []
    for row, pair in enumerate(entry):
        if isinstance(pair, str) or not isinstance(pair, Sequence) or len(pair) != 2:
            raise ValueError(f"{where}, entry {row}: expected a (time_s, state) pair, "
                             f"got {excerpt(pair)}")
        time_s, state = pair
        if isinstance(time_s, bool) or not isinstance(time_s, int | float) or (
                not math.isfinite(time_s)):
            raise ValueError(f"{where}, entry {row}: time must be a finite number of s, "
                             f"got {excerpt(time_s)}")
        times.append(float(time_s))
        states.append(_check_state(state, f"{where}, entry {row}"))
    if times[0] != 0.0:
        raise ValueError(f"{where}: the first entry must be at time 0 s, got {excerpt(times[0])}")
    if any(later <= earlier for earlier, later in itertools.pairwise(times)):
        raise ValueError(f"{where}: times must be strictly increasing, got {times}")
    return np.array(times), np.array(states, dtype=np.int8)


class TrafficLights:
    """``count`` traffic lights: cycling (seeded phase offsets) or scripted.

    Args:
        count: number of lights k (>= 0).
        timing: one :class:`LightTiming` for all lights, or one per light.
        offsets_s: fixed phase offsets, s into the cycle at t = 0 (k values); None draws
            them uniformly over the cycle at every :meth:`reset`.
        script: None (all lights cycle), or k entries, each None (that light cycles), a
            constant state, or a schedule ``[(0.0, state), (t1, state1), ...]``.

    After :meth:`reset`, read :attr:`states` (int8, (k,), read-only), :attr:`time_s`,
    :attr:`time_to_change`; advance with :meth:`step`.
    """

    def __init__(
        self,
        count: int,
        timing: LightTiming | Sequence[LightTiming] = LightTiming(),
        offsets_s: Sequence[float] | None = None,
        script: Sequence[LightScript] | None = None,
    ) -> None:
        if isinstance(count, bool) or not isinstance(count, int | np.integer) or count < 0:
            raise ValueError(f"TrafficLights count must be an int >= 0, got {excerpt(count)}")
        self.count = int(count)
        timings = [timing] * self.count if isinstance(timing, LightTiming) else list(timing)
        if len(timings) != self.count or not all(isinstance(t, LightTiming) for t in timings):
            raise ValueError(f"timing must be one LightTiming or {self.count} of them, "
                             f"got {excerpt(timing)}")
        self.timings = tuple(timings)
        self._green_end = np.array([t.green_s for t in timings], dtype=np.float64)
        self._yellow_end = np.array([t.green_s + t.yellow_s for t in timings])
        self._cycle = np.array([t.cycle_s for t in timings])
        self._fixed_offsets: NDArray[np.float64] | None = None
        if offsets_s is not None:
            offsets = np.asarray(offsets_s, dtype=np.float64)
            if offsets.shape != (self.count,) or not np.all(np.isfinite(offsets)):
                raise ValueError(f"offsets_s must be {self.count} finite numbers (s), "
                                 f"got {excerpt(offsets_s)}")
            self._fixed_offsets = np.mod(offsets, self._cycle)
        entries = [None] * self.count if script is None else list(script)
        if len(entries) != self.count:
            raise ValueError(f"script must have one entry per light ({self.count}), "
                             f"got {len(entries)}")
        scripts = {light: parsed for light, entry in enumerate(entries)
                   if (parsed := _parse_script(entry, light)) is not None}
        self.scripted = len(scripts)
        longest = max((len(times) for times, _ in scripts.values()), default=0)
        script_times = np.zeros((self.count, longest))
        script_states = np.zeros((self.count, longest), dtype=np.int8)
        script_length = np.zeros(self.count, dtype=np.int64)
        for light, (times, states) in scripts.items():
            script_length[light] = len(times)
            script_times[light, :len(times)] = times
            script_states[light, :len(times)] = states
        self.schedule = LightSchedule(self._green_end, self._yellow_end, self._cycle,
                                      script_length, script_times, script_states)
        self._offsets = np.zeros(self.count) if self._fixed_offsets is None else (
            self._fixed_offsets.copy())
        self._time_s = 0.0
        self._states = np.empty(self.count, dtype=np.int8)
        self._next_change_s = -math.inf
        self._refresh()

    @classmethod
    def from_config(
        cls, count: int, config: Mapping[str, Any] | None = None, *, owner: str = "lights"
    ) -> TrafficLights:
        """Build from a config mapping with the keys of :data:`LIGHTS_DEFAULTS`."""
        resolved = resolve_config(LIGHTS_DEFAULTS, config, owner=owner)
        try:
            timing = LightTiming(resolved["green_s"], resolved["yellow_s"], resolved["red_s"])
            return cls(count, timing, resolved["offsets_s"], resolved["script"])
        except ValueError as error:
            raise ConfigError(f"{owner}: {error}") from error

    # --- the clock ------------------------------------------------------------------------

    def reset(self, rng: np.random.Generator | None) -> NDArray[np.int8]:
        """Time back to 0; draw phase offsets from ``rng`` unless they are fixed. Returns states.

        ``rng`` may be None only when the offsets are fixed (or every light is scripted).
        """
        self._offsets = self.draw_offsets(rng)
        self._time_s = 0.0
        self._refresh()
        return self._states

    def draw_offsets(self, rng: np.random.Generator | None) -> NDArray[np.float64]:
        """The phase offsets (s) of an episode: drawn uniformly over each cycle from
        ``rng``, or the fixed ones (what :meth:`reset` takes; the track world draws each
        env's with it)."""
        if self._fixed_offsets is None and self.scripted < self.count:
            if rng is None:
                raise ValueError("TrafficLights.reset needs an rng to draw phase offsets "
                                 "(or give fixed offsets_s)")
            return rng.uniform(0.0, 1.0, self.count) * self._cycle
        return self._offsets.copy()

    def step(self, dt: float) -> NDArray[np.int8]:
        """Advance the clock by ``dt`` s (>= 0); returns :attr:`states`."""
        if not dt >= 0.0:
            raise ValueError(f"TrafficLights.step: dt must be >= 0 s, got {dt!r}")
        self._time_s += dt
        if self._time_s >= self._next_change_s:
            self._refresh()
        return self._states

    @property
    def time_s(self) -> float:
        """s since the last reset."""
        return self._time_s

    @property
    def offsets_s(self) -> NDArray[np.float64]:
        """s, each cycling light's phase at t = 0 (copy)."""
        return self._offsets.copy()

    @property
    def states(self) -> NDArray[np.int8]:
        """Current state per light, int8 (k,), read-only (equals ``state_at(time_s)``)."""
        return self._states

    @property
    def time_to_change(self) -> NDArray[np.float64]:
        """s until each light's state next changes (inf for a scripted light that is done)."""
        return self.time_to_change_at(self._time_s)

    def _refresh(self) -> None:
        states = np.empty(self.count, dtype=np.int8)
        self._next_change_s = refresh_lights(self.schedule, self._offsets, self._time_s, states)
        states.flags.writeable = False
        self._states = states

    # --- pure functions of time -----------------------------------------------------------

    def state_at(self, time_s: float) -> NDArray[np.int8]:
        """States at ``time_s`` (s since reset) with the current offsets; int8 (k,), new array."""
        states = np.empty(self.count, dtype=np.int8)
        states_at(self.schedule, self._offsets, float(time_s), states)
        return states

    def time_to_change_at(self, time_s: float) -> NDArray[np.float64]:
        """s from ``time_s`` until each light's state next changes; float64 (k,)."""
        remaining = np.empty(self.count)
        times_to_change(self.schedule, self._offsets, float(time_s), remaining)
        return remaining
