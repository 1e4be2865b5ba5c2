"""The incident kinds, the rules that raise them, and one incident as logged.

See :mod:`sdc_gym.metrics.driving_metrics` for how the rules are applied.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

INCIDENT_KINDS: tuple[str, ...] = ("collision", "acceleration", "jerk", "speed", "lane", "off_road")
"""Every incident kind, in the order incidents of the same step are reported."""

@dataclass(frozen=True)
class IncidentRules:
    """Sampling and thresholds of the incident rules; defaults are the Udacity highway's.

    Other environments pass their own limits, e.g. a track with no lane bands
    (``straddle_bands=()``), other road edges or another speed limit.
    """

    dt: float = 0.02
    """Physics step, s. Every recorded sample is one step apart."""
    block_steps: int = 10
    """Samples per acceleration block (10 x 0.02 s = 0.2 s)."""
    jerk_blocks: int = 5
    """Blocks per jerk window (5 x 0.2 s = 1 s)."""
    max_acceleration: float = 10.0
    """Block total acceleration at or above which an incident is raised, m/s^2."""
    max_jerk: float = 10.0
    """Window jerk magnitude at or above which an incident is raised, m/s^3."""
    speed_limit: float = 22.352
    """Speed strictly above which an incident is raised, m/s (50 mph)."""
    road_d_min: float = 0.8
    """Lateral offset d strictly below which the car is off the road, m."""
    road_d_max: float = 11.2
    """Lateral offset d strictly above which the car is off the road, m."""
    straddle_bands: tuple[tuple[float, float], ...] = ((3.2, 4.8), (7.2, 8.8))
    """Open intervals (lo, hi) of d, m, in which the car straddles a lane line."""
    max_straddle_steps: int = 150
    """Consecutive straddling steps allowed; one more raises an incident (150 = 3 s)."""

    def __post_init__(self) -> None:
        if not self.dt > 0.0:
            raise ValueError(f"dt must be > 0, got {self.dt}")
        if self.block_steps < 1 or self.jerk_blocks < 1 or self.max_straddle_steps < 0:
            raise ValueError("block_steps and jerk_blocks must be >= 1, max_straddle_steps >= 0")
        if not self.road_d_min < self.road_d_max:
            raise ValueError("road_d_min must be < road_d_max")
        # Normalise to a tuple of float pairs so the rules stay hashable and comparable.
        bands = tuple((float(lo), float(hi)) for lo, hi in self.straddle_bands)
        if any(not lo < hi for lo, hi in bands):
            raise ValueError(f"each straddle band needs lo < hi, got {bands}")
        object.__setattr__(self, "straddle_bands", bands)

    @property
    def block_seconds(self) -> float:
        """Duration of one acceleration block, s."""
        return self.block_steps * self.dt

    @property
    def jerk_window_seconds(self) -> float:
        """Duration of one jerk window, s."""
        return self.jerk_blocks * self.block_steps * self.dt


@dataclass(frozen=True)
class Incident:
    """One incident, located at the physics step where it began.

    ``value`` depends on the kind: the car id (collision), the block total acceleration in
    m/s^2 (acceleration), the signed window jerk in m/s^3 (jerk), the speed in m/s
    (speed), the straddle duration in s (lane), ``d`` in m (off_road), or what the env
    documents for its ``extra_kinds`` (the track loop's red_light: the stop line's index).
    Block and window incidents are placed at the last step of their block.
    """

    kind: str
    time: float
    step: int
    x: float
    y: float
    s: float
    d: float
    value: float

    def as_dict(self) -> dict[str, Any]:
        """Plain-Python dict, ready for JSON."""
        return asdict(self)
