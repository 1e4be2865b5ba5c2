"""Node rates: each node of the stack runs at its own rate inside the env's fixed loop.

On the car every ROS node had its own loop rate; here one agent is called once per env
step (50 Hz with ``steps_per_action = 1``). :class:`RateScheduler` decides which nodes
run at each tick so that a node of rate ``r`` Hz runs ``r`` times per simulated second:
it runs at tick ``k`` when ``floor(k * r * dt)`` grew since tick ``k - 1`` (and at tick
0). The arithmetic is exact (fractions), so e.g. 30 Hz in a 50 Hz loop runs on exactly
30 of every 50 ticks, with gaps of 1 or 2 ticks. A rate at or above the loop rate runs
every tick (the loop rate is the most a node can get; :meth:`RateScheduler.rate` tells
the effective rate). With ``r dt = p / q`` in lowest terms the test is integer arithmetic,
``(k p) // q > ((k - 1) p) // q`` (:func:`~sdc_gym.stack.track.node_kernels.node_due`, which
the batched stack evaluates in its kernel).

Presets (:data:`RATE_PRESETS`; the waypoint loader runs once, at construction):

=============  ========  ========  =====  ====================================
preset         updater   follower  DBW    detector
=============  ========  ========  =====  ====================================
``original``   10 Hz     30 Hz     50 Hz  every camera frame (every env step)
``seed``       2 Hz      5 Hz      15 Hz  every camera frame (every env step)
=============  ========  ========  =====  ====================================

The original's DBW node ran at 50 Hz and its pure pursuit at 30 Hz (spec); the spec does
not give the updater's rate: 10 Hz is this stack's choice (the seed team's note "50
waypoints at 10 Hz"). The seed team's write-up lowered the rates to 2 / 5 / 15 Hz to save
compute and noted that lower rates limit the achievable speed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from fractions import Fraction

import numpy as np

from sdc_gym.stack.track.node_kernels import node_due

NODES = ("detector", "updater", "follower", "dbw")
"""The scheduled nodes, in the order they run within a tick (data flows downstream)."""

EVERY_FRAME_HZ = math.inf
"""A rate meaning "every tick" (the detector's default: each camera frame)."""

# Exact fractions from floats like 0.02 s: denominators up to this bound.
_MAX_DENOMINATOR = 1_000_000


@dataclass(frozen=True)
class NodeRates:
    """Rates of the scheduled nodes, Hz (``math.inf``: every tick)."""

    updater_hz: float = 10.0
    follower_hz: float = 30.0
    dbw_hz: float = 50.0
    detector_hz: float = EVERY_FRAME_HZ

    def __post_init__(self) -> None:
        for key, value in asdict(self).items():
            if not (isinstance(value, int | float) and value > 0):
                raise ValueError(f"NodeRates: {key} must be a rate > 0 Hz (inf: every tick), "
                                 f"got {value!r}")

    def as_mapping(self) -> dict[str, float]:
        """{node name: Hz} for :class:`RateScheduler`."""
        return {"detector": self.detector_hz, "updater": self.updater_hz,
                "follower": self.follower_hz, "dbw": self.dbw_hz}


ORIGINAL_RATES = NodeRates()
SEED_RATES = NodeRates(updater_hz=2.0, follower_hz=5.0, dbw_hz=15.0)
RATE_PRESETS: dict[str, NodeRates] = {"original": ORIGINAL_RATES, "seed": SEED_RATES}


def node_rates(preset: str | NodeRates) -> NodeRates:
    """A preset by name (see :data:`RATE_PRESETS`) or the given :class:`NodeRates`."""
    if isinstance(preset, NodeRates):
        return preset
    try:
        return RATE_PRESETS[preset]
    except (KeyError, TypeError):
        raise ValueError(f"unknown rate preset {preset!r}; choose one of "
                         f"{sorted(RATE_PRESETS)} or pass NodeRates(...)") from None


class RateScheduler:
    """Which nodes run at each tick of a fixed-period loop; see the module docstring.

    Usage::

        scheduler = RateScheduler(0.02, {"follower": 30.0, "dbw": 50.0})
        for _ in range(50):
            for name in scheduler.tick():   # the nodes due at this tick, in given order
                ...
    """

    def __init__(self, loop_period_s: float, rates_hz: Mapping[str, float]) -> None:
        if not (loop_period_s > 0 and math.isfinite(loop_period_s)):
            raise ValueError(f"RateScheduler: loop_period_s must be a finite number > 0 s, "
                             f"got {loop_period_s!r}")
        self.loop_period_s = float(loop_period_s)
        self._dt = Fraction(loop_period_s).limit_denominator(_MAX_DENOMINATOR)
        self._per_tick: dict[str, Fraction | None] = {}
        for name, rate in rates_hz.items():
            if not (isinstance(rate, int | float) and rate > 0):
                raise ValueError(f"RateScheduler: rate of {name!r} must be > 0 Hz (inf: "
                                 f"every tick), got {rate!r}")
            runs_per_tick = None if math.isinf(rate) else (
                Fraction(rate).limit_denominator(_MAX_DENOMINATOR) * self._dt)
            # At or above the loop rate: every tick.
            self._per_tick[name] = None if runs_per_tick is None or runs_per_tick >= 1 \
                else runs_per_tick
        # Each node's runs per tick as a reduced fraction of ints (1/1: every tick), for
        # the kernels' exact integer test (node_kernels.node_due).
        fractions = [Fraction(1) if per_tick is None else per_tick
                     for per_tick in self._per_tick.values()]
        self.runs = np.array([f.numerator for f in fractions], dtype=np.int64)
        self.per_ticks = np.array([f.denominator for f in fractions], dtype=np.int64)
        self._names = tuple(self._per_tick)
        self._fractions = [(name, int(runs), int(per)) for name, runs, per in
                           zip(self._names, self.runs.tolist(), self.per_ticks.tolist(),
                               strict=True)]
        self._index = {name: i for i, name in enumerate(self._names)}
        self.reset()

    def reset(self) -> None:
        """Back to tick 0 (every node runs at the next tick)."""
        self.ticks = 0

    @property
    def names(self) -> tuple[str, ...]:
        """The scheduled nodes, in run order."""
        return tuple(self._per_tick)

    @property
    def time_s(self) -> float:
        """s, the time of the next tick."""
        return self.ticks * self.loop_period_s

    def rate(self, name: str) -> float:
        """Hz, the effective rate of ``name`` (at most the loop rate)."""
        per_tick = self._per_tick[name]
        return float((1 if per_tick is None else per_tick) / self._dt)

    def is_due(self, name: str, tick: int) -> bool:
        """Whether ``name`` runs at ``tick``."""
        i = self._index[name]
        return bool(node_due(int(self.runs[i]), int(self.per_ticks[i]), int(tick)))

    def tick(self) -> list[str]:
        """The nodes due at the current tick (in the mapping's order); advances one tick."""
        tick = self.ticks
        self.ticks += 1
        return [name for name, runs, per in self._fractions if node_due(runs, per, tick)]
